"""Compiled RMAC step (the fast back end of :class:`rmac_mj.agents.rmac.RMAC`).

``step`` and ``stop`` follow ``RMAC._act`` and ``RMAC._update`` (the numpy reference, which cites
Algorithm 2 line by line) statement by statement, so one control step is one compiled call instead
of a few dozen numpy ones. ``tests/test_rmac.py`` checks that both back ends take the same actions
and leave the same memories, step by step, for every option.

The kernels take an :class:`RMACState`, a numba structref that names what a step reads and writes:

======================  ============================================================================
``process``             M^P, an :class:`~rmac_mj.approximators.llr.LLRState` over [x, u | x']
``reference``           M^R over [x | x_hat]
``critic``              M^C over [x | V]
``traces``              (N_C,) eligibility traces of the critic's samples (line 26)
``x_prev``, ``u_prev``  (n,), (m,): x_{k-1} and u_{k-1}, updated by ``step``
``v_prev``              (1,): V_{k-1}, updated by ``step``
``vertices``            (2^m, m) the combinations of action extremes that span the reachable set
``period``              (n,) period of each periodic state dimension, 0 elsewhere
``low``, ``high``       (m,) action bounds
``gamma``, ``lam``      discount and trace decay
``alpha_c``, ``alpha_r``  critic and reference learning rates
``beta_u_zero``         beta_u counts as zero below this fraction of the state gains
``inverse_previous``    linearise the inverse at u_{k-1} (else at 0)
``gradient_at_next``    fit the critic's ranking model at x_k (else at x_{k-1})
``rule``                index of ``RMACConfig.reachable_rule`` in ('vertices', 'vertices_value',
                        'grid', 'exact')
``action_cost``         (m,) P of the score -sum_i P_i u_i^2 + gamma V(x') (rules other than
                        'vertices')
``candidates``          (c, m) candidate actions of those rules (vertices or grid)
``refine_steps``        golden-section steps of rule 'exact' (0: none)
``insert_rate``         ``reference_insert_rate``: M^R gets R(x_{k-1}) + rate (x_r - R(x_{k-1}))
``ref_idx``, ...        neighbour lists of the reference memory (``ref_*``) and of the critic
                        (``crit_*``): two buffers each, one for x_k and one for x_{k-1}
                        (``cur`` says which is x_k's): ``*_idx`` (2, K+1) samples, ``*_dist``
                        (2, K+1) their distances, ``*_info`` (2, 2) [length (-1: none), memory
                        version], ``*_point`` (2, n) where the list was searched
``proc_idx``,           (K_P+1,) the process model's neighbour list at (x_{k-1}, u_{k-1})
``proc_dist``
======================  ============================================================================

Its arrays are the agent's own (and the memories'), so Python and compiled code see one state.
The memories are used only through the compiled interface that ``rmac_mj.approximators.llr``
exports.

Fewer searches than statements. Algorithm 2 searches the same point more than once with one
insertion in between: M^R and M^C at x_k (for R(x_k) and V_k) and again at x_{k-1} one step later
(for the neighbours to update and the slot to replace), and M^P at (x_{k-1}, u_{k-1}) to insert
and then to fit. Each such point is searched once for K+1 neighbours and the list is carried
across the insertion (``llr_refresh``), which gives exactly the neighbours a second search would.
A list is used only while its memory's version shows no other change, and only at the very point
it was searched; otherwise the kernel searches again, as the reference does.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.experimental import structref

from rmac_mj.approximators.llr import (LLR_STATE_TYPE, llr_add_weighted, llr_candidates,
                                       llr_canonical, llr_fit_at, llr_insert_among,
                                       llr_move_outputs, llr_query, llr_refresh, wrap_scalar)


@structref.register
class RMACStateType(types.StructRef):
    """The numba type of :class:`RMACState`."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class RMACState(structref.StructRefProxy):
    """What one RMAC step reads and writes, named (fields: see the module docstring). Made by
    :func:`new_state`; opaque to Python."""


structref.define_boxing(RMACStateType, RMACState)

_VECTOR = types.float64[::1]
_MATRIX = types.float64[:, ::1]
_INDICES = types.int64[:, ::1]
RMAC_STATE_TYPE = RMACStateType([
    ("process", LLR_STATE_TYPE), ("reference", LLR_STATE_TYPE), ("critic", LLR_STATE_TYPE),
    ("traces", _VECTOR), ("x_prev", _VECTOR), ("u_prev", _VECTOR), ("v_prev", _VECTOR),
    ("vertices", _MATRIX), ("period", _VECTOR), ("low", _VECTOR), ("high", _VECTOR),
    ("gamma", types.float64), ("lam", types.float64), ("alpha_c", types.float64),
    ("alpha_r", types.float64), ("beta_u_zero", types.float64), ("inverse_previous", types.boolean),
    ("gradient_at_next", types.boolean), ("rule", types.int64), ("action_cost", _VECTOR),
    ("candidates", _MATRIX), ("refine_steps", types.int64), ("insert_rate", types.float64),
    ("ref_idx", _INDICES), ("ref_dist", _MATRIX), ("ref_info", _INDICES), ("ref_point", _MATRIX),
    ("crit_idx", _INDICES), ("crit_dist", _MATRIX), ("crit_info", _INDICES),
    ("crit_point", _MATRIX), ("cur", types.int64), ("proc_idx", types.int64[::1]),
    ("proc_dist", _VECTOR)])


@njit(cache=True)
def set_rates(state, alpha_c, alpha_r):
    """Set the critic's and the reference's learning rates (a trial's, when they decay)."""
    state.alpha_c = alpha_c
    state.alpha_r = alpha_r


@njit(cache=True)
def new_state(process, reference, critic, traces, x_prev, u_prev, v_prev, vertices, period, low,
              high, gamma, lam, alpha_c, alpha_r, beta_u_zero, inverse_previous, gradient_at_next,
              ref_info, crit_info, rule, action_cost, candidates, refine_steps, insert_rate):
    """An :class:`RMACState` over the given memory states and arrays (not copied). ``ref_info`` and
    ``crit_info`` (2, 2) int64 mark the neighbour lists; set their [:, 0] to -1 to drop the lists
    (at the start of a trial, after loading a state)."""
    state = structref.new(RMAC_STATE_TYPE)
    state.process = process
    state.reference = reference
    state.critic = critic
    state.traces = traces
    state.x_prev = x_prev
    state.u_prev = u_prev
    state.v_prev = v_prev
    state.vertices = vertices
    state.period = period
    state.low = low
    state.high = high
    state.gamma = gamma
    state.lam = lam
    state.alpha_c = alpha_c
    state.alpha_r = alpha_r
    state.beta_u_zero = beta_u_zero
    state.inverse_previous = inverse_previous
    state.gradient_at_next = gradient_at_next
    state.rule = rule
    state.action_cost = action_cost
    state.candidates = candidates
    state.refine_steps = refine_steps
    state.insert_rate = insert_rate
    n = x_prev.shape[0]
    state.ref_idx = np.zeros((2, reference.n_neighbours + 1), dtype=np.int64)
    state.ref_dist = np.zeros((2, reference.n_neighbours + 1))
    state.ref_info = ref_info
    state.ref_point = np.zeros((2, n))
    state.crit_idx = np.zeros((2, critic.n_neighbours + 1), dtype=np.int64)
    state.crit_dist = np.zeros((2, critic.n_neighbours + 1))
    state.crit_info = crit_info
    state.crit_point = np.zeros((2, n))
    state.cur = 0
    state.proc_idx = np.zeros(process.n_neighbours + 1, dtype=np.int64)
    state.proc_dist = np.zeros(process.n_neighbours + 1)
    return state


@njit(cache=True)
def _canonical(x, period):
    """A new array: x with its periodic entries wrapped (LLR's ``canonical``)."""
    out = np.empty(x.shape[0])
    llr_canonical(x, period, out)
    return out


@njit(cache=True)
def _search_list(memory, x, idx, dist, info, point, b):
    """Search a canonical x for K+1 neighbours into list buffer b, seeded with the other buffer's
    list (a point one step away); returns K(x)'s length."""
    other = 1 - b
    n = llr_candidates(memory, x, idx[b], dist[b], idx[other], max(info[other, 0], 0))
    info[b, 0] = n
    info[b, 1] = memory.meta[2]
    point[b, :] = x
    return min(n, memory.n_neighbours)


@njit(cache=True)
def _list_at(memory, x, info, point, b):
    """Whether list buffer b holds K(x) of the memory as it is now."""
    if info[b, 0] < 0 or info[b, 1] != memory.meta[2]:
        return False
    for j in range(x.shape[0]):
        if point[b, j] != x[j]:
            return False
    return True


@njit(cache=True)
def _carry(memory, idx, dist, info, point, b, version, slot):
    """Carry list buffer b across the insertion into ``slot`` that changed the memory from
    ``version``; a list of another version is dropped."""
    if info[b, 0] >= 0 and info[b, 1] == version:
        info[b, 0] = llr_refresh(memory, point[b], idx[b], dist[b], info[b, 0], slot)
        info[b, 1] = memory.meta[2]
    else:
        info[b, 0] = -1


@njit(cache=True)
def _inverse(s, x, x_desired, u_query):
    """f^-1(x, x_desired) linearised at (x, u_query); see RMAC._inverse."""
    P = s.process
    n = x.shape[0]
    m = u_query.shape[0]
    z = np.empty(n + m)
    z[:n] = x
    z[n:] = u_query
    idx = np.empty(P.n_neighbours, dtype=np.int64)
    beta = np.empty((n, n + m + 1))
    pred = np.empty(n)
    llr_query(P, z, idx, beta, pred)
    beta_u = np.ascontiguousarray(beta[:, n:n + m])
    u = np.zeros(m)
    if np.abs(beta_u).max() <= s.beta_u_zero * max(1.0, np.abs(beta[:, :n]).max()):
        return u
    e = np.empty(n)
    for j in range(n):
        e[j] = wrap_scalar(x_desired[j] - pred[j], s.period[j])
    if m == 1:
        bb = 0.0
        be = 0.0
        for j in range(n):
            bb += beta_u[j, 0] * beta_u[j, 0]
            be += beta_u[j, 0] * e[j]
        u[0] = u_query[0] + be / bb
    else:
        u[:] = u_query + np.linalg.pinv(beta_u) @ e
    for i in range(m):
        u[i] = min(max(u[i], s.low[i]), s.high[i])
    return u


@njit(cache=True)
def _act(s, x):
    """The greedy action in x (lines 10-11 without Delta u_k); leaves K+1 neighbours of x in the
    reference's current list."""
    n = x.shape[0]
    R = s.reference
    xq = _canonical(x, s.period)  # (as LLRMemory.query does)
    nk = _search_list(R, xq, s.ref_idx, s.ref_dist, s.ref_info, s.ref_point, s.cur)
    beta = np.empty((n, n + 1))
    x_desired = np.empty(n)
    llr_fit_at(R, xq, s.ref_idx[s.cur], nk, beta, x_desired)  # line 10
    u_query = s.u_prev.copy() if s.inverse_previous else np.zeros(s.u_prev.shape[0])
    return _inverse(s, x, x_desired, u_query)  # line 11


_RULE_VERTICES = 0
_RULE_EXACT = 3
_INV_PHI = (5.0 ** 0.5 - 1.0) / 2.0


@njit(cache=True)
def _reachable_score(s, u, pred, beta_p, x_next):
    """-sum_i P_i u_i^2 + gamma V(x'(u)), writing the canonical x'(u) to x_next; see
    RMAC._reachable_score."""
    n = pred.shape[0]
    m = u.shape[0]
    u_prev = s.u_prev
    for j in range(n):
        r = pred[j]
        for i in range(m):
            r += beta_p[j, n + i] * (u[i] - u_prev[i])
        x_next[j] = wrap_scalar(r, s.period[j])
    C = s.critic
    idx = np.empty(C.n_neighbours, dtype=np.int64)
    beta = np.empty((1, n + 1))
    v = np.empty(1)
    llr_query(C, x_next, idx, beta, v)
    cost = 0.0
    for i in range(m):
        cost += s.action_cost[i] * (u[i] * u[i])
    return -cost + s.gamma * v[0]


@njit(cache=True)
def _best_reachable(s, pred, beta_p):
    """x_r for the rules other than 'vertices'; see RMAC._best_reachable."""
    n = pred.shape[0]
    cands = s.candidates
    m = cands.shape[1]
    x_r = np.empty(n)
    x_next = np.empty(n)
    best_score = -np.inf
    best = 0
    for c in range(cands.shape[0]):
        score = _reachable_score(s, cands[c], pred, beta_p, x_next)
        if score > best_score:
            best_score = score
            best = c
            x_r[:] = x_next
    if s.rule == _RULE_EXACT and s.refine_steps > 0:
        low, high = s.low[0], s.high[0]
        h = (high - low) / (cands.shape[0] - 1)
        a = max(low, cands[best, 0] - h)
        b = min(high, cands[best, 0] + h)
        uc = np.empty(m)
        ud = np.empty(m)
        xc = np.empty(n)
        xd = np.empty(n)
        uc[0] = b - _INV_PHI * (b - a)
        ud[0] = a + _INV_PHI * (b - a)
        fc = _reachable_score(s, uc, pred, beta_p, xc)
        fd = _reachable_score(s, ud, pred, beta_p, xd)
        for _ in range(s.refine_steps):
            if fc >= fd:  # the maximum lies in [a, d]
                b = ud[0]
                ud[0] = uc[0]
                fd = fc
                xd[:] = xc
                uc[0] = b - _INV_PHI * (b - a)
                fc = _reachable_score(s, uc, pred, beta_p, xc)
            else:         # in [c, b]
                a = uc[0]
                uc[0] = ud[0]
                fc = fd
                xc[:] = xd
                ud[0] = a + _INV_PHI * (b - a)
                fd = _reachable_score(s, ud, pred, beta_p, xd)
        if fc >= fd:
            if fc > best_score:
                x_r[:] = xc
        elif fd > best_score:
            x_r[:] = xd
    return x_r


@njit(cache=True)
def _update(s, reward, x):
    """Lines 13-28 for the transition (x_prev, u_prev, reward, x); returns V_k."""
    P, R, C = s.process, s.reference, s.critic
    x_prev, u_prev, period = s.x_prev, s.u_prev, s.period
    cur = s.cur
    prev = 1 - cur
    n = x.shape[0]
    m = u_prev.shape[0]
    # Line 14: insert [x_{k-1}, u_{k-1} | x_k] in M^P; the neighbours of the insertion point,
    # carried across the insertion, are those of the fit that follows.
    z = np.empty(n + m)
    z[:n] = x_prev
    z[n:] = u_prev
    zq = _canonical(z, P.in_period)
    nc = llr_candidates(P, zq, s.proc_idx, s.proc_dist, s.proc_idx, 0)
    slot = llr_insert_among(P, z, x, s.proc_idx, min(nc, P.n_neighbours))
    nc = llr_refresh(P, zq, s.proc_idx, s.proc_dist, nc, slot)
    # Line 16: best reachable state, X_R = beta^P U_R linearised at (x_{k-1}, u_{k-1}).
    beta_p = np.empty((n, n + m + 1))
    pred = np.empty(n)
    llr_fit_at(P, zq, s.proc_idx, min(P.n_neighbours, P.meta[0]), beta_p, pred)
    beta_c = np.empty((1, n + 1))
    v_pred = np.empty(1)
    xc = _canonical(x, period)  # (as LLRMemory.query does)
    nk = _search_list(C, xc, s.crit_idx, s.crit_dist, s.crit_info, s.crit_point, cur)
    llr_fit_at(C, xc, s.crit_idx[cur], nk, beta_c, v_pred)
    v_k = v_pred[0]
    if s.rule != _RULE_VERTICES:  # r + gamma V(x') with the full critic
        x_r = _best_reachable(s, pred, beta_p)
    else:
        vertices = s.vertices
        nv = vertices.shape[0]
        reachable = np.empty((nv, n))
        for v in range(nv):
            for j in range(n):
                r = pred[j]
                for i in range(m):
                    r += beta_p[j, n + i] * (vertices[v, i] - u_prev[i])
                reachable[v, j] = r
        slope = beta_c[0, :n].copy()
        x_c = x
        if not s.gradient_at_next:
            xp = _canonical(x_prev, period)
            if _list_at(C, xp, s.crit_info, s.crit_point, prev):
                llr_fit_at(C, xp, s.crit_idx[prev], min(C.n_neighbours, C.meta[0]), beta_c,
                           v_pred)
            else:
                idx = np.empty(C.n_neighbours, dtype=np.int64)
                llr_query(C, x_prev, idx, beta_c, v_pred)
            slope = beta_c[0, :n].copy()
            x_c = x_prev
        best = 0
        best_value = -np.inf
        for v in range(nv):
            value = 0.0
            for j in range(n):
                value += slope[j] * wrap_scalar(reachable[v, j] - x_c[j], period[j])
            if value > best_value:
                best_value = value
                best = v
        x_r = np.empty(n)
        for j in range(n):
            x_r[j] = wrap_scalar(reachable[best, j], period[j])
    # Lines 17-20: insert [x_{k-1} | x_r] in M^R, move K(x_{k-1}) towards x_r.
    if _list_at(R, x_prev, s.ref_info, s.ref_point, prev):
        nk = min(R.n_neighbours, R.meta[0])
    else:
        nk = _search_list(R, x_prev, s.ref_idx, s.ref_dist, s.ref_info, s.ref_point, prev)
    near = s.ref_idx[prev]
    inserted = x_r
    if s.insert_rate < 1.0 and nk > 0:  # R(x_{k-1}) from K(x_{k-1}), moved towards x_r
        beta_r = np.empty((n, n + 1))
        r_prev = np.empty(n)
        llr_fit_at(R, x_prev, near, nk, beta_r, r_prev)
        inserted = np.empty(n)
        for j in range(n):
            inserted[j] = wrap_scalar(
                r_prev[j] + s.insert_rate * wrap_scalar(x_r[j] - r_prev[j], period[j]), period[j])
    version = R.meta[2]
    slot = llr_insert_among(R, x_prev, inserted, near, nk)
    _carry(R, s.ref_idx, s.ref_dist, s.ref_info, s.ref_point, cur, version, slot)
    llr_move_outputs(R, near, nk, x_r, s.alpha_r)
    # Lines 22-28: TD(lambda) on the critic's samples; V_k computed above (line 22).
    if _list_at(C, x_prev, s.crit_info, s.crit_point, prev):
        nk = min(C.n_neighbours, C.meta[0])
    else:
        nk = _search_list(C, x_prev, s.crit_idx, s.crit_dist, s.crit_info, s.crit_point, prev)
    near = s.crit_idx[prev]
    v_in = np.empty(1)
    v_in[0] = s.v_prev[0]
    version = C.meta[2]
    slot = llr_insert_among(C, x_prev, v_in, near, nk)  # line 23
    _carry(C, s.crit_idx, s.crit_dist, s.crit_info, s.crit_point, cur, version, slot)
    delta = reward + s.gamma * v_k - s.v_prev[0]  # line 24
    decay = s.lam * s.gamma
    traces = s.traces
    for i in range(C.meta[0]):
        traces[i] *= decay  # line 26
    for a in range(nk):
        traces[near[a]] = 1.0
    traces[slot] = 1.0
    step_size = np.empty(1)
    step_size[0] = s.alpha_c * delta
    llr_add_weighted(C, traces, step_size)  # line 27
    return v_k


@njit(cache=True)
def step(s, reward, x, du):
    """One control step in one compiled call, for a checked state x (periodic entries are wrapped
    here): u_k = sat(f^-1(x_k, R(x_k)) + Delta u_k) with the models as they are (lines 10-12), then
    lines 13-28; then x_prev, u_prev, v_prev advance to x_k, u_k, V_k. Returns u_k."""
    x = _canonical(x, s.period)
    u = _act(s, x)
    low, high = s.low, s.high
    for i in range(u.shape[0]):
        u[i] = min(max(u[i] + du[i], low[i]), high[i])
    s.v_prev[0] = _update(s, reward, x)
    s.x_prev[:] = x
    s.u_prev[:] = u
    s.cur = 1 - s.cur
    return u


@njit(cache=True)
def stop(s, reward, x):
    """The last transition of a trial (lines 13-28, no action) for a checked state x."""
    s.ref_info[s.cur, 0] = -1  # no action, so no reference list at x
    _update(s, reward, _canonical(x, s.period))

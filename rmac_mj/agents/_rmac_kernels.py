"""Compiled RMAC step (the fast back end of :class:`rmac_mj.agents.rmac.RMAC`).

``step`` and ``update`` follow ``RMAC._act`` and ``RMAC._update`` (the numpy reference, which cites
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
======================  ============================================================================

Its arrays are the agent's own (and the memories'), so Python and compiled code see one state.
The memories are used only through the compiled interface that ``rmac_mj.approximators.llr`` exports.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.experimental import structref

from rmac_mj.approximators.llr import (LLR_STATE_TYPE, llr_add_weighted, llr_insert,
                                       llr_move_outputs, llr_neighbours, llr_query, wrap_scalar)


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
RMAC_STATE_TYPE = RMACStateType([
    ("process", LLR_STATE_TYPE), ("reference", LLR_STATE_TYPE), ("critic", LLR_STATE_TYPE),
    ("traces", _VECTOR), ("x_prev", _VECTOR), ("u_prev", _VECTOR), ("v_prev", _VECTOR),
    ("vertices", types.float64[:, ::1]), ("period", _VECTOR), ("low", _VECTOR), ("high", _VECTOR),
    ("gamma", types.float64), ("lam", types.float64), ("alpha_c", types.float64),
    ("alpha_r", types.float64), ("beta_u_zero", types.float64), ("inverse_previous", types.boolean),
    ("gradient_at_next", types.boolean)])


@njit(cache=True)
def new_state(process, reference, critic, traces, x_prev, u_prev, v_prev, vertices, period, low,
              high, gamma, lam, alpha_c, alpha_r, beta_u_zero, inverse_previous, gradient_at_next):
    """An :class:`RMACState` over the given memory states and arrays (not copied)."""
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
    return state


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
    """The greedy action in x (lines 10-11 without Delta u_k)."""
    n = x.shape[0]
    R = s.reference
    idx = np.empty(R.n_neighbours, dtype=np.int64)
    beta = np.empty((n, n + 1))
    x_desired = np.empty(n)
    llr_query(R, x, idx, beta, x_desired)  # line 10
    u_query = s.u_prev.copy() if s.inverse_previous else np.zeros(s.u_prev.shape[0])
    return _inverse(s, x, x_desired, u_query)  # line 11


@njit(cache=True)
def update(s, reward, x):
    """Lines 13-28 for the transition (x_prev, u_prev, reward, x); returns V_k."""
    P, R, C = s.process, s.reference, s.critic
    x_prev, u_prev, period = s.x_prev, s.u_prev, s.period
    n = x.shape[0]
    m = u_prev.shape[0]
    # Line 14: insert [x_{k-1}, u_{k-1} | x_k] in M^P.
    z = np.empty(n + m)
    z[:n] = x_prev
    z[n:] = u_prev
    llr_insert(P, z, x, -1)
    # Line 16: best reachable state, X_R = beta^P U_R linearised at (x_{k-1}, u_{k-1}).
    idx = np.empty(max(P.n_neighbours, max(R.n_neighbours, C.n_neighbours)), dtype=np.int64)
    beta_p = np.empty((n, n + m + 1))
    pred = np.empty(n)
    llr_query(P, z, idx, beta_p, pred)
    vertices = s.vertices
    nv = vertices.shape[0]
    reachable = np.empty((nv, n))
    for v in range(nv):
        for j in range(n):
            r = pred[j]
            for i in range(m):
                r += beta_p[j, n + i] * (vertices[v, i] - u_prev[i])
            reachable[v, j] = r
    beta_c = np.empty((1, n + 1))
    v_pred = np.empty(1)
    llr_query(C, x, idx, beta_c, v_pred)
    v_k = v_pred[0]
    slope = beta_c[0, :n].copy()
    x_c = x
    if not s.gradient_at_next:
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
    nk = llr_neighbours(R, x_prev, idx)
    llr_insert(R, x_prev, x_r, idx[0] if nk > 0 else -1)
    llr_move_outputs(R, idx, nk, x_r, s.alpha_r)
    # Lines 22-28: TD(lambda) on the critic's samples; V_k computed above (line 22).
    nk = llr_neighbours(C, x_prev, idx)
    v_in = np.empty(1)
    v_in[0] = s.v_prev[0]
    slot = llr_insert(C, x_prev, v_in, idx[0] if nk > 0 else -1)  # line 23
    delta = reward + s.gamma * v_k - s.v_prev[0]  # line 24
    decay = s.lam * s.gamma
    traces = s.traces
    for i in range(C.meta[0]):
        traces[i] *= decay  # line 26
    for a in range(nk):
        traces[idx[a]] = 1.0
    traces[slot] = 1.0
    step_size = np.empty(1)
    step_size[0] = s.alpha_c * delta
    llr_add_weighted(C, traces, step_size)  # line 27
    return v_k


@njit(cache=True)
def step(s, reward, x, du):
    """One control step in one compiled call: u_k = sat(f^-1(x_k, R(x_k)) + Delta u_k) with the
    models as they are (lines 10-12), then lines 13-28; then x_prev, u_prev, v_prev advance to
    x_k, u_k, V_k. Returns u_k."""
    u = _act(s, x)
    low, high = s.low, s.high
    for i in range(u.shape[0]):
        u[i] = min(max(u[i] + du[i], low[i]), high[i])
    s.v_prev[0] = update(s, reward, x)
    s.x_prev[:] = x
    s.u_prev[:] = u
    return u

"""Compiled RMAC step, the ``backend='numba'`` twin of :mod:`rmac_mj.agents.rmac` (Algorithm 2).

:func:`step` is lines 8-29 on an :class:`RMACState`: act (10-12), then :func:`learn` (13-28: insert
in M^P, :func:`best_reachable`, :func:`update_reference`, ``critic.td_update``);
``tests/agents/test_rmac.py`` checks both back ends agree.
"""

from __future__ import annotations

import collections

import numpy as np
from numba import njit, types
from numba.experimental import structref

from rmac_mj.agents.critic import CRITIC_STATE_TYPE, td_overflows, td_update, value_fit
from rmac_mj.agents.rmac_config import REACHABLE_RULES
from rmac_mj.approximators.llr import (
    LLR_STATE_TYPE,
    llr_canonical,
    llr_fit_at,
    llr_insert_among,
    llr_local_fit,
    llr_move_outputs,
    llr_nearest,
    llr_query,
    wrap_scalar,
)

_RULE_VERTICES = REACHABLE_RULES.index("vertices")
_RULE_EXACT = REACHABLE_RULES.index("exact")
_INV_PHI = (5.0**0.5 - 1.0) / 2.0

#: The settings of a compiled RMAC step (fields: see :class:`RMACState`).
RMACSettings = collections.namedtuple(
    "RMACSettings",
    [
        "gamma",
        "alpha_r",
        "beta_u_zero",
        "inverse_previous",
        "gradient_at_next",
        "rule",
        "action_cost",
        "vertices",
        "candidates",
        "refine_steps",
        "insert_rate",
        "period",
        "low",
        "high",
    ],
)


@structref.register
class RMACStateType(types.StructRef):
    """The numba type of :class:`RMACState`."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class RMACState(structref.StructRefProxy):
    """What one RMAC step reads and writes, named. Made by :func:`new_state`; opaque to Python.

    Made from the memories' states, the trial's bookkeeping and the named :class:`RMACSettings`:

    ======================  ========================================================================
    ``process``             M^P, an ``LLRState`` over [x, u | x']
    ``reference``           M^R over [x | x_hat]
    ``critic``              the critic, a ``CriticState`` (M^C over [x | V], its traces, gamma,
                            lambda, alpha_c; :mod:`rmac_mj.agents.critic`)
    ``x_prev``, ``u_prev``  (n,), (m,): x_{k-1} and u_{k-1}, advanced by ``step``
    ``v_prev``              (1,): V_{k-1}, advanced by ``step``
    ``gamma``, ``alpha_r``  discount and the reference's learning rate
    ``beta_u_zero``         beta_u counts as zero below this fraction of the state gains
    ``inverse_previous``    linearise the inverse at u_{k-1} (else at 0)
    ``gradient_at_next``    fit the critic's ranking model at x_k (else at x_{k-1})
    ``rule``                index of ``RMACConfig.reachable_rule`` in ``REACHABLE_RULES``
    ``action_cost``         (m,) P of the score -sum_i P_i u_i^2 + gamma V(x') (rules other than
                            'vertices')
    ``vertices``            (2^m, m) the combinations of action extremes that span the reachable set
    ``candidates``          (c, m) candidate actions of the other rules (vertices or grid)
    ``refine_steps``        golden-section steps of rule 'exact' (0: none)
    ``insert_rate``         ``reference_insert_rate``: M^R gets R(x_{k-1}) + rate (x_r - R(x_{k-1}))
    ``period``              (n,) period of each periodic state dimension, 0 elsewhere
    ``low``, ``high``       (m,) action bounds
    ======================  ========================================================================

    Its arrays are the agent's own (and the memories'), so Python and compiled code see one state.
    The memories are used only through the compiled interface of ``rmac_mj.approximators.llr``: a
    neighbour list asked for twice (K(x_k) when acting, K(x_{k-1}) one step later) is searched once
    there, invisibly to this module.
    """


structref.define_boxing(RMACStateType, RMACState)

_VECTOR = types.float64[::1]
_MATRIX = types.float64[:, ::1]
RMAC_STATE_TYPE = RMACStateType(
    [
        ("process", LLR_STATE_TYPE),
        ("reference", LLR_STATE_TYPE),
        ("critic", CRITIC_STATE_TYPE),
        ("x_prev", _VECTOR),
        ("u_prev", _VECTOR),
        ("v_prev", _VECTOR),
        ("gamma", types.float64),
        ("alpha_r", types.float64),
        ("beta_u_zero", types.float64),
        ("inverse_previous", types.boolean),
        ("gradient_at_next", types.boolean),
        ("rule", types.int64),
        ("action_cost", _VECTOR),
        ("vertices", _MATRIX),
        ("candidates", _MATRIX),
        ("refine_steps", types.int64),
        ("insert_rate", types.float64),
        ("period", _VECTOR),
        ("low", _VECTOR),
        ("high", _VECTOR),
    ]
)


@njit(cache=True)
def new_state(process, reference, critic, x_prev, u_prev, v_prev, settings):
    """An :class:`RMACState` over the memories' states, the critic's and the trial's arrays
    x_{k-1}, u_{k-1}, V_{k-1} (none copied), with its :class:`RMACSettings`."""
    s = structref.new(RMAC_STATE_TYPE)
    s.process = process
    s.reference = reference
    s.critic = critic
    s.x_prev = x_prev
    s.u_prev = u_prev
    s.v_prev = v_prev
    s.gamma = settings.gamma
    s.alpha_r = settings.alpha_r
    s.beta_u_zero = settings.beta_u_zero
    s.inverse_previous = settings.inverse_previous
    s.gradient_at_next = settings.gradient_at_next
    s.rule = settings.rule
    s.action_cost = settings.action_cost
    s.vertices = settings.vertices
    s.candidates = settings.candidates
    s.refine_steps = settings.refine_steps
    s.insert_rate = settings.insert_rate
    s.period = settings.period
    s.low = settings.low
    s.high = settings.high
    return s


@njit(cache=True)
def set_reference_rate(s, alpha_r):
    """alpha_r of the steps that follow (a trial's, when it decays; the critic has its own)."""
    s.alpha_r = alpha_r


@njit(cache=True)
def _canonical(x, period):
    """A new array: x with its periodic entries wrapped (LLR's ``canonical``)."""
    out = np.empty(x.shape[0])
    llr_canonical(x, period, out)
    return out


@njit(cache=True)
def _joined(x, u):
    """[x, u], a new array."""
    n = x.shape[0]
    z = np.empty(n + u.shape[0])
    for j in range(n):
        z[j] = x[j]
    for i in range(u.shape[0]):
        z[n + i] = u[i]
    return z


@njit(cache=True)
def _copy(src, dst):
    """dst[:] = src for two vectors of one length (a loop: no shape check to compile)."""
    for j in range(src.shape[0]):
        dst[j] = src[j]


# -- the policy: u = f^-1(x, R(x)) -------------------------------------------------------------------


@njit(cache=True)
def _pinv_times(beta_u, e, several_actions):
    """pinv(beta_u) @ e, for a learner with several actions (``several_actions`` True). With one
    (None) the caller solves it itself and never calls this; numba prunes the branch on a None
    argument before typing, so that ``np.linalg.pinv`` (2 s of compiling) is not compiled then."""
    if several_actions is None:
        return np.empty(0)
    return np.linalg.pinv(beta_u) @ e


@njit(cache=True, inline="always")
def inverse(s, x, x_desired, u_query, several_actions):
    """f^-1(x, x_desired) linearised at (x, u_query); see ``RMAC._inverse``. ``several_actions``: see
    :func:`step`."""
    P = s.process
    n = x.shape[0]
    m = u_query.shape[0]
    idx = np.empty(P.n_neighbours, dtype=np.int64)
    beta = np.empty((n, n + m + 1))
    pred = np.empty(n)
    llr_query(P, _joined(x, u_query), idx, beta, pred)
    beta_u = np.ascontiguousarray(beta[:, n : n + m])
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
        du = _pinv_times(beta_u, e, several_actions)
        for i in range(m):
            u[i] = u_query[i] + du[i]
    for i in range(m):
        u[i] = min(max(u[i], s.low[i]), s.high[i])
    return u


@njit(cache=True, inline="always")
def act(s, x, several_actions):
    """The greedy action in a canonical x: lines 10-11 without Delta u_k."""
    xq = _canonical(x, s.period)  # (as LLRMemory.query does)
    x_desired = llr_local_fit(s.reference, xq).prediction  # line 10: x_hat_{k+1} = R(x_k)
    u_query = s.u_prev.copy() if s.inverse_previous else np.zeros(s.u_prev.shape[0])
    return inverse(s, x, x_desired, u_query, several_actions)  # line 11


# -- line 16: the best reachable state ----------------------------------------------------------------


@njit(cache=True)
def _reachable_score(s, u, u_model, model, x_next):
    """-sum_i P_i u_i^2 + gamma V(x'(u)) with x'(u) = f(x, u_model) + beta_u (u - u_model), writing
    the canonical x'(u) to x_next; see ``RMAC._reachable_score``."""
    pred, beta_p = model.prediction, model.beta
    n = pred.shape[0]
    m = u.shape[0]
    for j in range(n):
        r = pred[j]
        for i in range(m):
            r += beta_p[j, n + i] * (u[i] - u_model[i])
        x_next[j] = wrap_scalar(r, s.period[j])
    C = s.critic.memory
    idx = np.empty(C.n_neighbours, dtype=np.int64)
    beta = np.empty((1, n + 1))
    v = np.empty(1)
    llr_query(C, x_next, idx, beta, v)
    cost = 0.0
    for i in range(m):
        cost += s.action_cost[i] * (u[i] * u[i])
    return -cost + s.gamma * v[0]


@njit(cache=True, inline="always")
def _best_scored(s, u_model, model):
    """x_r for the rules other than 'vertices': the candidate with the highest score, refined by
    golden-section search for 'exact'; see ``RMAC._best_reachable``."""
    n = model.prediction.shape[0]
    cands = s.candidates
    m = cands.shape[1]
    x_r = np.empty(n)
    x_next = np.empty(n)
    best_score = -np.inf
    best = -1
    for c in range(cands.shape[0]):
        score = _reachable_score(s, cands[c], u_model, model, x_next)
        if score > best_score:
            best_score = score
            best = c
            _copy(x_next, x_r)
    if best < 0:  # no score above -inf (the critic's values overflow): the first candidate
        best = 0
        _reachable_score(s, cands[0], u_model, model, x_r)
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
        fc = _reachable_score(s, uc, u_model, model, xc)
        fd = _reachable_score(s, ud, u_model, model, xd)
        for _ in range(s.refine_steps):
            if fc >= fd:  # the maximum lies in [a, d]
                b = ud[0]
                ud[0] = uc[0]
                fd = fc
                _copy(xc, xd)
                uc[0] = b - _INV_PHI * (b - a)
                fc = _reachable_score(s, uc, u_model, model, xc)
            else:  # in [c, b]
                a = uc[0]
                uc[0] = ud[0]
                fc = fd
                _copy(xd, xc)
                ud[0] = a + _INV_PHI * (b - a)
                fd = _reachable_score(s, ud, u_model, model, xd)
        if fc >= fd:
            if fc > best_score:
                _copy(xc, x_r)
        elif fd > best_score:
            _copy(xd, x_r)
    return x_r


@njit(cache=True, inline="always")
def _best_vertex(s, x, u, x_next, model, value):
    """x_r of the paper's rule: the vertex of X_R = beta^P U_R (linearised at (x, u)) with the
    highest value under the critic's local linear model, fitted at x' (``value``) or at x."""
    pred, beta_p = model.prediction, model.beta
    n = pred.shape[0]
    m = u.shape[0]
    vertices, period = s.vertices, s.period
    nv = vertices.shape[0]
    reachable = np.empty((nv, n))
    for v in range(nv):
        for j in range(n):
            r = pred[j]
            for i in range(m):
                r += beta_p[j, n + i] * (vertices[v, i] - u[i])
            reachable[v, j] = r
    # The critic's local linear model, V(y) = V(x_c) + beta^C_x wrap(y - x_c).
    x_c = x_next
    slope = value.beta[0, :n].copy()
    if not s.gradient_at_next:
        x_c = x
        slope = value_fit(s.critic, x).beta[0, :n].copy()
    best = 0
    best_value = -np.inf
    for v in range(nv):
        score = 0.0
        for j in range(n):
            score += slope[j] * wrap_scalar(reachable[v, j] - x_c[j], period[j])
        if score > best_value:
            best_value = score
            best = v
    x_r = np.empty(n)
    for j in range(n):
        x_r[j] = wrap_scalar(reachable[best, j], period[j])
    return x_r


@njit(cache=True, inline="always")
def best_reachable(s, x, u, x_next, model, value):
    """Line 16: x_r, the best state reachable from x under the process model's local fit at (x, u)
    (``model``), with the critic's fit at x' (``value``) for the paper's rule."""
    if s.rule == _RULE_VERTICES:
        return _best_vertex(s, x, u, x_next, model, value)
    return _best_scored(s, u, model)


# -- lines 17-20: the reference model -------------------------------------------------------------------


@njit(cache=True, inline="always")
def update_reference(s, x, x_r):
    """Lines 17-20: insert [x | x_r] in M^R (or R(x) moved towards x_r: ``insert_rate``), then move
    the samples K(x) of before the insertion towards x_r by alpha_r."""
    R, period = s.reference, s.period
    n = x.shape[0]
    near, nk = llr_nearest(R, x)
    near = near[:nk].copy()  # K(x) before the insertion
    inserted = x_r
    if s.insert_rate < 1.0 and nk > 0:  # R(x) from K(x), moved towards x_r
        beta_r = np.empty((n, n + 1))
        r_x = np.empty(n)
        llr_fit_at(R, x, near, nk, beta_r, r_x)
        inserted = np.empty(n)
        for j in range(n):
            inserted[j] = wrap_scalar(
                r_x[j] + s.insert_rate * wrap_scalar(x_r[j] - r_x[j], period[j]), period[j]
            )
    llr_insert_among(R, x, inserted, near, nk)  # line 17
    llr_move_outputs(R, near, nk, x_r, s.alpha_r)  # lines 18-20


# -- lines 13-28: one transition ------------------------------------------------------------------------


@njit(cache=True, inline="always")
def learn(s, x, u, reward, x_next, v, model_learns, terminal):
    """Lines 13-28 for the transition (x, u, r, x') from canonical states, with V(x) = ``v``;
    returns V(x') (line 22, before the critic's update). ``model_learns``: line 14 inserts the
    transition in M^P (a real one); False for a simulated transition, which the process model
    predicted and must not learn from. ``terminal``: x' is a terminal state, whose value is 0 in the
    TD error (no bootstrap). Returns NaN, with nothing changed, when the critic's update would
    overflow (``td_overflows``): checked before any memory changes."""
    P = s.process
    z = _joined(x, u)
    zq = _canonical(z, P.in_period)
    # Line 22 first: V(x') and its local model do not depend on M^P, so a TD error that overflows
    # is refused before any memory changes.
    value = value_fit(s.critic, x_next)  # line 22: V(x') and its local model
    v_next = value.prediction[0]
    if td_overflows(s.critic, v, reward, 0.0 if terminal else v_next):
        return np.nan  # refused, nothing changed (the caller says so)
    if model_learns:  # line 14: insert [x, u | x'] in M^P
        near, nk = llr_nearest(P, zq)
        llr_insert_among(P, z, x_next, near, nk)
    model = llr_local_fit(P, zq)  # the local process model at (x, u)
    x_r = best_reachable(s, x, u, x_next, model, value)  # line 16: finite (see _best_scored)
    update_reference(s, x, x_r)  # lines 17-20
    td_update(s.critic, x, v, reward, 0.0 if terminal else v_next)  # lines 23-28
    return v_next


@njit(cache=True)
def step(s, reward, x, du, model_learns, last, terminal, several_actions):
    """One control step in one compiled call, for a checked state x (periodic entries are wrapped
    here): u_k = sat(f^-1(x_k, R(x_k)) + Delta u_k) with the models as they are (lines 10-12), then
    lines 13-28 (line 14 only if ``model_learns``: not in a simulated trial); then x_prev, u_prev,
    v_prev advance to x_k, u_k, V_k. With ``last``, the trial's last transition, into x = x_K: lines
    13-28 only, no action (``du`` is not read, u_k is empty) and nothing advances; ``terminal``: x_K
    is terminal, V(x_K) = 0 in the TD error.

    ``several_actions``: True for a learner with several actions, None with one (a type, not a
    value: only the first compiles ``np.linalg.pinv``, see :func:`_pinv_times`).

    Returns (u_k, V_k), V_k NaN when the transition was refused (``learn``: nothing changed, nothing
    advances). One kernel for both, so that the learning step is compiled once.
    """
    x = _canonical(x, s.period)
    m = s.u_prev.shape[0]
    u = np.empty(0 if last else m)
    if not last:
        u = act(s, x, several_actions)
        for i in range(m):
            u[i] = min(max(u[i] + du[i], s.low[i]), s.high[i])
    v_next = learn(s, s.x_prev, s.u_prev, reward, x, s.v_prev[0], model_learns, terminal)
    if last or np.isnan(v_next):
        return u, v_next
    s.v_prev[0] = v_next
    _copy(x, s.x_prev)
    _copy(u, s.u_prev)
    return u, v_next

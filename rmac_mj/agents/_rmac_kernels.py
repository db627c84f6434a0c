"""Compiled RMAC step (the fast back end of :class:`rmac_mj.agents.rmac.RMAC`).

``act`` and ``update`` follow ``RMAC._act`` and ``RMAC._update`` (the numpy reference, which cites
Algorithm 2 line by line) statement by statement, on the memories' packed arrays (see
``rmac_mj.approximators._llr_kernels``), so one control step is two compiled calls instead of a few
dozen numpy ones. ``tests/test_rmac.py`` checks that both back ends produce the same trajectory.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rmac_mj.approximators import _llr_kernels as _k


def pack_params(agent) -> tuple:
    """The agent's constants as the kernels take them."""
    from rmac_mj.agents.rmac import BETA_U_ZERO
    cfg = agent.config
    return (np.ascontiguousarray(agent.vertices), agent.period.copy(),
            agent.action_space.low.copy(), agent.action_space.high.copy(),
            np.array([cfg.gamma, cfg.lam, cfg.alpha_c, cfg.alpha_r, BETA_U_ZERO]),
            np.array([cfg.inverse_query == "previous", cfg.critic_gradient_at == "next"],
                     dtype=np.int64))


def act(agent, x: np.ndarray, u_prev: np.ndarray) -> np.ndarray:
    """Greedy action f^-1(x, R(x)) (lines 10-11 without Delta u_k)."""
    return _act(agent.process._pack_cached(), agent.reference._pack_cached(), x, u_prev,
                agent._params)


def step(agent, reward: float, x: np.ndarray, du: np.ndarray) -> tuple[np.ndarray, float]:
    """One control step in one compiled call: u_k = sat(f^-1(x_k, R(x_k)) + Delta u_k) with the
    models as they are (lines 10-12), then lines 13-28; returns (u_k, V_k)."""
    return _step(agent.process._pack_cached(), agent.reference._pack_cached(),
                 agent.critic._pack_cached(), agent.traces, agent._x_prev, agent._u_prev,
                 reward, x, agent._v_prev, du, agent._params)


def update(agent, reward: float, x: np.ndarray) -> float:
    """Lines 13-28; returns V_k."""
    return _update(agent.process._pack_cached(), agent.reference._pack_cached(),
                   agent.critic._pack_cached(), agent.traces, agent._x_prev, agent._u_prev,
                   reward, x, agent._v_prev, agent._params)


@njit(cache=True)
def _inverse(P, x, x_desired, u_query, period, low, high, beta_u_zero):
    """f^-1(x, x_desired) linearised at (x, u_query); see RMAC._inverse."""
    n = x.shape[0]
    m = u_query.shape[0]
    z = np.empty(n + m)
    z[:n] = x
    z[n:] = u_query
    idx = np.empty(P[7][0], dtype=np.int64)
    beta = np.empty((n, n + m + 1))
    pred = np.empty(n)
    _k.query(P, z, idx, beta, pred)
    beta_u = np.ascontiguousarray(beta[:, n:n + m])
    u = np.zeros(m)
    if np.abs(beta_u).max() <= beta_u_zero * max(1.0, np.abs(beta[:, :n]).max()):
        return u
    e = np.empty(n)
    for j in range(n):
        e[j] = _k.wrap(x_desired[j] - pred[j], period[j])
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
        u[i] = min(max(u[i], low[i]), high[i])
    return u


@njit(cache=True)
def _act(P, R, x, u_prev, params):
    vertices, period, low, high, rates, flags = params
    n = x.shape[0]
    idx = np.empty(R[7][0], dtype=np.int64)
    beta = np.empty((n, n + 1))
    x_desired = np.empty(n)
    _k.query(R, x, idx, beta, x_desired)  # line 10
    u_query = u_prev.copy() if flags[0] else np.zeros(u_prev.shape[0])
    return _inverse(P, x, x_desired, u_query, period, low, high, rates[4])  # line 11


@njit(cache=True)
def _update(P, R, C, traces, x_prev, u_prev, reward, x, v_prev, params):
    vertices, period, low, high, rates, flags = params
    gamma, lam, alpha_c, alpha_r = rates[0], rates[1], rates[2], rates[3]
    n = x.shape[0]
    m = u_prev.shape[0]
    # Line 14: insert [x_{k-1}, u_{k-1} | x_k] in M^P.
    z = np.empty(n + m)
    z[:n] = x_prev
    z[n:] = u_prev
    _k.insert(P, z, x, -1)
    # Line 16: best reachable state, X_R = beta^P U_R linearised at (x_{k-1}, u_{k-1}).
    idx = np.empty(max(P[7][0], max(R[7][0], C[7][0])), dtype=np.int64)
    beta_p = np.empty((n, n + m + 1))
    pred = np.empty(n)
    _k.query(P, z, idx, beta_p, pred)
    nv = vertices.shape[0]
    reachable = np.empty((nv, n))
    for v in range(nv):
        for j in range(n):
            s = pred[j]
            for i in range(m):
                s += beta_p[j, n + i] * (vertices[v, i] - u_prev[i])
            reachable[v, j] = s
    beta_c = np.empty((1, n + 1))
    v_pred = np.empty(1)
    _k.query(C, x, idx, beta_c, v_pred)
    v_k = v_pred[0]
    slope = beta_c[0, :n].copy()
    x_c = x
    if not flags[1]:
        _k.query(C, x_prev, idx, beta_c, v_pred)
        slope = beta_c[0, :n].copy()
        x_c = x_prev
    best = 0
    best_value = -np.inf
    for v in range(nv):
        value = 0.0
        for j in range(n):
            value += slope[j] * _k.wrap(reachable[v, j] - x_c[j], period[j])
        if value > best_value:
            best_value = value
            best = v
    x_r = np.empty(n)
    for j in range(n):
        x_r[j] = _k.wrap(reachable[best, j], period[j])
    # Lines 17-20: insert [x_{k-1} | x_r] in M^R, move K(x_{k-1}) towards x_r.
    Xt, Y, stamp, meta, w, pin, pout, ip, fp, d = R
    nk = _k.search(Xt, meta[0], x_prev, w, pin, ip[1], ip[0], idx, d)
    _k.insert(R, x_prev, x_r, idx[0] if nk > 0 else -1)
    for a in range(nk):
        i = idx[a]
        for j in range(n):
            y = Y[i, j] + alpha_r * _k.wrap(x_r[j] - Y[i, j], period[j])
            Y[i, j] = _k.wrap(y, period[j])
    # Lines 22-28: TD(lambda) on the critic's samples; V_k computed above (line 22).
    Xt, Y, stamp, meta, w, pin, pout, ip, fp, d = C
    nk = _k.search(Xt, meta[0], x_prev, w, pin, ip[1], ip[0], idx, d)
    v_in = np.empty(1)
    v_in[0] = v_prev
    slot = _k.insert(C, x_prev, v_in, idx[0] if nk > 0 else -1)  # line 23
    delta = reward + gamma * v_k - v_prev  # line 24
    decay = lam * gamma
    count = meta[0]
    for i in range(count):
        traces[i] *= decay  # line 26
    for a in range(nk):
        traces[idx[a]] = 1.0
    traces[slot] = 1.0
    step = alpha_c * delta
    for i in range(count):
        Y[i, 0] += step * traces[i]  # line 27
    return v_k


@njit(cache=True)
def _step(P, R, C, traces, x_prev, u_prev, reward, x, v_prev, du, params):
    low, high = params[2], params[3]
    u = _act(P, R, x, u_prev, params)
    for i in range(u.shape[0]):
        u[i] = min(max(u[i] + du[i], low[i]), high[i])
    v_k = _update(P, R, C, traces, x_prev, u_prev, reward, x, v_prev, params)
    return u, v_k

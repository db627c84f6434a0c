"""Numba kernels of the redundancy scores of ``replacement='redundancy'``.

The equations are in ``LLRMemory``'s docstring; the numpy version is ``LLRMemory``'s numpy path.
They read an ``LLRState``'s fields and write its ``redundancy``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rmac_mj.approximators._llr_fit import fit
from rmac_mj.approximators._llr_search import wrap

MEASURE_DISTANCE = 0
MEASURE_MISFIT = 1


@njit(cache=True, inline="always")
def distance_to(state, i, xq):
    """The weighted distance of sample i to a canonical xq: the 1-norm, or the 2-norm (not its
    square, which the search uses), of w * wrap(x_i - xq)."""
    d = 0.0
    for j in range(xq.shape[0]):
        e = state.weights[j] * wrap(state.Xt[j, i] - xq[j], state.in_period[j])
        d += abs(e) if state.norm == 1 else e * e
    return d if state.norm == 1 else np.sqrt(d)


@njit(cache=True, inline="always")
def misfits(state, xq, y, idx, nk, out):
    """Squared misfits of the new sample [xq | y] (xq canonical) and of its neighbours
    ``idx[:nk]`` under one local model: the affine fit (``fit``, unclipped) to these nk + 1
    samples at xq. out[0] is the new sample's, out[1 + a] that of idx[a]; each is
    sum_o wrap(y_o - y_hat_o)^2 with y_hat = pred + beta_x wrap(x - xq)."""
    n = xq.shape[0]
    m = y.shape[0]
    Xt2 = np.empty((n, nk + 1))
    Y2 = np.empty((nk + 1, m))
    for j in range(n):
        Xt2[j, 0] = xq[j]
    for o in range(m):
        Y2[0, o] = y[o]
    for a in range(nk):
        i = idx[a]
        for j in range(n):
            Xt2[j, a + 1] = state.Xt[j, i]
        for o in range(m):
            Y2[a + 1, o] = state.Y[i, o]
    rows = np.arange(nk + 1)
    beta = np.empty((m, n + 1))
    pred = np.empty(m)
    fit(
        Xt2,
        Y2,
        rows,
        nk + 1,
        xq,
        state,
        np.bool_(False),  # unclipped; a bool, not the literal False (one compiled fit)
        beta,
        pred,
    )
    for a in range(nk + 1):
        e2 = 0.0
        for o in range(m):
            y_hat = pred[o]
            for j in range(n):
                y_hat += beta[o, j] * wrap(Xt2[j, a] - xq[j], state.in_period[j])
            r = wrap(Y2[a, o] - y_hat, state.out_period[o])
            e2 += r * r
        out[a] = e2


@njit(cache=True, inline="always")
def score(state, xq, y, idx, nk):
    """Update the redundancy scores of the neighbours ``idx[:nk]`` of a new sample [xq | y] (xq
    canonical) and return the new sample's own score (``LLRMemory`` documents the equations):
    rho_i <- (1 - eta) rho_i + eta c_i with c_i = -d(x_i, xq) ('distance') or -e_i^2
    ('misfit'); the new sample's is rho_* = (1 - eta) mean_i rho_i + eta c_*, the mean over the
    updated neighbours, with c_* = -min_i d(x_i, xq), resp. -e_*^2 (0 with no neighbours)."""
    rho = state.redundancy
    eta = state.smoothing
    if nk <= 0:
        return 0.0
    own = 0.0
    if state.measure == MEASURE_DISTANCE:
        for a in range(nk):
            i = idx[a]
            d = distance_to(state, i, xq)
            if a == 0:
                own = -d
            rho[i] = (1.0 - eta) * rho[i] - eta * d
    else:
        e2 = np.empty(nk + 1)
        misfits(state, xq, y, idx, nk, e2)
        for a in range(nk):
            i = idx[a]
            rho[i] = (1.0 - eta) * rho[i] - eta * e2[a + 1]
        own = -e2[0]
    mean = 0.0
    for a in range(nk):
        mean += rho[idx[a]]
    return (1.0 - eta) * (mean / nk) + eta * own

"""Numba kernel of LLR's local fit: the affine least-squares model of K neighbours (the fast path of
``fit_numpy`` in :mod:`rmac_mj.approximators.llr_numpy`: the same normal equations, the same
conditioning)."""

from __future__ import annotations

import numpy as np
from numba import njit

from rmac_mj.approximators._llr_search import wrap


@njit(cache=True, inline="always")
def _rotate(M, a, b, c, s):
    """Columns a and b of M turned by the Jacobi rotation J (cosine c, sine s), in place:
    M[:, a], M[:, b] <- c M[:, a] - s M[:, b], s M[:, a] + c M[:, b]."""
    for k in range(M.shape[0]):
        mka = M[k, a]
        mkb = M[k, b]
        M[k, a] = c * mka - s * mkb
        M[k, b] = s * mka + c * mkb


@njit(cache=True, inline="always")
def jacobi_eigh(G, evals, evecs):
    """Eigen-decomposition G = evecs diag(evals) evecs^T of a small symmetric matrix (p, p) by cyclic
    Jacobi rotations (evals unsorted; G is overwritten). For p <= 4 this is twice as fast as
    LAPACK through numpy.linalg.eigh, and accurate for the small eigenvalues the cutoff tests."""
    p = G.shape[0]
    for a in range(p):
        for b in range(p):
            evecs[a, b] = 1.0 if a == b else 0.0
    for _sweep in range(50):
        off = 0.0
        scale = 0.0
        for a in range(p):
            scale += G[a, a] * G[a, a]
            for b in range(a + 1, p):
                off += G[a, b] * G[a, b]
        if off <= 1e-30 * scale:
            break
        for a in range(p - 1):
            for b in range(a + 1, p):
                gab = G[a, b]
                if gab == 0.0:
                    continue
                theta = (G[b, b] - G[a, a]) / (2.0 * gab)
                t = (1.0 if theta >= 0 else -1.0) / (abs(theta) + np.sqrt(theta * theta + 1.0))
                c = 1.0 / np.sqrt(t * t + 1.0)
                s = t * c
                _rotate(G, a, b, c, s)  # G <- G J, then J^T G: its columns, then its rows
                _rotate(G.T, a, b, c, s)
                _rotate(evecs, a, b, c, s)
    for a in range(p):
        evals[a] = G[a, a]


@njit(cache=True)
def fit(Xt, Y, idx, nk, xq, settings, clip, beta_out, pred_out):
    """Affine least-squares fit to the neighbours ``idx[:nk]``, centred on and valid around ``xq``,
    with the ``settings`` (weights w, periods, cutoff, ridge) of a memory's LLRState.

    The regressors are the weighted, wrapped offsets z_i = w * wrap(x_i - xq) plus a 1. The normal
    matrix G = A^T A (+ ridge on the slopes) is inverted through its eigen-decomposition, dropping
    eigenvalues below ``eig_cutoff * max`` (a truncated SVD of A with relative cutoff
    sqrt(eig_cutoff)); this gives the minimum-norm solution when the fit is under-determined.
    Periodic outputs are unwrapped around the nearest neighbour's output. Writes beta (m, n+1) in raw
    input units, with beta @ [xq; 1] == prediction, and the prediction (m,), clipped to the
    neighbours' output range when ``clip``.
    """
    w, in_period, out_period = settings.weights, settings.in_period, settings.out_period
    n, m = Xt.shape[0], Y.shape[1]
    p = n + 1
    if nk == 0:
        beta_out[:, :] = 0.0
        pred_out[:] = 0.0
        return
    A = np.empty((nk, p))
    Yn = np.empty((nk, m))
    for a in range(nk):
        i = idx[a]
        for j in range(n):
            A[a, j] = w[j] * wrap(Xt[j, i] - xq[j], in_period[j])
        A[a, n] = 1.0
        for o in range(m):
            if out_period[o] > 0.0 and a > 0:
                Yn[a, o] = Yn[0, o] + wrap(Y[i, o] - Y[idx[0], o], out_period[o])
            else:
                Yn[a, o] = Y[i, o]
    G = A.T @ A
    for j in range(n):
        G[j, j] += settings.ridge
    evals = np.empty(p)
    evecs = np.empty((p, p))
    jacobi_eigh(G, evals, evecs)
    top = evals.max()
    Ginv = np.zeros((p, p))
    for c in range(p):
        if evals[c] > settings.eig_cutoff * top and evals[c] > 0.0:
            for a in range(p):
                for b in range(p):
                    Ginv[a, b] += evecs[a, c] * evecs[b, c] / evals[c]
    g = Ginv @ (A.T @ Yn)  # (p, m)
    for o in range(m):
        pred = g[n, o]
        if clip:
            lo = Yn[0, o]
            hi = Yn[0, o]
            for a in range(1, nk):
                lo = min(lo, Yn[a, o])
                hi = max(hi, Yn[a, o])
            pred = min(max(pred, lo), hi)
        offset = pred
        for j in range(n):
            beta_out[o, j] = g[j, o] * w[j]
            offset -= beta_out[o, j] * xq[j]
        beta_out[o, n] = offset
        pred_out[o] = pred

"""Local Linear Regression in plain numpy: the readable reference that the compiled kernels follow.

:func:`search_numpy` orders samples by weighted distance (ties by index), :func:`fit_numpy` fits the
neighbours' affine model in the weighted, query-centred space; :func:`distance_numpy` and
:func:`misfit_numpy` are the redundancy measures.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class FitSettings(NamedTuple):
    """What a memory's local fit takes besides its samples (the compiled fit reads the same fields
    from the memory's LLRState): the input weighting (n,), the input and output periods (n,) and
    (m,) (0: not periodic), the relative eigenvalue cutoff and the ridge term."""

    weights: np.ndarray
    in_period: np.ndarray
    out_period: np.ndarray
    eig_cutoff: float
    ridge: float


def wrap(d: np.ndarray, period: np.ndarray) -> np.ndarray:
    """Differences ``d`` (shape (..., n)) wrapped to [-period/2, period/2) where period > 0."""
    d = np.asarray(d, dtype=float)
    safe = np.where(period > 0, period, 1.0)
    return np.where(period > 0, d - safe * np.floor(d / safe + 0.5), d)


def search_numpy(
    X: np.ndarray, xq: np.ndarray, weights: np.ndarray, period: np.ndarray, norm: int, k: int
) -> np.ndarray:
    """Indices of the min(k, len(X)) nearest rows of X (shape (N, n)) to xq (n,), nearest first."""
    e = weights * wrap(X - xq, period)
    d = np.abs(e).sum(axis=1) if norm == 1 else (e * e).sum(axis=1)
    return np.argsort(d, kind="stable")[:k]


def fit_numpy(
    X: np.ndarray, Y: np.ndarray, xq: np.ndarray, settings: FitSettings, clip: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Local affine model of neighbours X (k, n) -> Y (k, m) around xq (n,), with a memory's
    ``settings``.

    Returns (prediction of shape (m,), beta of shape (m, n+1)) with beta @ [xq; 1] == prediction.
    See ``_llr_fit.fit`` for the method; this is the same computation in numpy.
    """
    weights, in_period, out_period, eig_cutoff, ridge = settings
    k, n = X.shape
    m = Y.shape[1]
    if k == 0:
        return np.zeros(m), np.zeros((m, n + 1))
    A = np.hstack([weights * wrap(X - xq, in_period), np.ones((k, 1))])
    Yn = Y.copy()
    Yn[1:] = Y[0] + wrap(Y[1:] - Y[0], out_period)  # no-op for non-periodic outputs
    G = A.T @ A + ridge * np.diag(np.r_[np.ones(n), 0.0])
    evals, evecs = np.linalg.eigh(G)
    keep = (evals > eig_cutoff * evals[-1]) & (evals > 0)
    G_inv = (evecs[:, keep] / evals[keep]) @ evecs[:, keep].T
    g = G_inv @ (A.T @ Yn)  # (n+1, m): slopes in weighted units, then the value at xq
    pred = g[n].copy()
    if clip:
        pred = np.clip(pred, Yn.min(axis=0), Yn.max(axis=0))
    beta = np.empty((m, n + 1))
    beta[:, :n] = (g[:n] * weights[:, None]).T
    beta[:, n] = pred - beta[:, :n] @ xq
    return pred, beta


def distance_numpy(
    X: np.ndarray, xq: np.ndarray, weights: np.ndarray, period: np.ndarray, norm: int
) -> np.ndarray:
    """Weighted distances (shape (k,)) of the rows of X (k, n) to xq: the 1-norm or the 2-norm (not
    squared) of w * wrap(x - xq)."""
    e = weights * wrap(X - xq, period)
    return np.abs(e).sum(axis=1) if norm == 1 else np.sqrt((e * e).sum(axis=1))


def misfit_numpy(X: np.ndarray, Y: np.ndarray, xq: np.ndarray, settings: FitSettings) -> np.ndarray:
    """Squared residuals (shape (k,)) of the samples X (k, n) -> Y (k, m) under their one affine
    fit at xq (``fit_numpy``, unclipped): |wrap(y - pred - beta_x wrap(x - xq))|^2."""
    pred, beta = fit_numpy(X, Y, xq, settings, False)
    n = X.shape[1]
    fitted = pred + wrap(X - xq, settings.in_period) @ beta[:, :n].T
    r = wrap(Y - fitted, settings.out_period)
    return (r * r).sum(axis=1)

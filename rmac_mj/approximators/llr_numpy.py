"""Local Linear Regression in plain numpy: the readable reference of :mod:`rmac_mj.approximators.llr`
(``LLRMemory(backend='numpy')``), which the compiled kernels (``_llr_search``, ``_llr_fit``,
``_llr_kernels``) follow step by step.

The search (:func:`search_numpy`) orders samples by the weighted distance, ties by index as a
stable sort; the fit (:func:`fit_numpy`) is the affine least-squares model of the neighbours in
the weighted, query-centred input space, conditioned as the memory says. Redundancy scores (the
``replacement='redundancy'`` rule) are measured by :func:`distance_numpy` and
:func:`misfit_numpy`:

``redundancy`` ['distance'] and ``redundancy_smoothing`` [0.1]: the score of
  ``replacement='redundancy'``, the scheme issue 14 describes of the authors' code (a redundancy
  score per sample, smoothed over updates; the squared model misfit for the process memory, the
  distance for the others). Its details are our own choices, made precise here. Every sample i
  carries a score rho_i (higher: more redundant). When a sample [x_* | y_*] is inserted, with K(x_*)
  its K nearest stored samples (before the insertion), each neighbour's score is smoothed
  exponentially towards a redundancy measure c_i,

      rho_i <- (1 - eta) rho_i + eta c_i            for i in K(x_*),   eta = redundancy_smoothing,

  and the new sample starts from its neighbourhood's level with one such step towards its own
  measure, rho_* = (1 - eta) mean_{i in K(x_*)} rho_i + eta c_* (0 on an empty memory). The measures:

  - 'distance': c_i = -d(x_i, x_*), the weighted distance of the memory (1- or 2-norm of
    w * wrap(x_i - x_*)); c_* = -min_i d(x_i, x_*). A sample close to new samples is redundant.
  - 'misfit': one affine model is fitted (as a query, unclipped) at x_* to the new sample and its
    neighbours, and c_j = -e_j^2 with e_j^2 = |wrap(y_j - y_hat(x_j))|^2 its squared residual, for
    the neighbours and for the new sample alike. A sample the local model of its neighbourhood
    predicts well adds little and is redundant; one it misfits holds information (a bend of the
    function, or noise: this measure keeps outliers, which the process memory's deterministic
    dynamics make rare).

  Once full, the new sample replaces the stored sample of highest score (first of equals), after
  its neighbours' scores have been updated; the new sample itself is always stored. Our choices:
  scores change only on insertion (a query leaves the memory unchanged, so greedy trials and
  plots do not alter what is forgotten); the new sample's start above (a first version started it
  at c_* itself: a new sample is then judged by its single nearest distance or its own misfit while
  the others' scores are averages, so it was nearly always the most redundant, the next sample
  replaced it, and the memories stopped taking in new states: RMAC got stuck in 5 of 10
  experiments, docs/studies/memory-management.md); ``fit`` scores each given sample by its own
  measure among the others (c_i as if inserted last). eta = 0.1 averages a score over roughly its
  last ten neighbourhood events.
"""

from __future__ import annotations

import numpy as np


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
    X: np.ndarray,
    Y: np.ndarray,
    xq: np.ndarray,
    weights: np.ndarray,
    in_period: np.ndarray,
    out_period: np.ndarray,
    eig_cutoff: float,
    ridge: float,
    clip: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """Local affine model of neighbours X (k, n) -> Y (k, m) around xq (n,).

    Returns (prediction of shape (m,), beta of shape (m, n+1)) with beta @ [xq; 1] == prediction.
    See ``_llr_fit.fit`` for the method; this is the same computation in numpy.
    """
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


def misfit_numpy(
    X: np.ndarray,
    Y: np.ndarray,
    xq: np.ndarray,
    weights: np.ndarray,
    in_period: np.ndarray,
    out_period: np.ndarray,
    eig_cutoff: float,
    ridge: float,
) -> np.ndarray:
    """Squared residuals (shape (k,)) of the samples X (k, n) -> Y (k, m) under their one affine
    fit at xq (``fit_numpy``, unclipped): |wrap(y - pred - beta_x wrap(x - xq))|^2."""
    pred, beta = fit_numpy(X, Y, xq, weights, in_period, out_period, eig_cutoff, ridge, False)
    n = X.shape[1]
    fitted = pred + wrap(X - xq, in_period) @ beta[:, :n].T
    r = wrap(Y - fitted, out_period)
    return (r * r).sum(axis=1)

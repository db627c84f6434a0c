"""Interquartile means, stratified-bootstrap intervals, improvement probability, profiles.

After Agarwal et al., NeurIPS 2021. Scores: one number per experiment (higher is better), one array
per task; every interval is a percentile bootstrap within tasks (``scipy.stats.bootstrap``, fixed
seed), reproducible to the bit.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

#: Confidence level of every interval.
CONFIDENCE = 0.95
#: Bootstrap resamples per interval.
N_RESAMPLES = 10_000
#: Seed of the bootstrap's resampling: intervals are reproducible.
SEED = 0
#: The fraction trimmed from each end for the interquartile mean.
IQM_TRIM = 0.25


@dataclasses.dataclass(frozen=True)
class Estimate:
    """A point estimate with its confidence interval [low, high] (NaN where it cannot be computed)."""

    value: float
    low: float
    high: float

    def as_dict(self) -> dict[str, Any]:
        """``{"value": v, "ci95": [low, high]}`` with None for NaN (JSON has no NaN)."""

        def clean(v: float) -> float | None:
            return None if np.isnan(v) else float(v)

        return {"value": clean(self.value), "ci95": [clean(self.low), clean(self.high)]}


def _strata(scores: Any, name: str = "scores") -> tuple[np.ndarray, ...]:
    """``scores`` as a tuple of 1-D float arrays, one per task: a 1-D array (or list of numbers) is
    one task. ValueError unless every task has finite scores."""
    if isinstance(scores, np.ndarray) or all(np.ndim(v) == 0 for v in scores):
        parts = [np.asarray(scores, dtype=float)]
    else:
        parts = [np.asarray(part, dtype=float) for part in scores]
    if not parts or any(p.ndim != 1 or p.size == 0 for p in parts):
        raise ValueError(
            f"{name} must be a non-empty 1-D array of per-experiment scores, or a "
            f"sequence of them (one per task)"
        )
    if not all(np.all(np.isfinite(p)) for p in parts):
        raise ValueError(f"{name} must be finite")
    return tuple(parts)


def iqm(scores: Any, axis: int = -1) -> np.ndarray | float:
    """The interquartile mean: the mean of the middle 50% of ``scores`` along ``axis``
    (``scipy.stats.trim_mean`` with 25% cut from each end: ``floor(n / 4)`` scores)."""
    from scipy import stats  # lazily: scipy.stats takes half a second to import

    return stats.trim_mean(np.asarray(scores, dtype=float), IQM_TRIM, axis=axis)


def _bootstrap(
    strata: tuple[np.ndarray, ...], statistic, confidence: float, n_resamples: int, seed: int
):
    """The stratified percentile bootstrap interval of ``statistic(*strata, axis)``; NaNs when a
    stratum has fewer than two experiments (nothing to resample).

    Percentile intervals are the paper's and its library's (rliable) default, so numbers here
    compare with published ones; BCa's jackknife acceleration is erratic for a trimmed mean of ten
    experiments with ties. scipy rather than rliable: rliable's repository was archived in October
    2025, and every estimate here is a few lines over ``scipy.stats.trim_mean`` and
    ``scipy.stats.bootstrap``.
    """
    if min(len(s) for s in strata) < 2:
        return None
    from scipy import stats

    result = stats.bootstrap(
        strata,
        statistic,
        vectorized=True,
        paired=False,
        confidence_level=confidence,
        n_resamples=n_resamples,
        method="percentile",
        rng=np.random.default_rng(seed),
    )
    return result.confidence_interval


def iqm_interval(
    scores: Any, confidence: float = CONFIDENCE, n_resamples: int = N_RESAMPLES, seed: int = SEED
) -> Estimate:
    """The IQM of ``scores`` (pooled over tasks) with its stratified-bootstrap interval.

    Args:
      scores: ndarray of shape (experiments,), or a sequence of them, one per task.
    """
    strata = _strata(scores)

    def statistic(*samples: np.ndarray, axis: int = -1) -> np.ndarray:
        return iqm(np.concatenate(samples, axis=axis), axis=axis)

    value = float(iqm(np.concatenate(strata)))
    interval = _bootstrap(strata, statistic, confidence, n_resamples, seed)
    if interval is None:
        return Estimate(value, np.nan, np.nan)
    return Estimate(value, float(interval.low), float(interval.high))


def _improvement(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """P(X > Y) over every pair of the last axes' entries, ties counting half; shape x.shape[:-1]."""
    xs, ys = x[..., :, None], y[..., None, :]
    return (xs > ys).mean(axis=(-2, -1)) + 0.5 * (xs == ys).mean(axis=(-2, -1))


def probability_of_improvement(
    x: Any, y: Any, confidence: float = CONFIDENCE, n_resamples: int = N_RESAMPLES, seed: int = SEED
) -> Estimate:
    """P(X > Y): the probability that an experiment of learner X scores higher than one of learner Y
    (ties count half; the Mann-Whitney U statistic over n m), averaged over tasks, with its interval
    from resampling both learners' experiments, each within its task.

    0.5 for identical samples, 1 when every score of X beats every score of Y.

    Args:
      x, y: ndarrays of shape (experiments,) (the counts may differ), or sequences of them with one
        entry per task, in the same task order.
    """
    xs, ys = _strata(x, "x"), _strata(y, "y")
    if len(xs) != len(ys):
        raise ValueError(
            f"x and y must have scores for the same tasks, got {len(xs)} and {len(ys)}"
        )
    k = len(xs)

    def statistic(*samples: np.ndarray, axis: int = -1) -> np.ndarray:
        return np.mean([_improvement(samples[i], samples[k + i]) for i in range(k)], axis=0)

    value = float(statistic(*xs, *ys))
    interval = _bootstrap(xs + ys, statistic, confidence, n_resamples, seed)
    if interval is None:
        return Estimate(value, np.nan, np.nan)
    return Estimate(value, float(interval.low), float(interval.high))


def pairwise_improvement(
    scores: Mapping[str, Any],
    confidence: float = CONFIDENCE,
    n_resamples: int = N_RESAMPLES,
    seed: int = SEED,
) -> dict[str, dict]:
    """:func:`probability_of_improvement` of every pair of learners, in the order given, keyed
    ``"A > B"`` (P(B > A) is 1 - P(A > B)), as JSON-ready dicts ``{"value", "ci95", "experiments":
    [n_A, n_B]}`` (one task each; the counts are summed over tasks otherwise)."""
    table = {}
    for a, b in itertools.combinations(scores, 2):
        estimate = probability_of_improvement(scores[a], scores[b], confidence, n_resamples, seed)
        counts = [sum(len(part) for part in _strata(scores[name])) for name in (a, b)]
        table[f"{a} > {b}"] = {**estimate.as_dict(), "experiments": counts}
    return table


def performance_profile(
    scores: Any,
    thresholds: Sequence[float],
    confidence: float = CONFIDENCE,
    n_resamples: int = N_RESAMPLES,
    seed: int = SEED,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fraction of experiments scoring above each threshold (averaged over tasks), with its
    pointwise stratified-bootstrap interval.

    Returns:
      (fraction, low, high), each ndarray of shape (len(thresholds),); low and high are NaN when a
      task has fewer than two experiments.
    """
    strata = _strata(scores)
    taus = np.asarray(thresholds, dtype=float).reshape(-1)

    def statistic(*samples: np.ndarray, axis: int = -1) -> np.ndarray:
        fractions = [
            (np.moveaxis(s, axis, -1)[..., None, :] > taus[:, None]).mean(axis=-1) for s in samples
        ]
        return np.moveaxis(np.mean(fractions, axis=0), -1, 0)

    fraction = statistic(*strata)
    interval = _bootstrap(strata, statistic, confidence, n_resamples, seed)
    if interval is None:
        nan = np.full(taus.shape, np.nan)
        return fraction, nan, nan.copy()
    return fraction, np.asarray(interval.low), np.asarray(interval.high)

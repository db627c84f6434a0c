"""Learning-curve statistics, provenance and atomic result files.

Everything written here is plain: JSON, CSV and ``.npz`` files that numpy or pandas read without this
package (``numpy.load(..., allow_pickle=False)``).
"""

from __future__ import annotations

import csv
import dataclasses
import importlib.metadata
import io
import json
import os
import pathlib
import platform
import subprocess
import tempfile
from typing import Any, Iterable, Sequence

import numpy as np

#: Trials over which the final level is averaged.
FINAL_WINDOW = 50
#: The "first minutes" over which the early return is averaged (simulated time; the paper's Fig. 2
#: compares the learners over their first 10 minutes).
EARLY_MINUTES = 10.0
#: Significance level of the end-of-run comparison of learners (two-sided).
SIGNIFICANCE_LEVEL = 0.05
#: With fewer experiments than this per learner, 95% intervals are too wide to read (the Student t
#: factor exceeds 2.7, and the standard deviation itself is a rough guess).
FEW_EXPERIMENTS = 5


def confidence_interval(samples: np.ndarray, confidence: float = 0.95, axis: int = 0):
    """Student-t confidence interval of the mean along ``axis``.

    Args:
      samples: ndarray with the experiments along ``axis``.
    Returns:
      (mean, low, high), each of the shape of ``samples`` without ``axis``; low and high are NaN where
      fewer than two samples exist.
    """
    samples = np.asarray(samples, dtype=float)
    n = samples.shape[axis]
    mean = samples.mean(axis=axis)
    if n < 2:
        nan = np.full_like(mean, np.nan)
        return mean, nan, nan.copy()
    # Imported here, not at the top: every worker process imports this module, and scipy.stats
    # alone takes about half a second of CPU to import.
    from scipy import stats

    half = stats.t.ppf(0.5 + confidence / 2, n - 1) * samples.std(axis=axis, ddof=1) / np.sqrt(n)
    return mean, mean - half, mean + half


def _check_trial_seconds(trial_seconds) -> float:
    if not (isinstance(trial_seconds, (int, float, np.floating, np.integer))
            and np.isfinite(trial_seconds) and trial_seconds > 0):
        raise ValueError(f"trial_seconds must be a positive number (simulated seconds per trial), "
                         f"got {trial_seconds!r}")
    return float(trial_seconds)


def minutes_to_within(curve: np.ndarray, fraction: float = 0.1, window: int = FINAL_WINDOW, *,
                      trial_seconds: float) -> float:
    """Simulated minutes until ``curve`` first comes within ``fraction`` of its final level.

    The final level is the mean of the last ``window`` trials; trial t (1-based) ends at
    t * trial_seconds.
    """
    trial_seconds = _check_trial_seconds(trial_seconds)
    curve = np.asarray(curve, dtype=float)
    final = curve[-window:].mean()
    close = np.abs(curve - final) <= fraction * abs(final)
    first = int(np.argmax(close)) + 1  # close[-1] may be False, but the window mean lies inside it
    return first * trial_seconds / 60.0


def trials_in(minutes: float, trial_seconds: float) -> int:
    """The number of whole trials of ``trial_seconds`` that end within ``minutes`` (at least 1)."""
    trial_seconds = _check_trial_seconds(trial_seconds)
    # The small tolerance keeps e.g. 10 min / 3 s at 200 trials despite rounding.
    return max(1, int(np.floor(minutes * 60.0 / trial_seconds + 1e-9)))


def stuck_threshold(reference_return: float | None) -> float | None:
    """The final level below which an experiment counts as stuck: worse than the near-optimal
    reference by more than the reference's own magnitude (for a negative, cost-like return: more than
    twice its cost; dc_pendulum/swingup: 2 x -748 = -1496). None without a reference."""
    if reference_return is None:
        return None
    return float(reference_return - abs(reference_return))


def _nan_to_none(values) -> Any:
    array = np.asarray(values, dtype=float)
    if array.ndim == 0:
        return None if not np.isfinite(array) else float(array)
    return [None if not np.isfinite(v) else float(v) for v in array]


def summarise(returns: np.ndarray, greedy: np.ndarray | None = None,
              greedy_trials: Sequence[int] = (), optimal_return: float | None = None, *,
              trial_seconds: float) -> dict:
    """The summary of one learner: returns is an ndarray of shape (experiments, trials).

    ``greedy`` (experiments, evaluations) holds the greedy-trial returns after the trials listed in
    ``greedy_trials``; ``trial_seconds`` is the task's trial length (simulated s), which turns trials
    into minutes. Stuck experiments are counted only against a reference (``optimal_return``; see
    :func:`stuck_threshold`), else ``stuck_experiments`` is None.
    """
    returns = np.asarray(returns, dtype=float)
    n_experiments, n_trials = returns.shape
    window = min(FINAL_WINDOW, n_trials)
    early = trials_in(EARLY_MINUTES, trial_seconds)
    mean, low, high = confidence_interval(returns)
    finals = returns[:, -window:].mean(axis=1)
    final_mean, final_low, final_high = confidence_interval(finals)
    stuck_below = stuck_threshold(optimal_return)
    summary = {
        "experiments": n_experiments,
        "trials": n_trials,
        "mean_return_per_trial": mean.tolist(),
        "ci95_low_per_trial": _nan_to_none(low),
        "ci95_high_per_trial": _nan_to_none(high),
        "final_return_mean": float(final_mean),
        "final_return_ci95": [_nan_to_none(final_low), _nan_to_none(final_high)],
        "final_return_per_experiment": finals.tolist(),
        "minutes_to_90pct": minutes_to_within(mean, window=window, trial_seconds=trial_seconds),
        "mean_return_first_10min": float(returns[:, :early].mean()),
        "first_10min_trials": min(early, n_trials),
        "stuck_below": stuck_below,
        "stuck_experiments": None if stuck_below is None else int(np.sum(finals < stuck_below)),
    }
    if optimal_return is not None:
        summary["gap_to_optimal"] = float(optimal_return - final_mean)
    if greedy is not None and len(greedy_trials):
        greedy = np.asarray(greedy, dtype=float)
        summary["greedy_eval_trials"] = [int(t) for t in greedy_trials]
        summary["greedy_return_per_eval"] = greedy.mean(axis=0).tolist()
    return summary


def compare_final_returns(finals: dict[str, Sequence[float]],
                          level: float = SIGNIFICANCE_LEVEL) -> list[dict[str, Any]]:
    """Welch's t-test (unequal variances, two-sided) of every pair of learners' final returns.

    Args:
      finals: learner -> its experiments' final returns (``final_return_per_experiment``).
    Returns:
      One dict per pair: ``learners`` [a, b], ``experiments`` [n_a, n_b], ``difference`` (mean a - mean
      b), ``p_value`` (None when a learner has fewer than 2 experiments or neither varies), ``better``
      (the learner with the higher mean when p < ``level``, else None) and ``level``.
    """
    names = list(finals)
    tests = []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            x, y = np.asarray(finals[a], dtype=float), np.asarray(finals[b], dtype=float)
            p_value = None
            if len(x) >= 2 and len(y) >= 2:
                from scipy import stats  # lazily, as in confidence_interval
                p = float(stats.ttest_ind(x, y, equal_var=False).pvalue)
                p_value = p if np.isfinite(p) else None
            difference = float(x.mean() - y.mean()) if len(x) and len(y) else None
            better = None
            if p_value is not None and p_value < level and difference:
                better = a if difference > 0 else b
            tests.append({"test": "Welch t-test, two-sided", "learners": [a, b],
                          "experiments": [len(x), len(y)], "difference": difference,
                          "p_value": p_value, "better": better, "level": level})
    return tests


def describe_test(test: dict[str, Any]) -> str:
    """One line for a result of :func:`compare_final_returns`."""
    a, b = test["learners"]
    if test["p_value"] is None:
        return (f"final returns, {a} vs {b}: no test possible ({test['experiments'][0]} and "
                f"{test['experiments'][1]} experiments; Welch's t-test needs 2 or more, with spread)")
    p = test["p_value"]
    p_text = f"p = {p:.2g}" if p >= 1e-4 else "p < 0.0001"
    if test["better"] is None:
        return (f"final returns, {a} vs {b}: difference {test['difference']:+.1f}, not significant "
                f"({p_text}, Welch's t-test; a difference this size needs more experiments to rank them)")
    worse = b if test["better"] == a else a
    return (f"final returns: {test['better']} better than {worse} by {abs(test['difference']):.1f}, "
            f"{p_text} (Welch's t-test, significant at {test['level']:g})")


def few_experiments_note(experiments: int) -> str:
    """The warning printed and drawn when ``experiments`` < :data:`FEW_EXPERIMENTS`."""
    return (f"note: {experiments} experiment{'s' if experiments != 1 else ''} per learner: too few to rank "
            f"the learners; the 95% intervals and the t-test assume normally distributed returns, which "
            f"fewer than {FEW_EXPERIMENTS} experiments cannot show")


def write_atomic(path: str | os.PathLike, write) -> pathlib.Path:
    """Call ``write(file_handle)`` on a temporary file beside ``path``, then rename it into place.

    A reader never sees a half-written ``path``: it is either absent or complete. The file gets the
    permissions a plain ``open(path, "w")`` would give (0666 less the umask), not the temporary file's
    private 0600, so results on a shared machine or cluster stay readable by the group.
    """
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle = tempfile.NamedTemporaryFile(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp",
                                         delete=False)
    try:
        with handle:
            write(handle)
        os.chmod(handle.name, 0o666 & ~_umask())
        os.replace(handle.name, path)
    except BaseException:
        pathlib.Path(handle.name).unlink(missing_ok=True)
        raise
    return path


def _umask() -> int:
    """The process's umask (read by setting it and putting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_json(path: str | os.PathLike, document: Any) -> pathlib.Path:
    text = json.dumps(document, indent=2, sort_keys=False, allow_nan=False)
    return write_atomic(path, lambda handle: handle.write(text.encode() + b"\n"))


def cached_json(path: str | os.PathLike, decode, compute, refresh: bool = False,
                announce=None, message: str = ""):
    """A result cached as JSON at ``path``: ``decode(document)`` of the file when it is there and
    readable (an unreadable or foreign entry is recomputed and overwritten), else ``compute()``,
    written with ``.to_json_dict()``. ``announce(message)`` is called before a computation."""
    path = pathlib.Path(path)
    if not refresh and path.is_file():
        try:
            with open(path) as handle:
                return decode(json.load(handle))
        except (OSError, ValueError, KeyError, TypeError):
            pass
    if announce is not None and message:
        announce(message)
    result = compute()
    try:
        write_json(path, result.to_json_dict())
    except OSError as err:
        raise ValueError(f"cannot write the cache entry {str(path)!r}: {err}") from err
    return result


def write_csv(path: str | os.PathLike, header: Sequence[str], rows: Iterable[Sequence[Any]]
              ) -> pathlib.Path:
    """A UTF-8 CSV file of ``header`` then ``rows``, written atomically (see :func:`write_atomic`)."""
    def write(handle) -> None:
        text = io.TextIOWrapper(handle, newline="", encoding="utf-8")
        writer = csv.writer(text)
        writer.writerow(header)
        writer.writerows(rows)
        text.flush()
        text.detach()
    return write_atomic(path, write)


def write_npz(path: str | os.PathLike, **arrays: np.ndarray) -> pathlib.Path:
    return write_atomic(path, lambda handle: np.savez(handle, **arrays))


def code_version() -> dict[str, Any]:
    """The package version and, in a git checkout, the commit and whether the tree is dirty."""
    version = {"package": _version("rmac-mj")}
    root = pathlib.Path(__file__).resolve().parents[2]
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True,
                                text=True, timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, timeout=10, check=True).stdout.strip()
        version["commit"] = commit
        version["dirty"] = bool(dirty)
    except (OSError, subprocess.SubprocessError):
        version["commit"] = None
    return version


def _version(distribution: str) -> str | None:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return None


def provenance() -> dict[str, Any]:
    """Package versions, code version and machine: stored beside every result."""
    return {
        "code": code_version(),
        "packages": {name: _version(name) for name in
                     ("mujoco", "dm-control", "numpy", "scipy", "numba", "matplotlib")},
        "python": platform.python_version(),
        "machine": {"cpus": os.cpu_count(), "processor": platform.processor() or platform.machine(),
                    "system": platform.system()},
    }


def as_jsonable(value: Any) -> Any:
    """Dataclasses, tuples and numpy scalars/arrays as plain JSON data."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return as_jsonable(dataclasses.asdict(value))
    if isinstance(value, dict):
        return {str(k): as_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [as_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value

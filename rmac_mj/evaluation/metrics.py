"""Learning-curve metrics: the one place where results are turned into numbers.

``reproduce``, ``sweep``, ``compare`` and the scripts read their numbers here. Curves: ndarrays
(experiments, trials) of sums of rewards per trial, times simulated; the mean with a Student-t 95%
interval and Welch's t-test.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

#: Trials over which the final level is averaged.
FINAL_WINDOW = 50
#: The "first minutes" over which the early return is averaged (simulated time; the paper's Fig. 2
#: compares the learners over their first 10 minutes).
EARLY_MINUTES = 10.0
#: A shorter early window, for the studies of how fast learning starts (sweeps report it).
FIRST_MINUTES = 5.0
#: Fractions of the near-optimal return the mean greedy curve is timed to (``summarise``:
#: ``greedy_trial_within_20pct`` and ``_10pct``).
GREEDY_WITHIN = (0.2, 0.1)
#: Significance level of the end-of-run comparison of learners (two-sided).
SIGNIFICANCE_LEVEL = 0.05
#: With fewer experiments than this per learner, 95% intervals are too wide to read (the Student t
#: factor exceeds 2.7, and the standard deviation itself is a rough guess), and a bootstrap has too
#: few distinct resamples to mean anything: the summaries withhold every interval and probability
#: of improvement below it (:func:`withheld`), saying why.
FEW_EXPERIMENTS = 5


def withheld(*experiments: int) -> str | None:
    """Why an interval or a probability of learners with these experiment counts is withheld, or
    None when each has :data:`FEW_EXPERIMENTS` or more."""
    fewest = min(experiments)
    if fewest >= FEW_EXPERIMENTS:
        return None
    counts = " and ".join(map(str, experiments))
    return (
        f"{counts} experiment{'s' if max(experiments) != 1 else ''}: too few for a 95% interval "
        f"or a probability (they need {FEW_EXPERIMENTS} or more per learner)"
    )


def shorter_than(minutes: float, n_trials: int, trial_seconds: float) -> bool:
    """Whether a run of ``n_trials`` trials lasts less than ``minutes`` of simulated time (then a
    window of its first ``minutes`` is undefined, not its whole run)."""
    return n_trials * _check_trial_seconds(trial_seconds) < minutes * 60.0 - 1e-9


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
    if not (
        isinstance(trial_seconds, (int, float, np.floating, np.integer))
        and np.isfinite(trial_seconds)
        and trial_seconds > 0
    ):
        raise ValueError(
            f"trial_seconds must be a positive number (simulated seconds per trial), "
            f"got {trial_seconds!r}"
        )
    return float(trial_seconds)


def minutes_to_within(
    curve: np.ndarray, fraction: float = 0.1, window: int = FINAL_WINDOW, *, trial_seconds: float
) -> float:
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


def first_reaching(curve: np.ndarray, trials: Sequence[int], level: float) -> int | None:
    """The first of ``trials`` (1-based trial numbers, shape (t,)) at which ``curve`` (shape (t,),
    e.g. the mean greedy return after those trials) is at or above ``level``; None if it never is."""
    above = np.asarray(curve, dtype=float) >= level
    return int(np.asarray(trials)[int(np.argmax(above))]) if above.any() else None


def within_optimal(optimal_return: float, fraction: float) -> float:
    """The return within ``fraction`` of a (negative) near-optimal return: -748 and 0.1 give -822.8."""
    return optimal_return - fraction * abs(optimal_return)


def trials_in(minutes: float, trial_seconds: float) -> int:
    """The number of whole trials of ``trial_seconds`` that end within ``minutes`` (at least 1)."""
    trial_seconds = _check_trial_seconds(trial_seconds)
    # The small tolerance keeps e.g. 10 min / 3 s at 200 trials despite rounding.
    return max(1, int(np.floor(minutes * 60.0 / trial_seconds + 1e-9)))


def stuck_threshold(reference_return: float | None) -> float | None:
    """The final level below which an experiment counts as stuck: worse than the near-optimal
    reference by more than the reference's own magnitude (for a negative, cost-like return: more than
    twice its cost; the paper's swing-up: 2 x -748 = -1496). None without a reference."""
    if reference_return is None:
        return None
    return float(reference_return - abs(reference_return))


def _nan_to_none(values) -> Any:
    array = np.asarray(values, dtype=float)
    if array.ndim == 0:
        return None if not np.isfinite(array) else float(array)
    return [None if not np.isfinite(v) else float(v) for v in array]


def final_returns(returns: np.ndarray, window: int = FINAL_WINDOW) -> np.ndarray:
    """Each experiment's final level: the mean of its last ``window`` trials (all, if fewer).

    Args:
      returns: ndarray of shape (experiments, trials).
    Returns:
      ndarray of shape (experiments,).
    """
    returns = np.asarray(returns, dtype=float)
    return returns[:, -min(window, returns.shape[1]) :].mean(axis=1)


def early_returns(returns: np.ndarray, minutes: float, trial_seconds: float) -> np.ndarray:
    """Each experiment's mean return over the trials that end within its first ``minutes`` of
    simulated time (at least one trial); ndarray of shape (experiments,)."""
    returns = np.asarray(returns, dtype=float)
    return returns[:, : trials_in(minutes, trial_seconds)].mean(axis=1)


def interval(samples: np.ndarray) -> list[float | None]:
    """[mean, low, high] of the 95% interval of the mean of ``samples`` (shape (experiments,));
    None where undefined (fewer than two samples)."""
    return _nan_to_none(np.stack(confidence_interval(np.asarray(samples, dtype=float))))


def _measured_minutes(
    env_steps: np.ndarray | None,
    env_step_seconds: float | None,
    returns: np.ndarray,
    trial_seconds: float,
) -> np.ndarray | None:
    """Simulated minutes at the end of every trial, shape (experiments, trials), from the
    environment steps that really ran (NaN after an experiment's last trial); None when they are
    not known (curves written before they were recorded) or equal what ``trial_seconds`` says."""
    if env_steps is None or env_step_seconds is None:
        return None
    env_steps = np.asarray(env_steps, dtype=float)
    ran = np.isfinite(returns)
    if env_steps.shape != returns.shape or not np.all(np.isfinite(env_steps[ran])):
        return None
    minutes = env_steps * float(env_step_seconds) / 60.0
    nominal = np.arange(1, returns.shape[1] + 1) * trial_seconds / 60.0
    if ran.all() and np.allclose(minutes, nominal, rtol=1e-9, atol=0.0):
        return None  # every trial ran to its limit: the nominal times, to the bit
    return np.where(ran, minutes, np.nan)


def _nan_interval(returns: np.ndarray):
    """:func:`confidence_interval` per trial over the experiments that ran it (NaN: did not)."""
    columns = [confidence_interval(column[np.isfinite(column)]) for column in returns.T]
    return tuple(np.array([c[k] for c in columns], dtype=float) for k in range(3))


@dataclasses.dataclass(frozen=True, kw_only=True)
class LearnerSummary:
    """One learner's row of ``summary.json``: its curves turned into numbers (:func:`summarise`).

    Returns are sums of rewards per trial; times are simulated minutes unless named otherwise;
    a ``*_ci95`` is [low, high] of a 95% interval, None where withheld or undefined. The fields
    after ``first_5min_iqm_ci95`` are written only where their inputs were known (a reference,
    greedy evaluations, environment steps, wall or CPU times): None, then, and not in the row.
    """

    experiments: int
    """Experiments of the learner."""
    trials: int | None = None
    """Trials of the longest experiment."""
    final_window: int | None = None
    """Trials averaged for each experiment's final level."""
    mean_return_per_trial: list[float]
    """The mean curve, one value per trial (over the experiments that ran it)."""
    ci95_low_per_trial: list[float | None]
    """Low end of the per-trial Student-t 95% interval (None: fewer than two experiments)."""
    ci95_high_per_trial: list[float | None]
    """High end of the per-trial Student-t 95% interval."""
    final_return_mean: float | None
    """Mean over the experiments of their final level."""
    final_return_ci95: list[float | None]
    """Student-t 95% interval of ``final_return_mean``."""
    final_return_per_experiment: list[float]
    """Each experiment's final level: the mean of its last ``final_window`` trials."""
    minutes_to_90pct: float
    """Minutes until the mean curve is within 10% of its final level."""
    mean_return_first_10min: float | None = None
    """Mean return of the trials within the first 10 minutes; None for a shorter run."""
    first_10min_trials: int | None = None
    """Trials within the first 10 minutes (the fewest of any experiment)."""
    mean_return_first_5min: float | None = None
    """Mean over the experiments of their mean return in the first 5 minutes; None for a shorter
    run."""
    first_5min_ci95: list[float | None] | None = None
    """Student-t 95% interval of ``mean_return_first_5min``."""
    first_5min_trials: int | None = None
    """Trials within the first 5 minutes (the fewest of any experiment)."""
    stuck_below: float | None = None
    """The final level below which an experiment is stuck (:func:`stuck_threshold`)."""
    stuck_experiments: int | None = None
    """Experiments whose final level is below ``stuck_below``; None without a reference."""
    intervals_withheld: str | None = None
    """Why every interval is withheld (too few experiments), or None."""
    trials_per_experiment: list[int] | None = None
    """Trials each experiment ran (runs that end early per experiment, or counted in steps)."""
    env_steps_per_trial: list[float | None] | None = None
    """Mean environment steps taken by the end of each trial."""
    env_steps_per_experiment: list[int] | None = None
    """Environment steps each experiment took."""
    simulated_minutes_per_experiment: list[float] | None = None
    """Simulated minutes each experiment learned for, from its steps."""
    trial_seconds_mean: float | None = None
    """Simulated seconds of a trial as run, on average."""
    greedy_eval_env_steps: list[float | None] | None = None
    """Mean environment steps by the end of each evaluated trial."""
    final_return_iqm: float | None = None
    """Interquartile mean of the final levels."""
    final_return_iqm_ci95: list[float | None] | None = None
    """Stratified-bootstrap 95% interval of ``final_return_iqm``."""
    first_5min_iqm: float | None = None
    """Interquartile mean of the experiments' first-5-minute returns."""
    first_5min_iqm_ci95: list[float | None] | None = None
    """Stratified-bootstrap 95% interval of ``first_5min_iqm``."""
    gap_to_optimal: float | None = None
    """The near-optimal return minus ``final_return_mean``."""
    greedy_eval_trials: list[int] | None = None
    """Trials after which the greedy policy was evaluated (1-based)."""
    greedy_return_per_eval: list[float | None] | None = None
    """Mean greedy return at each evaluation."""
    greedy_return_last_mean: float | None = None
    """Mean of each experiment's last greedy return."""
    greedy_return_last_ci95: list[float | None] | None = None
    """Student-t 95% interval of ``greedy_return_last_mean``."""
    greedy_trial_within_20pct: int | None = None
    """First evaluated trial whose mean greedy return is within 20% of the near-optimal return."""
    greedy_trial_within_10pct: int | None = None
    """The same within 10%."""
    experiment_wall_s_mean: float | None = None
    """Wall time of an experiment (s), the mean."""
    experiment_wall_s_total: float | None = None
    """Wall time of all experiments (s)."""
    experiment_cpu_s_mean: float | None = None
    """CPU time of an experiment (s), the mean."""
    cpu_s_per_simulated_minute: float | None = None
    """CPU seconds per simulated minute learned."""
    exploration_floor: float | None = None
    """The learner's exploration floor, where the run computed one (set by the runner)."""

    def as_dict(self) -> dict[str, Any]:
        """The row as written to ``summary.json``: every field, but those after
        ``first_5min_iqm_ci95`` only where known (the greedy fields with the evaluations; the
        trials within 20% and 10% with the evaluations and a reference)."""
        row = dataclasses.asdict(self)
        evaluated, referenced = self.greedy_eval_trials is not None, self.gap_to_optimal is not None
        kept = {
            "greedy_return_per_eval": evaluated,
            "greedy_return_last_mean": evaluated,
            "greedy_return_last_ci95": evaluated,
            "greedy_trial_within_20pct": evaluated and referenced,
            "greedy_trial_within_10pct": evaluated and referenced,
        }
        return {
            key: value
            for key, value in row.items()
            if key in _ALWAYS_WRITTEN or kept.get(key, value is not None)
        }

    @classmethod
    def from_dict(cls, row: dict[str, Any]) -> LearnerSummary:
        """A row of ``summary.json`` read back; what it lacks (a summary written before a field
        existed) is None, what it holds beyond the fields is left out."""
        return cls(**{key: row[key] for key in _FIELDS if key in row})


_FIELDS = [f.name for f in dataclasses.fields(LearnerSummary)]
_ALWAYS_WRITTEN = set(_FIELDS[: _FIELDS.index("intervals_withheld") + 1]) | {
    "final_return_iqm",
    "final_return_iqm_ci95",
    "first_5min_iqm",
    "first_5min_iqm_ci95",
}


@dataclasses.dataclass(frozen=True)
class _Runs:
    """How far each experiment of a learner ran: ``ran`` (experiments,) trials each, ``ragged``
    when some ended early (NaN after), ``window`` the trials of a final level."""

    experiments: int
    trials: int
    ragged: bool
    ran: np.ndarray
    window: int

    @classmethod
    def of(cls, returns: np.ndarray) -> _Runs:
        n_experiments, n_trials = returns.shape
        ragged = bool(not np.all(np.isfinite(returns)) and np.all(np.isfinite(returns[:, 0])))
        ran = np.sum(np.isfinite(returns), axis=1) if ragged else np.full(n_experiments, n_trials)
        return cls(n_experiments, n_trials, ragged, ran, min(FINAL_WINDOW, int(ran.min())))


def _curve_and_finals(returns: np.ndarray, runs: _Runs):
    """The per-trial (mean, low, high) of the experiments that ran each trial, and each
    experiment's final level over its own last trials."""
    if runs.ragged:
        mean, low, high = _nan_interval(returns)
        finals = np.array([row[:n][-runs.window :].mean() for row, n in zip(returns, runs.ran)])
    else:
        mean, low, high = confidence_interval(returns)
        finals = final_returns(returns, runs.window)
    return mean, low, high, finals


def _first_minutes(
    returns: np.ndarray,
    runs: _Runs,
    mean: np.ndarray,
    finals: np.ndarray,
    measured: np.ndarray | None,
    trial_seconds: float,
) -> tuple[np.ndarray, dict[str, Any]]:
    """Each experiment's mean return in the first 5 minutes, and the fields of the first minutes
    and of the minutes to 90%: from the nominal trial times, or from the minutes ``measured``."""
    early = trials_in(EARLY_MINUTES, trial_seconds)
    if measured is None:
        first = early_returns(returns, FIRST_MINUTES, trial_seconds)
        early_mean = float(returns[:, :early].mean())
        first_10min_trials = min(early, runs.trials)
        first_5min_trials = min(trials_in(FIRST_MINUTES, trial_seconds), runs.trials)
        # trial t (1-based) of the mean curve ends at t * trial_seconds
        to_90 = minutes_to_within(mean, window=runs.window, trial_seconds=trial_seconds)
    else:

        def within(minutes: float) -> np.ndarray:  # the trials ended by then (at least the first)
            inside = np.nan_to_num(measured, nan=np.inf) <= minutes + 1e-9
            inside[:, 0] = True
            return inside

        first = np.array([row[mask].mean() for row, mask in zip(returns, within(FIRST_MINUTES))])
        early_mean = float(np.mean(returns[within(EARLY_MINUTES)]))
        first_10min_trials = int(within(EARLY_MINUTES).sum(axis=1).min())
        first_5min_trials = int(within(FIRST_MINUTES).sum(axis=1).min())
        final = np.nanmean(mean[-runs.window :]) if not runs.ragged else float(np.mean(finals))
        close = np.abs(mean - final) <= 0.1 * abs(final)
        to_90 = float(np.nanmean(measured[:, int(np.argmax(close))]))
    return first, {
        "minutes_to_90pct": to_90,
        "mean_return_first_10min": (
            None if shorter_than(EARLY_MINUTES, runs.trials, trial_seconds) else early_mean
        ),
        "first_10min_trials": first_10min_trials,
        "first_5min_trials": first_5min_trials,
    }


def _step_counts(
    env_steps: np.ndarray | None,
    env_step_seconds: float | None,
    returns: np.ndarray,
    runs: _Runs,
    greedy_trials: Sequence[int] | None,
) -> dict[str, Any]:
    """The fields of the environment steps taken (none when they are not known), and the trials
    each experiment ran where they differ or are counted in steps; ``greedy_trials``: the trials
    evaluated greedily, or None."""
    fields: dict[str, Any] = {}
    if runs.ragged:
        fields["trials_per_experiment"] = [int(n) for n in runs.ran]
    steps = None if env_steps is None else np.asarray(env_steps, dtype=float)
    if (
        steps is None
        or steps.shape != returns.shape
        or not np.all(np.isfinite(steps[np.isfinite(returns)]))
    ):
        return fields
    last = steps[np.arange(runs.experiments), runs.ran - 1]
    fields["trials_per_experiment"] = [int(n) for n in runs.ran]
    fields["env_steps_per_trial"] = _nan_to_none(np.nanmean(steps, axis=0))
    fields["env_steps_per_experiment"] = [int(v) for v in last]
    if env_step_seconds is not None:
        fields["simulated_minutes_per_experiment"] = (last * env_step_seconds / 60.0).tolist()
        fields["trial_seconds_mean"] = float(np.sum(last) * env_step_seconds / np.sum(runs.ran))
    if greedy_trials is not None:
        at = np.asarray(greedy_trials, dtype=int) - 1
        fields["greedy_eval_env_steps"] = _nan_to_none(np.nanmean(steps[:, at], axis=0))
    return fields


def _iqm(scores: np.ndarray, reason: str | None) -> tuple[float | None, list[float | None]]:
    """The interquartile mean of ``scores`` and its bootstrap interval (withheld: no interval)."""
    from rmac_mj.evaluation import statistics

    estimate = (
        statistics.iqm_interval(scores)
        if reason is None
        else statistics.Estimate(float(statistics.iqm(scores)), np.nan, np.nan)
    ).as_dict()
    return estimate["value"], estimate["ci95"]


def _greedy_fields(
    greedy: np.ndarray,
    greedy_trials: Sequence[int],
    optimal_return: float | None,
    reason: str | None,
) -> dict[str, Any]:
    """The fields of the greedy evaluations (experiments, evaluations) after ``greedy_trials``."""
    greedy = np.asarray(greedy, dtype=float)
    if np.all(np.isfinite(greedy)):
        per_eval, lasts = greedy.mean(axis=0), greedy[:, -1]
    else:  # experiments that ran fewer trials: over those that ran each; their own last
        per_eval = np.array(
            [np.mean(c[np.isfinite(c)]) if np.isfinite(c).any() else np.nan for c in greedy.T]
        )
        lasts = np.array([row[np.isfinite(row)][-1] for row in greedy if np.isfinite(row).any()])
    last_mean, last_low, last_high = interval(lasts)
    if reason is not None:
        last_low = last_high = None
    fields = {
        "greedy_eval_trials": [int(t) for t in greedy_trials],
        "greedy_return_per_eval": _nan_to_none(per_eval),
        "greedy_return_last_mean": last_mean,
        "greedy_return_last_ci95": [last_low, last_high],
    }
    if optimal_return is not None:  # how soon the mean greedy policy is near-optimal
        for fraction in GREEDY_WITHIN:
            fields[f"greedy_trial_within_{round(100 * fraction)}pct"] = first_reaching(
                per_eval, greedy_trials, within_optimal(optimal_return, fraction)
            )
    return fields


def _time_fields(
    wall_times: np.ndarray | None,
    cpu_times: np.ndarray | None,
    measured: np.ndarray | None,
    runs: _Runs,
    trial_seconds: float,
) -> dict[str, Any]:
    """The fields of the experiments' wall and CPU times (none where not known)."""
    fields: dict[str, Any] = {}
    if wall_times is not None:
        fields["experiment_wall_s_mean"] = float(np.mean(wall_times))
        fields["experiment_wall_s_total"] = float(np.sum(wall_times))
    if cpu_times is not None and np.all(np.isfinite(cpu_times)):
        fields["experiment_cpu_s_mean"] = float(np.mean(cpu_times))
        # CPU of an experiment (its greedy trials and snapshots included) per minute it learned
        learned = (
            runs.trials * trial_seconds / 60.0
            if measured is None
            else float(np.mean(measured[np.arange(runs.experiments), runs.ran - 1]))
        )
        fields["cpu_s_per_simulated_minute"] = float(np.mean(cpu_times) / learned)
    return fields


def summarise(
    returns: np.ndarray,
    greedy: np.ndarray | None = None,
    greedy_trials: Sequence[int] = (),
    optimal_return: float | None = None,
    *,
    trial_seconds: float,
    wall_times: np.ndarray | None = None,
    cpu_times: np.ndarray | None = None,
    env_steps: np.ndarray | None = None,
    env_step_seconds: float | None = None,
) -> LearnerSummary:
    """The summary of one learner (:class:`LearnerSummary`): ``returns`` (experiments, trials).

    ``greedy`` (experiments, evaluations): the greedy-trial returns after the trials listed in
    ``greedy_trials``; ``trial_seconds``: the task's trial length (simulated s), which turns trials
    into minutes; ``optimal_return``: the reference stuck experiments are counted against
    (:func:`stuck_threshold`); ``wall_times``, ``cpu_times`` (experiments,): each experiment's (s).
    ``env_steps`` (experiments, trials): the environment steps by the end of each trial, and
    ``env_step_seconds`` the seconds of one: with them the times come from the steps that really
    ran, not from a trial's limit. ``returns`` may end early per experiment (NaN after; a budget in
    steps): per-trial means are over the experiments that ran the trial, final levels over each
    experiment's own last trials. Beside the paper's mean and Student-t interval, the final and
    first minutes' returns have the interquartile mean with its stratified-bootstrap interval
    (Agarwal et al. 2021). With fewer than :data:`FEW_EXPERIMENTS` experiments every interval is
    None and ``intervals_withheld`` says why; a window longer than the run is None.
    """
    returns = np.asarray(returns, dtype=float)
    runs = _Runs.of(returns)
    measured = _measured_minutes(env_steps, env_step_seconds, returns, trial_seconds)
    mean, low, high, finals = _curve_and_finals(returns, runs)
    first, first_minutes = _first_minutes(returns, runs, mean, finals, measured, trial_seconds)
    reason = withheld(runs.experiments)
    short = shorter_than(FIRST_MINUTES, runs.trials, trial_seconds)
    evaluated = greedy is not None and len(greedy_trials) > 0
    return LearnerSummary(
        experiments=runs.experiments,
        trials=runs.trials,
        final_window=runs.window,
        mean_return_per_trial=mean.tolist(),
        ci95_low_per_trial=_nan_to_none(low),
        ci95_high_per_trial=_nan_to_none(high),
        final_return_per_experiment=finals.tolist(),
        intervals_withheld=reason,
        **_levels(finals, None if short else first, reason, optimal_return),
        **first_minutes,
        **_step_counts(
            env_steps, env_step_seconds, returns, runs, greedy_trials if evaluated else None
        ),
        **(_greedy_fields(greedy, greedy_trials, optimal_return, reason) if evaluated else {}),
        **_time_fields(wall_times, cpu_times, measured, runs, trial_seconds),
    )


def _levels(
    finals: np.ndarray,
    first: np.ndarray | None,
    reason: str | None,
    optimal_return: float | None,
) -> dict[str, Any]:
    """The fields of the final levels and the first minutes' returns (``first``: None for a run
    shorter than the window): means, intervals (withheld for ``reason``), IQMs, stuck experiments
    and the gap to the near-optimal return."""
    final_mean, final_low, final_high = interval(finals)
    first_mean, first_low, first_high = (None, None, None) if first is None else interval(first)
    if reason is not None:
        final_low = final_high = first_low = first_high = None
    final_iqm = _iqm(finals, reason)
    first_iqm = (None, [None, None]) if first_mean is None else _iqm(first, reason)
    stuck_below = stuck_threshold(optimal_return)
    return {
        "final_return_mean": final_mean,
        "final_return_ci95": [final_low, final_high],
        "mean_return_first_5min": first_mean,
        "first_5min_ci95": [first_low, first_high],
        "stuck_below": stuck_below,
        "stuck_experiments": None if stuck_below is None else int(np.sum(finals < stuck_below)),
        "final_return_iqm": final_iqm[0],
        "final_return_iqm_ci95": final_iqm[1],
        "first_5min_iqm": first_iqm[0],
        "first_5min_iqm_ci95": first_iqm[1],
        "gap_to_optimal": (None if optimal_return is None else float(optimal_return - final_mean)),
    }


def improvement(finals: dict[str, Sequence[float]]) -> dict[str, dict[str, Any]]:
    """The probability of improvement of every pair of learners' final returns
    (``statistics.pairwise_improvement``), keyed ``"A > B"``; a pair with fewer than
    :data:`FEW_EXPERIMENTS` experiments of either learner gets value and ci95 None and ``withheld``
    saying why (from 2 experiments each it would read 1.00 [1.00, 1.00])."""
    from rmac_mj.evaluation import statistics

    names, table = list(finals), {}
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            counts = [len(finals[a]), len(finals[b])]
            reason = withheld(*counts)
            if reason is None:
                table.update(statistics.pairwise_improvement({a: finals[a], b: finals[b]}))
            else:
                table[f"{a} > {b}"] = {
                    "value": None,
                    "ci95": [None, None],
                    "experiments": counts,
                    "withheld": reason,
                }
    return table


def compare_final_returns(
    finals: dict[str, Sequence[float]], level: float = SIGNIFICANCE_LEVEL
) -> list[dict[str, Any]]:
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
        for b in names[i + 1 :]:
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
            tests.append(
                {
                    "test": "Welch t-test, two-sided",
                    "learners": [a, b],
                    "experiments": [len(x), len(y)],
                    "difference": difference,
                    "p_value": p_value,
                    "better": better,
                    "level": level,
                }
            )
    return tests

"""What people read at the end of a run: the summary table, the tests between learners, the notes.

The numbers come from :mod:`rmac_mj.evaluation.metrics` (through ``summary.json``); this module
words them, the same way for ``reproduce``, ``compare`` and ``sweep``.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from rmac_mj.agents import ALGORITHMS
from rmac_mj.evaluation import metrics
from rmac_mj.evaluation.metrics import LearnerSummary


def describe_test(test: dict[str, Any]) -> str:
    """One line for a result of :func:`compare_final_returns`."""
    a, b = test["learners"]
    if test["p_value"] is None:
        return (
            f"final returns, {a} vs {b}: no test possible ({test['experiments'][0]} and "
            f"{test['experiments'][1]} experiments; Welch's t-test needs 2 or more, with spread)"
        )
    p = test["p_value"]
    p_text = f"p = {p:.2g}" if p >= 1e-4 else "p < 0.0001"
    if test["better"] is None:
        return (
            f"final returns, {a} vs {b}: difference {test['difference']:+.1f}, not significant "
            f"({p_text}, Welch's t-test; a difference this size needs more experiments to rank them)"
        )
    worse = b if test["better"] == a else a
    return (
        f"final returns: {test['better']} better than {worse} by {abs(test['difference']):.1f}, "
        f"{p_text} (Welch's t-test, significant at {test['level']:g})"
    )


def _estimate(value: float | None, ci95: list | None, digits: int = 0) -> str:
    """``v [low, high]``, or n/a (a summary written before the estimate existed)."""
    if value is None:
        return "n/a"
    if not ci95 or ci95[0] is None:
        return f"{value:.{digits}f}"
    return f"{value:.{digits}f} [{ci95[0]:.{digits}f}, {ci95[1]:.{digits}f}]"


def describe_improvement(pair: str, estimate: dict[str, Any]) -> str:
    """One line for the probability of improvement of ``pair`` ("a > b"): ``{"value", "ci95",
    "experiments"}``. With fewer than ``FEW_EXPERIMENTS`` experiments of either learner it is
    withheld, saying why (a summary written before it was withheld holds a number: it is not
    shown); a learner is called better only when the interval excludes 0.5."""
    a, b = pair.split(" > ", 1)
    reason = estimate.get("withheld") or metrics.withheld(*estimate.get("experiments", [0]))
    if reason is not None:
        return f"final returns: P({pair}), the probability of improvement, withheld: {reason}"
    low, high = estimate["ci95"]
    verdict = ""
    if low is not None and (low > 0.5 or high < 0.5):
        verdict = f": {a if low > 0.5 else b} better"
    return (
        f"final returns: P({pair}) = {_estimate(estimate['value'], estimate['ci95'], 2)}, "
        f"probability of improvement{verdict}"
    )


def across_runs(summaries: dict[str, dict[str, Any]]) -> list[str]:
    """The probability of improvement of the final returns between every pair of (run, learner)
    of several runs (``rmac-mj compare``), one line each: a comparison across runs, not only within
    one."""
    finals = {
        f"{label}: {algorithm}": summary[algorithm]["final_return_per_experiment"]
        for label, summary in summaries.items()
        for algorithm in ALGORITHMS
        if algorithm in summary and "final_return_per_experiment" in summary[algorithm]
    }
    return [
        describe_improvement(pair, estimate)
        for pair, estimate in metrics.improvement(finals).items()
    ]


def few_experiments_note(experiments: int) -> str:
    """The warning printed and drawn when ``experiments`` < :data:`FEW_EXPERIMENTS`."""
    return (
        f"note: {experiments} experiment{'s' if experiments != 1 else ''} per learner: too few to rank "
        f"the learners; the 95% intervals and probabilities are withheld (n/a) and the t-test "
        f"assumes normally distributed returns, which fewer than {metrics.FEW_EXPERIMENTS} "
        "experiments cannot show"
    )


def _span(values: Iterable[int]) -> str:
    """``"25"``, or ``"24 to 26"`` when the values differ."""
    values = sorted(set(values))
    return str(values[0]) if len(values) == 1 else f"{values[0]} to {values[-1]}"


def _trials_ran(row: LearnerSummary) -> list[int]:
    """The trials each experiment of a learner ran (``trials`` for all, in a summary without
    ``trials_per_experiment``)."""
    return row.trials_per_experiment or [row.trials] * row.experiments


def what_ran(summary: dict[str, Any], algorithms: Iterable[str]) -> str:
    """The trials and environment steps each learner's experiments ran: ``"s-ac 25 trials, 20040
    steps; sb3-sac 24 to 26 trials, 20010 to 20070 steps"`` (steps where the curves recorded them)."""
    ran = []
    for algorithm in algorithms:
        row = LearnerSummary.from_dict(summary[algorithm])
        text = f"{algorithm} {_span(_trials_ran(row))} trials"
        if row.env_steps_per_experiment:
            text += f", {_span(row.env_steps_per_experiment)} steps"
        ran.append(text)
    return "; ".join(ran)


def budget_line(summary: dict[str, Any], algorithms: Iterable[str]) -> str | None:
    """What each experiment ran, for a run budgeted in environment steps: ``"each experiment:
    20000 env steps asked (at most 600 trials); ran: s-ac 25 trials, 20040 steps"``; None for a
    run budgeted in trials (each ran them all)."""
    protocol = summary.get("protocol") or {}
    if protocol.get("steps") is None:
        return None
    return (
        f"each experiment: {protocol['steps']} env steps asked (at most "
        f"{protocol.get('trials', '?')} trials); ran: {what_ran(summary, algorithms)}"
    )


def window_lines(rows: dict[str, LearnerSummary]) -> list[str]:
    """What the final and greedy columns average over: the final window in trials (stated for a
    run shorter than :data:`~rmac_mj.evaluation.metrics.FINAL_WINDOW`, and when the experiments
    ran different numbers of trials) and the trial of the last greedy evaluation."""
    lines = []
    windows = {
        metrics.FINAL_WINDOW if row.final_window is None else row.final_window
        for row in rows.values()
    }
    ran = [n for row in rows.values() for n in _trials_ran(row)]
    if windows:
        window = _span(windows)
        text = f"final return: each experiment's mean over its last {window} trials"
        if min(ran) <= max(windows):
            text += (
                f", all it ran (the window is {metrics.FINAL_WINDOW} trials; this run is shorter)"
                if max(ran) <= max(windows)
                else f" (the experiments ran {_span(ran)} trials)"
            )
        elif len(set(ran)) > 1:
            text += f" (the experiments ran {_span(ran)} trials)"
        lines.append(text + "; then the mean over the experiments, and their IQM")
    evaluated = [row for row in rows.values() if row.greedy_eval_trials]
    if evaluated:
        last = {row.greedy_eval_trials[-1] for row in evaluated}
        uniform = all(len(set(_trials_ran(row))) == 1 for row in evaluated)
        after = f"trial {_span(last)}" if uniform else "each experiment's last evaluated trial"
        lines.append(
            f"greedy at end: the greedy evaluation (no exploration, no learning) after {after}; "
            "the mean over the experiments"
        )
    return lines


def timing_line(rows: dict[str, LearnerSummary], shorter: bool) -> str:
    """What the time columns average over, and the level below which an experiment is stuck;
    ``shorter``: the first 10 minutes are n/a for a run shorter than them."""
    parts = [
        "min to 90%: simulated minutes until the mean curve is within 10% of its final level",
        f"first 10 min: n/a, the run is shorter than {metrics.EARLY_MINUTES:g} simulated minutes"
        if shorter
        else f"first 10 min: the mean return of the trials within the first "
        f"{metrics.EARLY_MINUTES:g} simulated minutes",
    ]
    below = [row.stuck_below for row in rows.values() if row.stuck_below]
    if below:
        parts.append(f"stuck: experiments whose final return is below {below[0]:.0f}")
    return "; ".join(parts)


def _header(greedy: bool, ci: str) -> str:
    """The table's column titles; ``ci`` the interval's title, or empty when every row withholds
    it; ``greedy`` with the column of the last greedy evaluation."""
    return (
        f"{'learner':>8} {'experiments':>11} {'final return':>13} {'95% CI':>19} "
        f"{'IQM' + ci:>25} "
        + (f"{'greedy at end' + ci:>25} " if greedy else "")
        + f"{'min to 90%':>10} {'first 10 min':>12} {'stuck':>5}"
    )


def _first_10min(row: LearnerSummary, trial_seconds: float | None) -> float | None:
    """The row's first 10 minutes' return, None for a run shorter than them."""
    early = row.mean_return_first_10min
    if (
        early is not None
        and trial_seconds
        and row.trials
        and metrics.shorter_than(metrics.EARLY_MINUTES, row.trials, trial_seconds)
    ):
        return None  # written before the window was left empty for a shorter run
    return early


def _table_row(algorithm: str, row: LearnerSummary, greedy: bool, early: float | None) -> str:
    """One learner's line of the table (``greedy``: with the greedy column)."""
    # a summary written before intervals were withheld holds them: they are not shown
    few = metrics.withheld(row.experiments) is not None
    low, high = row.final_return_ci95
    ci = f"[{low:.0f}, {high:.0f}]" if low is not None and not few else "n/a"
    stuck = "n/a" if row.stuck_experiments is None else str(row.stuck_experiments)
    iqm = _estimate(row.final_return_iqm, None if few else row.final_return_iqm_ci95)
    at_end = ""
    if greedy:
        at_end = (
            _estimate(row.greedy_return_last_mean, None if few else row.greedy_return_last_ci95)
            if row.greedy_eval_trials
            else "n/a"
        )
        at_end = f"{at_end:>25} "
    return (
        f"{algorithm:>8} {row.experiments:>11d} {row.final_return_mean:>13.1f} "
        f"{ci:>19} {iqm:>25} {at_end}{row.minutes_to_90pct:>10.1f} "
        f"{'n/a' if early is None else f'{early:.1f}':>12} {stuck:>5}"
    )


def _trial_length_line(seconds: float, rows: dict[str, LearnerSummary]) -> str:
    """How long a trial is, and how long it was as run where that differs."""
    measured = {
        a: row.trial_seconds_mean for a, row in rows.items() if row.trial_seconds_mean is not None
    }
    if measured and any(abs(v - seconds) > 1e-9 * seconds for v in measured.values()):
        return (
            f"one trial = at most {seconds:g} s of simulated time; "
            "as run, on average: " + ", ".join(f"{a} {v:.3g} s" for a, v in measured.items())
        )
    return f"one trial = {seconds:g} s of simulated time"


def _comparison_lines(summary: dict[str, Any], rows: dict[str, LearnerSummary]) -> list[str]:
    """The tests between the learners' final returns, their probabilities of improvement, and the
    note on too few experiments."""
    tests = metrics.compare_final_returns(
        {a: row.final_return_per_experiment for a, row in rows.items()}
    )
    lines = [describe_test(test) for test in tests]
    improvement = summary.get("probability_of_improvement", {})
    lines.extend(
        describe_improvement(pair, estimate)
        for pair, estimate in improvement.items()
        if all(name in rows for name in pair.split(" > "))
    )
    fewest = min((row.experiments for row in rows.values()), default=None)
    if fewest is not None and fewest < metrics.FEW_EXPERIMENTS:
        lines.append(few_experiments_note(fewest))
    return lines


def summary_table(summary: dict[str, Any], algorithms: Iterable[str] | None = None) -> str:
    """The end-of-run table of a run's summary (``summary.json``): one row per learner (with the
    greedy return at the last evaluation when the run evaluated), what its columns average over,
    then whether the final returns differ significantly, and a warning when too few experiments
    make the intervals meaningless."""
    rows = {
        a: LearnerSummary.from_dict(summary[a]) for a in (algorithms or ALGORITHMS) if a in summary
    }
    greedy = any(row.greedy_eval_trials for row in rows.values())
    # a column claims an interval only where some row shows one (too few experiments: none)
    shown = any(metrics.withheld(row.experiments) is None for row in rows.values())
    header = _header(greedy, " [95% CI]" if shown else "")
    lines = [header, "-" * len(header)]
    early = {a: _first_10min(row, summary.get("trial_seconds")) for a, row in rows.items()}
    lines.extend(_table_row(a, row, greedy, early[a]) for a, row in rows.items())
    budget = budget_line(summary, list(rows))
    if budget is not None:
        lines.append(budget)
    lines.extend(window_lines(rows))
    lines.append(timing_line(rows, any(value is None for value in early.values())))
    if summary.get("optimal_return") is not None:
        lines.append(f"near-optimal return: {summary['optimal_return']:.1f}")
    if summary.get("trial_seconds") is not None:
        lines.append(_trial_length_line(summary["trial_seconds"], rows))
    lines.extend(_comparison_lines(summary, rows))
    return "\n".join(lines)

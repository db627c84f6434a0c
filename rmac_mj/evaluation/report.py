"""What people read at the end of a run: the summary table, the tests between learners, the notes.

The numbers come from :mod:`rmac_mj.evaluation.metrics` (through ``summary.json``); this module
words them, the same way for ``reproduce``, ``compare`` and ``sweep``.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from rmac_mj.agents import ALGORITHMS
from rmac_mj.evaluation import metrics


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


def _trials_ran(row: dict[str, Any]) -> list[int]:
    """The trials each experiment of a learner ran (``trials`` for all, in a summary without
    ``trials_per_experiment``)."""
    return row.get("trials_per_experiment") or [row["trials"]] * row["experiments"]


def what_ran(summary: dict[str, Any], algorithms: Iterable[str]) -> str:
    """The trials and environment steps each learner's experiments ran: ``"s-ac 25 trials, 20040
    steps; sb3-sac 24 to 26 trials, 20010 to 20070 steps"`` (steps where the curves recorded them)."""
    ran = []
    for algorithm in algorithms:
        row = summary[algorithm]
        text = f"{algorithm} {_span(_trials_ran(row))} trials"
        if row.get("env_steps_per_experiment"):
            text += f", {_span(row['env_steps_per_experiment'])} steps"
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


def window_lines(summary: dict[str, Any], algorithms: Iterable[str]) -> list[str]:
    """What the final and greedy columns average over: the final window in trials (stated for a
    run shorter than :data:`~rmac_mj.evaluation.metrics.FINAL_WINDOW`, and when the experiments
    ran different numbers of trials) and the trial of the last greedy evaluation."""
    algorithms = list(algorithms)
    lines = []
    windows = {summary[a].get("final_window", metrics.FINAL_WINDOW) for a in algorithms}
    ran = [n for a in algorithms for n in _trials_ran(summary[a])]
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
    evaluated = [a for a in algorithms if summary[a].get("greedy_eval_trials")]
    if evaluated:
        last = {summary[a]["greedy_eval_trials"][-1] for a in evaluated}
        uniform = all(len(set(_trials_ran(summary[a]))) == 1 for a in evaluated)
        after = f"trial {_span(last)}" if uniform else "each experiment's last evaluated trial"
        lines.append(
            f"greedy at end: the greedy evaluation (no exploration, no learning) after {after}; "
            "the mean over the experiments"
        )
    return lines


def timing_line(summary: dict[str, Any], algorithms: Iterable[str], shorter: bool) -> str:
    """What the time columns average over, and the level below which an experiment is stuck;
    ``shorter``: the first 10 minutes are n/a for a run shorter than them."""
    parts = [
        "min to 90%: simulated minutes until the mean curve is within 10% of its final level",
        f"first 10 min: n/a, the run is shorter than {metrics.EARLY_MINUTES:g} simulated minutes"
        if shorter
        else f"first 10 min: the mean return of the trials within the first "
        f"{metrics.EARLY_MINUTES:g} simulated minutes",
    ]
    below = [summary[a]["stuck_below"] for a in algorithms if summary[a].get("stuck_below")]
    if below:
        parts.append(f"stuck: experiments whose final return is below {below[0]:.0f}")
    return "; ".join(parts)


def summary_table(summary: dict[str, Any], algorithms: Iterable[str] | None = None) -> str:
    """The end-of-run table: one row per learner (with the greedy return at the last evaluation
    when the run evaluated), what its columns average over, then whether the final returns differ
    significantly, and a warning when too few experiments make the intervals meaningless."""
    algorithms = [a for a in (algorithms or ALGORITHMS) if a in summary]
    greedy = any(summary[a].get("greedy_eval_trials") for a in algorithms)
    # a column claims an interval only where some row shows one (too few experiments: none)
    ci = (
        " [95% CI]"
        if any(metrics.withheld(summary[a]["experiments"]) is None for a in algorithms)
        else ""
    )
    header = (
        f"{'learner':>8} {'experiments':>11} {'final return':>13} {'95% CI':>19} "
        f"{'IQM' + ci:>25} "
        + (f"{'greedy at end' + ci:>25} " if greedy else "")
        + f"{'min to 90%':>10} {'first 10 min':>12} {'stuck':>5}"
    )
    lines = [header, "-" * len(header)]
    shorter = False
    for algorithm in algorithms:
        row = summary[algorithm]
        # a summary written before intervals were withheld holds them: they are not shown
        few = metrics.withheld(row["experiments"]) is not None
        low, high = row["final_return_ci95"]
        ci = f"[{low:.0f}, {high:.0f}]" if low is not None and not few else "n/a"
        stuck = "n/a" if row.get("stuck_experiments") is None else str(row["stuck_experiments"])
        iqm = _estimate(
            row.get("final_return_iqm"), None if few else row.get("final_return_iqm_ci95")
        )
        at_end = ""
        if greedy:
            at_end = (
                _estimate(
                    row.get("greedy_return_last_mean"),
                    None if few else row.get("greedy_return_last_ci95"),
                )
                if row.get("greedy_eval_trials")
                else "n/a"
            )
            at_end = f"{at_end:>25} "
        early = row.get("mean_return_first_10min")
        if (
            early is not None
            and summary.get("trial_seconds")
            and row.get("trials")
            and metrics.shorter_than(metrics.EARLY_MINUTES, row["trials"], summary["trial_seconds"])
        ):
            early = None  # written before the window was left empty for a shorter run
        shorter = shorter or early is None
        lines.append(
            f"{algorithm:>8} {row['experiments']:>11d} {row['final_return_mean']:>13.1f} "
            f"{ci:>19} {iqm:>25} {at_end}{row['minutes_to_90pct']:>10.1f} "
            f"{'n/a' if early is None else f'{early:.1f}':>12} {stuck:>5}"
        )
    budget = budget_line(summary, algorithms)
    if budget is not None:
        lines.append(budget)
    lines.extend(window_lines(summary, algorithms))
    lines.append(timing_line(summary, algorithms, shorter))
    if summary.get("optimal_return") is not None:
        lines.append(f"near-optimal return: {summary['optimal_return']:.1f}")
    if summary.get("trial_seconds") is not None:
        measured = {
            a: summary[a].get("trial_seconds_mean")
            for a in algorithms
            if summary[a].get("trial_seconds_mean") is not None
        }
        if measured and any(
            abs(v - summary["trial_seconds"]) > 1e-9 * summary["trial_seconds"]
            for v in measured.values()
        ):
            lines.append(
                f"one trial = at most {summary['trial_seconds']:g} s of simulated time; "
                "as run, on average: " + ", ".join(f"{a} {v:.3g} s" for a, v in measured.items())
            )
        else:
            lines.append(f"one trial = {summary['trial_seconds']:g} s of simulated time")
    tests = metrics.compare_final_returns(
        {
            a: summary[a]["final_return_per_experiment"]
            for a in algorithms
            if "final_return_per_experiment" in summary[a]
        }
    )
    lines.extend(describe_test(test) for test in tests)
    improvement = summary.get("probability_of_improvement", {})
    lines.extend(
        describe_improvement(pair, estimate)
        for pair, estimate in improvement.items()
        if all(name in algorithms for name in pair.split(" > "))
    )
    fewest = min((summary[a]["experiments"] for a in algorithms), default=None)
    if fewest is not None and fewest < metrics.FEW_EXPERIMENTS:
        lines.append(few_experiments_note(fewest))
    return "\n".join(lines)

"""Judge result directories against the goal of issue 14 (docs/studies/rmac-best.md).

Usage: python scripts/studies/goal_report.py DIR[:LEARNER[:LABEL]] ... [--paired] [--plot FILE.png]

Each DIR is an `rmac-mj reproduce --out` directory run with `--evaluate-every`; LEARNER picks one of
its learners (default: every learner in it). Prints one markdown row per (directory, learner) with
the five goal metrics, their 95% confidence intervals and whether each goal is met, then the
difference of every row from the first: Welch's t-test, or with ``--paired`` (runs with the same
seeds, e.g. the configurations of one sweep) experiment i against experiment i, mean +- 95%
half-width and a paired t-test. "greedy, last 5" is the mean of the last five greedy trials, a
steadier measure of the final policy than the last greedy trial alone.

The goal (issue 14): greedy return after the last trial >= -775; exploring return, mean of the last
50 trials, >= -905; mean return of the first 5 simulated minutes >= -1800; the mean curve within 10%
of its final level in <= 5 simulated minutes; no experiment stuck (last 50 trials below -1500).
"""

import json
import pathlib
import sys

import numpy as np
from scipy import stats

from rmac_mj.evaluation import (
    FIRST_MINUTES,
    confidence_interval,
    early_returns,
    final_returns,
    minutes_to_within,
)
from rmac_mj.results import ResultStore

GOAL = {"greedy": -775.0, "exploring": -905.0, "first_5min": -1800.0, "minutes_to_90pct": 5.0}
STUCK_BELOW = -1500.0


def load(directory: pathlib.Path, learner: str):
    """Per-experiment learning curves and greedy returns, and the trial length in seconds."""
    store = ResultStore(directory)
    if not store.finished(learner):
        raise SystemExit(f"goal_report: no curves of {learner!r} in {directory}")
    curves = store.load_curves(learner)
    if curves.greedy_returns.shape[1] == 0:
        raise SystemExit(
            f"goal_report: {directory} has no greedy trials (run with --evaluate-every)"
        )
    return curves.returns, curves.greedy_returns, store.read_summary()["trial_seconds"]


def metrics(returns: np.ndarray, greedy: np.ndarray, seconds: float) -> dict:
    finals = final_returns(returns)
    return {
        "greedy": greedy[:, -1],
        "greedy_last5": greedy[:, -5:].mean(axis=1),
        "exploring": finals,
        "first_5min": early_returns(returns, FIRST_MINUTES, seconds),
        "minutes_to_90pct": minutes_to_within(returns.mean(axis=0), trial_seconds=seconds),
        "stuck": int(np.sum(finals < STUCK_BELOW)),
        "n": len(returns),
    }


def paired_difference(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float]:
    """a - b experiment by experiment (same seeds): (mean, 95% half-width, paired t-test p)."""
    mean, low, _ = confidence_interval(a - b)
    return float(mean), float(mean - low), float(stats.ttest_rel(a, b).pvalue)


def cell(samples: np.ndarray, goal: float) -> str:
    mean, low, high = confidence_interval(samples)
    return f"{mean:.0f} [{low:.0f}, {high:.0f}] {'yes' if mean >= goal else 'no'}"


def parse(argument: str) -> list[tuple[pathlib.Path, str, str]]:
    directory, _, rest = argument.partition(":")
    learner, _, label = rest.partition(":")
    path = pathlib.Path(directory)
    learners = (
        [learner]
        if learner
        else json.loads((path / "summary.json").read_text())["protocol"]["algorithms"]
    )
    return [(path, a, label or f"{path.name} {a}") for a in learners]


def plot(
    rows: list[tuple[str, np.ndarray, np.ndarray, float]], path: str, bands: bool = True
) -> None:
    """Exploring learning curves (10-trial running mean) and greedy returns, mean and (``bands``)
    95% CI, for rows (label, returns, greedy returns, trial seconds)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, gx) = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for label, returns, greedy, seconds in rows:
        mean, low, high = confidence_interval(returns)
        window = np.ones(10) / 10
        smooth = [np.convolve(c, window, mode="valid") for c in (mean, low, high)]
        minutes = (np.arange(len(smooth[0])) + 10) * seconds / 60
        (line,) = ax.plot(minutes, smooth[0], label=label, lw=1.2)
        if bands:
            ax.fill_between(minutes, smooth[1], smooth[2], color=line.get_color(), alpha=0.2)
        every = returns.shape[1] // greedy.shape[1]
        gm, glo, ghi = confidence_interval(greedy)
        gminutes = np.arange(1, greedy.shape[1] + 1) * every * seconds / 60
        gx.plot(gminutes, gm, color=line.get_color(), lw=1.2, label=label)
        if bands:
            gx.fill_between(gminutes, glo, ghi, color=line.get_color(), alpha=0.2)
    for axis, title, goal in (
        (ax, "exploring trials (10-trial mean)", GOAL["exploring"]),
        (gx, "greedy trials", GOAL["greedy"]),
    ):
        axis.axhline(-748, color="k", lw=0.8, ls="--", label="near-optimal (-748)")
        axis.axhline(goal, color="tab:red", lw=0.8, ls=":", label=f"goal ({goal:.0f})")
        axis.set(xlabel="simulated minutes", title=title, ylim=(-3000, -650))
        axis.grid(alpha=0.3)
    ax.set_ylabel("return per trial, mean and 95% CI over experiments")
    gx.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main(arguments: list[str]) -> None:
    out = None
    paired = "--paired" in arguments
    arguments = [a for a in arguments if a != "--paired"]
    if "--plot" in arguments:
        at = arguments.index("--plot")
        out = arguments[at + 1]
        del arguments[at : at + 2]
    entries = [entry for argument in arguments for entry in parse(argument)]
    print(
        "| run | exp. | greedy at the end (goal -775) | exploring, last 50 (goal -905) "
        "| first 5 min (goal -1800) | min to 90% (goal 5) | stuck (goal 0) |"
    )
    print("|---|---|---|---|---|---|---|")
    table, curves = [], []
    for directory, learner, label in entries:
        returns, greedy, seconds = load(directory, learner)
        m = metrics(returns, greedy, seconds)
        table.append((label, m))
        curves.append((label, returns, greedy, seconds))
        minutes = m["minutes_to_90pct"]
        print(
            f"| {label} | {m['n']} | {cell(m['greedy'], GOAL['greedy'])} | "
            f"{cell(m['exploring'], GOAL['exploring'])} | {cell(m['first_5min'], GOAL['first_5min'])} | "
            f"{minutes:.1f} {'yes' if minutes <= GOAL['minutes_to_90pct'] else 'no'} | "
            f"{m['stuck']}/{m['n']} {'yes' if m['stuck'] == 0 else 'no'} |"
        )
    base_label, base = table[0]
    for label, m in table[1:]:
        parts = []
        for key in ("greedy", "greedy_last5", "exploring", "first_5min"):
            if paired:
                if len(m[key]) != len(base[key]):
                    raise SystemExit(
                        f"goal_report: --paired needs as many experiments in {label} "
                        f"as in {base_label}"
                    )
                mean, half, p = paired_difference(m[key], base[key])
                parts.append(f"{key} {mean:+.0f} ± {half:.0f} (p = {p:.2g})")
            else:
                difference = m[key].mean() - base[key].mean()
                p = stats.ttest_ind(m[key], base[key], equal_var=False).pvalue
                parts.append(f"{key} {difference:+.0f} (p = {p:.2g})")
        print(f"- {label} vs {base_label} ({'paired' if paired else 'Welch'}): " + ", ".join(parts))
    if out:
        plot(curves, out)


if __name__ == "__main__":
    main(sys.argv[1:])

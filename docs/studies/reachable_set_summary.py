"""Summarise the reachable-set study (docs/studies/reachable-set.md) from its result directories.

Usage: python docs/studies/reachable_set_summary.py ROOT [RULE ...] [--plot FILE.png]
ROOT/RULE is the `rmac-mj reproduce --out` directory of one rule (any name: a directory).
Prints one markdown row per rule and Welch's t-test of every pair of rules' final returns.
"""

import pathlib
import sys

import numpy as np

from rmac_mj.experiments.results import (compare_final_returns, confidence_interval, describe_test,
                                         minutes_to_within)

TRIAL_SECONDS, STUCK_BELOW = 3.0, -1496.0


def load(directory: pathlib.Path):
    files = sorted((directory / "curves" / "rmac").glob("exp_*.npz"))
    data = [np.load(f) for f in files]
    return (np.array([d["returns"] for d in data]), np.array([d["greedy_returns"] for d in data]),
            np.array([float(d["wall_time_s"]) for d in data]))


def plot(root: str, rules: list[str], path: str) -> None:
    """Mean learning curve (10-trial moving average) and mean greedy return per rule."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax, gx) = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for rule in rules:
        returns, greedy, _ = load(pathlib.Path(root) / rule)
        curve = np.convolve(returns.mean(axis=0), np.ones(10) / 10, mode="valid")
        minutes = (np.arange(len(curve)) + 10) * TRIAL_SECONDS / 60
        ax.plot(minutes, curve, label=rule)
        gx.plot(np.arange(1, greedy.shape[1] + 1) * 20 * TRIAL_SECONDS / 60, greedy.mean(axis=0),
                marker=".", label=rule)
    for axis, title in ((ax, "exploring trials (10-trial mean)"), (gx, "greedy trial every 20")):
        axis.axhline(-748, color="k", lw=0.8, ls="--")
        axis.set(xlabel="simulated minutes", title=title, ylim=(-3000, -600))
        axis.grid(alpha=0.3)
    ax.set_ylabel("return per trial, mean of experiments")
    gx.legend(title="reachable_rule")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(root: str, rules: list[str]) -> None:
    finals = {}
    print("| rule | exp. | last 50, mean [95% CI] | greedy at 600, mean [95% CI] | greedy, last 5 evaluations "
          "| min to 90% | first 5 min (trials 1-100) | stuck | wall s / exp. |")
    print("|---|---|---|---|---|---|---|---|---|")
    for rule in rules:
        returns, greedy, wall = load(pathlib.Path(root) / rule)
        final = returns[:, -50:].mean(axis=1)
        finals[rule] = final
        m, lo, hi = confidence_interval(final)
        gm, glo, ghi = confidence_interval(greedy[:, -1])
        minutes = minutes_to_within(returns.mean(axis=0), trial_seconds=TRIAL_SECONDS)
        print(f"| {rule} | {len(returns)} | {m:.0f} [{lo:.0f}, {hi:.0f}] | {gm:.0f} [{glo:.0f}, "
              f"{ghi:.0f}] | {greedy[:, -5:].mean():.0f} | {minutes:.1f} | {returns[:, :100].mean():.0f} | "
              f"{int(np.sum(final < STUCK_BELOW))}/{len(returns)} | {wall.mean():.0f} |")
    for test in compare_final_returns(finals):
        print("-", describe_test(test))

if __name__ == "__main__":
    args = sys.argv[2:]
    out = None
    if "--plot" in args:
        out = args[args.index("--plot") + 1]
        del args[args.index("--plot"):args.index("--plot") + 2]
    chosen = args or ["vertices", "vertices_value", "grid", "exact"]
    main(sys.argv[1], chosen)
    if out:
        plot(sys.argv[1], chosen, out)

"""Summarise the reachable-set study (docs/studies/reachable-set.md) from its result directories.

Usage: python scripts/studies/reachable_set_summary.py ROOT [RULE ...] [--plot FILE.png]
ROOT/RULE is the `rmac-mj reproduce --out` directory of one rule (any name: a directory).
Prints one markdown row per rule and Welch's t-test of every pair of rules' final returns.
"""

import pathlib

import numpy as np

from rmac_mj.evaluation import (
    compare_final_returns,
    confidence_interval,
    describe_test,
    final_returns,
    minutes_to_within,
)
from rmac_mj.results import ResultStore

TRIAL_SECONDS, STUCK_BELOW = 3.0, -1496.0


def load(directory: pathlib.Path):
    curves = ResultStore(directory).load_curves("rmac")
    return curves.returns, curves.greedy_returns, curves.wall_times


def plot(root: str, rules: list[str], path: str) -> None:
    """Mean learning curve (10-trial running mean) and mean greedy return per rule
    (goal_report's figure)."""
    from goal_report import plot as plot_curves

    plot_curves(
        [(rule, *load(pathlib.Path(root) / rule)[:2], TRIAL_SECONDS) for rule in rules],
        path,
        bands=False,
    )


def main(root: str, rules: list[str]) -> None:
    finals = {}
    print(
        "| rule | exp. | last 50, mean [95% CI] | greedy at 600, mean [95% CI] | greedy, last 5 evaluations "
        "| min to 90% | first 5 min (trials 1-100) | stuck | wall s / exp. |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for rule in rules:
        returns, greedy, wall = load(pathlib.Path(root) / rule)
        final = final_returns(returns)
        finals[rule] = final
        m, lo, hi = confidence_interval(final)
        gm, glo, ghi = confidence_interval(greedy[:, -1])
        minutes = minutes_to_within(returns.mean(axis=0), trial_seconds=TRIAL_SECONDS)
        print(
            f"| {rule} | {len(returns)} | {m:.0f} [{lo:.0f}, {hi:.0f}] | {gm:.0f} [{glo:.0f}, "
            f"{ghi:.0f}] | {greedy[:, -5:].mean():.0f} | {minutes:.1f} | {returns[:, :100].mean():.0f} | "
            f"{int(np.sum(final < STUCK_BELOW))}/{len(returns)} | {wall.mean():.0f} |"
        )
    for test in compare_final_returns(finals):
        print("-", describe_test(test))


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", help="the directory holding one reproduce directory per rule")
    parser.add_argument("rules", nargs="*", default=["vertices", "vertices_value", "grid", "exact"])
    parser.add_argument("--plot", metavar="FILE.png", help="also draw the curves")
    args = parser.parse_args()
    main(args.root, args.rules)
    if args.plot:
        plot(args.root, args.rules, args.plot)

"""Summarise the exploration-schedule study (docs/studies/exploration-schedule.md) from its sweep.

Usage: python scripts/studies/exploration_schedule_summary.py OUT [--plot FILE.png]
OUT is the `rmac-mj sweep docs/studies/exploration-schedule.toml --out OUT` directory. Prints the
results table (from OUT/sweep.csv) and the paired differences of every configuration from the
paper's (experiment i against experiment i: the same seeds), with two-sided t-tests.
"""

import csv
import pathlib

import goal_report
import numpy as np

PAPER = "paper"
TRIAL_SECONDS = 3.0


def load(out: pathlib.Path, name: str) -> dict[str, np.ndarray]:
    returns, greedy, _ = goal_report.load(out / name, "rmac")
    return {"returns": returns, "greedy": greedy}


def paired(d: np.ndarray) -> str:
    mean, half, p = goal_report.paired_difference(d, np.zeros_like(d))
    return f"{mean:+.0f} ± {half:.0f} (p {'< 0.001' if p < 0.001 else f'= {p:.3f}'})"


def main(out: pathlib.Path) -> None:
    rows = list(csv.DictReader(open(out / "sweep.csv")))
    f = lambda row, key: float(row[key]) if row[key] not in ("", "None") else None  # noqa: E731
    ci = lambda row, m, lo, hi: f"{f(row, m):.0f} [{f(row, lo):.0f}, {f(row, hi):.0f}]"  # noqa
    print(
        "| configuration | greedy | exploring | floor | exploring - floor | first 5 min "
        "| min to 90% |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for row in rows:
        floor = f(row, "exploration_floor")
        gap = "-" if floor is None else f"{f(row, 'final_return_mean') - floor:+.0f}"
        print(
            f"| {row['configuration']} | "
            f"{ci(row, 'greedy_return_mean', 'greedy_return_ci95_low', 'greedy_return_ci95_high')} | "
            f"{ci(row, 'final_return_mean', 'final_return_ci95_low', 'final_return_ci95_high')} | "
            f"{'-' if floor is None else f'{floor:.0f}'} | {gap} | "
            f"{ci(row, 'mean_return_first_5min', 'first_5min_ci95_low', 'first_5min_ci95_high')} | "
            f"{f(row, 'minutes_to_90pct'):.1f} |"
        )
    base = load(out, PAPER)
    print()
    print(
        "| configuration | greedy (mean of the last 5 greedy trials) | exploring (last 50) "
        "| first 5 min |"
    )
    print("| --- | --- | --- | --- |")
    for row in rows:
        name = row["configuration"]
        if name == PAPER:
            continue
        c = load(out, name)
        greedy = c["greedy"][:, -5:].mean(axis=1) - base["greedy"][:, -5:].mean(axis=1)
        exploring = c["returns"][:, -50:].mean(axis=1) - base["returns"][:, -50:].mean(axis=1)
        first = c["returns"][:, :100].mean(axis=1) - base["returns"][:, :100].mean(axis=1)
        print(f"| {name} | {paired(greedy)} | {paired(exploring)} | {paired(first)} |")


def plot(out: pathlib.Path, path: str) -> None:
    """Mean exploring curve (10-trial running mean) and mean greedy return per configuration
    (goal_report's figure)."""
    from goal_report import plot as plot_curves

    names = [row["configuration"] for row in csv.DictReader(open(out / "sweep.csv"))]
    plot_curves(
        [
            (name, c["returns"], c["greedy"], TRIAL_SECONDS)
            for name, c in ((name, load(out, name)) for name in names)
        ],
        path,
        bands=False,
    )


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=pathlib.Path, help="the sweep's --out directory")
    parser.add_argument("--plot", metavar="FILE.png", help="also draw the curves")
    args = parser.parse_args()
    main(args.out)
    if args.plot:
        plot(args.out, args.plot)

"""Summarise the memory-management study (docs/studies/memory-management.md) from sweep results.

Usage: python scripts/studies/memory_management_summary.py SWEEP_DIR [MEMORY_SIZE_DIR]

SWEEP_DIR is the `rmac-mj sweep docs/studies/memory-management.toml --out` directory. Prints one
markdown row per configuration (numbers from SWEEP_DIR/sweep.csv) with the paired difference from
its baseline in the mean of the last 5 greedy trials and in the exploring return (mean of the last
50 trials), experiment by experiment (same seeds), ± 95% half-width and the p-value of a paired
t-test. The baseline is the paper's configuration ('nearest'); the two variants with other memory
sizes are also paired with 'nearest' at the same sizes from MEMORY_SIZE_DIR (the output of
docs/studies/memory-size.toml, same seeds and, for 'nearest', the same code path).
"""

import csv
import pathlib
import sys

import goal_report
import numpy as np

SAME_SIZE = {
    "redundancy-process-50": "critic-reference-2000__process_capacity=50",
    "redundancy-critic-reference-4000": "critic-reference-4000__process_capacity=100",
}


def paired(a: np.ndarray, b: np.ndarray) -> str:
    mean, half, p = goal_report.paired_difference(a, b)
    return (
        f"{mean:+.0f} ± {half:.0f} (p {p:.3f})"
        if p >= 0.001
        else f"{mean:+.0f} ± {half:.0f} (p {p:.1e})"
    )


def metrics(directory: pathlib.Path):
    m = goal_report.metrics(*goal_report.load(directory, "rmac"))
    return m["greedy_last5"], m["exploring"]


def main(root: str, sizes: str | None) -> None:
    root_p = pathlib.Path(root)
    rows = list(csv.DictReader(open(root_p / "sweep.csv")))
    base_g, base_f = metrics(root_p / "nearest")
    print(
        "| configuration | exploring (last 50) | greedy (trial 600) | paired greedy | paired exploring "
        "| first 5 min | min to 90% | stuck | paired greedy, same sizes |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for row in rows:
        name = row["configuration"]
        g, f = metrics(root_p / name)

        def ci(k, lo, hi, row=row):
            return f"{float(row[k]):.0f} [{float(row[lo]):.0f}, {float(row[hi]):.0f}]"

        same = ""
        if sizes and name in SAME_SIZE:
            sg, _ = metrics(pathlib.Path(sizes) / SAME_SIZE[name])
            same = paired(g, sg)
        print(
            f"| {name} | {ci('final_return_mean', 'final_return_ci95_low', 'final_return_ci95_high')} "
            f"| {ci('greedy_return_mean', 'greedy_return_ci95_low', 'greedy_return_ci95_high')} "
            f"| {'' if name == 'nearest' else paired(g, base_g)} "
            f"| {'' if name == 'nearest' else paired(f, base_f)} "
            f"| {ci('mean_return_first_5min', 'first_5min_ci95_low', 'first_5min_ci95_high')} "
            f"| {float(row['minutes_to_90pct']):.1f} | {row['stuck_experiments']} | {same} |"
        )


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else None)

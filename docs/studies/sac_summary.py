"""Summarise the S-AC study (docs/studies/sac.md) from sweep results.

Usage: python docs/studies/sac_summary.py SWEEP_DIR BASELINE_DIR [--sort KEY]

SWEEP_DIR is an `rmac-mj sweep --out` directory of S-AC configurations (docs/studies/sac.toml or
sac-tiles.toml); BASELINE_DIR is the paper's configuration run on the same seeds (a configuration
directory of either sweep). Prints one markdown row per configuration: the greedy return after
trial 600, the mean of the last five greedy trials, the exploring return (mean of the last 50
trials), the mean of the first 5 simulated minutes (95% CIs over experiments), minutes until the
mean curve is within 10% of its final level, stuck experiments (last 50 trials below -1500), and
the paired difference from the baseline, experiment i against experiment i (same seeds): mean ±
95% half-width and the p-value of a paired t-test. --sort greedy_last5 orders the rows by that
metric (best first); the default keeps the sweep's order.
"""

import json
import pathlib
import sys

import numpy as np
from scipy import stats

from rmac_mj.experiments.results import confidence_interval, minutes_to_within


def metrics(directory: pathlib.Path) -> dict:
    files = sorted((directory / "curves" / "s-ac").glob("exp_*.npz"))
    if not files:
        raise SystemExit(f"sac_summary: no S-AC curves in {directory}")
    data = [np.load(f) for f in files]
    returns = np.array([d["returns"] for d in data])
    greedy = np.array([d["greedy_returns"] for d in data])
    seconds = json.loads((directory / "summary.json").read_text()).get("trial_seconds", 3.0)
    first = int(round(5 * 60 / seconds))
    return {"greedy": greedy[:, -1], "greedy_last5": greedy[:, -5:].mean(axis=1),
            "exploring": returns[:, -50:].mean(axis=1), "first_5min": returns[:, :first].mean(axis=1),
            "minutes": minutes_to_within(returns.mean(axis=0), trial_seconds=seconds),
            "stuck": int(np.sum(returns[:, -50:].mean(axis=1) < -1500)), "n": len(returns)}


def ci(samples: np.ndarray) -> str:
    mean, low, high = confidence_interval(samples)
    return f"{mean:.0f} [{low:.0f}, {high:.0f}]"


def paired(a: np.ndarray, b: np.ndarray) -> str:
    d = a - b
    if not np.any(d):
        return "0 (identical)"
    half = stats.t.ppf(0.975, len(d) - 1) * d.std(ddof=1) / np.sqrt(len(d))
    p = stats.ttest_rel(a, b).pvalue
    return f"{d.mean():+.0f} ± {half:.0f} (p {p:.3f})" if p >= 0.001 else \
        f"{d.mean():+.0f} ± {half:.0f} (p < 0.001)"


def main(arguments: list[str]) -> None:
    sort = None
    if "--sort" in arguments:
        at = arguments.index("--sort")
        sort = arguments[at + 1]
        del arguments[at:at + 2]
    root, baseline = pathlib.Path(arguments[0]), pathlib.Path(arguments[1])
    index = json.loads((root / "sweep.json").read_text())
    names = [c["directory"] for c in index["configurations"]]
    base = metrics(baseline)
    rows = [(name, metrics(root / name)) for name in names]
    if sort:
        rows.sort(key=lambda row: -row[1][sort].mean())
    print("| configuration | greedy at 600 | greedy, last 5 | exploring, last 50 | first 5 min "
          "| min to 90% | stuck | paired greedy, last 5 | paired exploring | paired first 5 min |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, m in rows:
        print(f"| {name} | {ci(m['greedy'])} | {ci(m['greedy_last5'])} | {ci(m['exploring'])} "
              f"| {ci(m['first_5min'])} | {m['minutes']:.1f} | {m['stuck']}/{m['n']} "
              f"| {paired(m['greedy_last5'], base['greedy_last5'])} "
              f"| {paired(m['exploring'], base['exploring'])} "
              f"| {paired(m['first_5min'], base['first_5min'])} |")


if __name__ == "__main__":
    main(sys.argv[1:])

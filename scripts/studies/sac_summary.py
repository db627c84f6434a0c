"""Summarise the S-AC study (docs/studies/sac.md) from sweep results.

Usage: python scripts/studies/sac_summary.py SWEEP_DIR BASELINE_DIR [--sort KEY] [--plot FILE.png]

SWEEP_DIR is an `rmac-mj sweep --out` directory of S-AC configurations (docs/studies/sac.toml or
sac-tiles.toml); BASELINE_DIR is the paper's configuration run on the same seeds (a configuration
directory of either sweep). Prints one markdown row per configuration: the greedy return after
trial 600, the mean of the last five greedy trials, the exploring return (mean of the last 50
trials), the mean of the first 5 simulated minutes (95% CIs over experiments), minutes until the
mean curve is within 10% of its final level, stuck experiments (last 50 trials below -1500), and
the paired difference from the baseline, experiment i against experiment i (same seeds): mean ±
95% half-width and the p-value of a paired t-test. --sort greedy_last5 orders the rows by that
metric (best first); the default keeps the sweep's order. --plot draws, for the learning-rate
sweep (sac.toml), the first 5 minutes and the last five greedy trials against alpha_a, one line
per (alpha_c, lambda), mean and 95% CI.
"""

import json
import pathlib
import sys

import goal_report
import numpy as np

from rmac_mj.evaluation import confidence_interval


def metrics(directory: pathlib.Path) -> dict:
    """goal_report's metrics of the S-AC experiments in ``directory``."""
    return goal_report.metrics(*goal_report.load(directory, "s-ac"))


def ci(samples: np.ndarray) -> str:
    mean, low, high = confidence_interval(samples)
    return f"{mean:.0f} [{low:.0f}, {high:.0f}]"


def paired(a: np.ndarray, b: np.ndarray) -> str:
    if not np.any(a - b):
        return "0 (identical)"
    mean, half, p = goal_report.paired_difference(a, b)
    return (
        f"{mean:+.0f} ± {half:.0f} (p {p:.3f})"
        if p >= 0.001
        else f"{mean:+.0f} ± {half:.0f} (p < 0.001)"
    )


def plot(root: pathlib.Path, index: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lines: dict = {}
    for c in index["configurations"]:
        v = c["values"]
        lines.setdefault((v["s-ac.alpha_c"], v["s-ac.lam"]), []).append(
            (v["s-ac.alpha_a"], metrics(root / c["directory"]))
        )
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for (critic, lam), points in sorted(lines.items()):
        points.sort(key=lambda p: p[0])
        x = np.array([p[0] for p in points])
        style = "-" if lam == 0.65 else "--"
        for ax, key in zip(axes, ("first_5min", "greedy_last5")):
            mean, low, high = np.array([confidence_interval(p[1][key]) for p in points]).T
            shift = x * (1 + 0.04 * (critic / 0.1 - 1))  # spread the error bars a little
            ax.errorbar(
                shift,
                mean,
                yerr=[mean - low, high - mean],
                fmt="o" + style,
                ms=3,
                lw=1,
                capsize=2,
                label=f"alpha_c {critic}, lambda {lam}",
            )
    for ax, title in zip(
        axes,
        (
            "mean return, first 5 simulated minutes",
            "greedy return, mean of the last 5 greedy trials",
        ),
    ):
        ax.set_xscale("log")
        ax.minorticks_off()
        ax.set_xticks([0.0025, 0.005, 0.01, 0.02], ["0.0025", "0.005\n(paper)", "0.01", "0.02"])
        ax.set(xlabel="actor learning rate alpha_a", title=title)
        ax.grid(alpha=0.3)
    axes[1].set_ylim(-1450, -700)  # one lambda 0.8, alpha_c 0.2 bar reaches -1760
    axes[1].axhline(-748, color="k", lw=0.8, ls=":", label="near-optimal (-748)")
    axes[0].set_ylabel("return per trial, 10 experiments")
    axes[1].legend(fontsize=7, loc="lower left", ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main(arguments: list[str]) -> None:
    sort, out = None, None
    if "--plot" in arguments:
        at = arguments.index("--plot")
        out = arguments[at + 1]
        del arguments[at : at + 2]
    if "--sort" in arguments:
        at = arguments.index("--sort")
        sort = arguments[at + 1]
        del arguments[at : at + 2]
    root, baseline = pathlib.Path(arguments[0]), pathlib.Path(arguments[1])
    index = json.loads((root / "sweep.json").read_text())
    names = [c["directory"] for c in index["configurations"]]
    base = metrics(baseline)
    rows = [(name, metrics(root / name)) for name in names]
    if sort:
        rows.sort(key=lambda row: -row[1][sort].mean())
    print(
        "| configuration | greedy at 600 | greedy, last 5 | exploring, last 50 | first 5 min "
        "| min to 90% | stuck | paired greedy, last 5 | paired exploring | paired first 5 min |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, m in rows:
        print(
            f"| {name} | {ci(m['greedy'])} | {ci(m['greedy_last5'])} | {ci(m['exploring'])} "
            f"| {ci(m['first_5min'])} | {m['minutes_to_90pct']:.1f} | {m['stuck']}/{m['n']} "
            f"| {paired(m['greedy_last5'], base['greedy_last5'])} "
            f"| {paired(m['exploring'], base['exploring'])} "
            f"| {paired(m['first_5min'], base['first_5min'])} |"
        )
    if out:
        plot(root, index, out)


if __name__ == "__main__":
    main(sys.argv[1:])

"""The tables and the figure of docs/panel.md, from the panel's result directories.

    python scripts/reports/panel_report.py PANEL [SAC] [--out docs]

PANEL is a ``rmac-mj panel --out PANEL`` directory (one ``reproduce`` directory per task); SAC,
optionally, a directory of the same tasks' SAC runs made apart (``SAC/<task>/``). A directory may be
unfinished: every experiment whose curve is saved counts, and the tables say how many. Prints one
Markdown table per task (:func:`rmac_mj.experiments.panel.panel_rows`: the greedy return at the
goal's trial as its IQM with a stratified-bootstrap 95% interval, the experiments that reached the
goal, the environment steps, the CPU per experiment and against SAC's) and draws ``panel.png``:
every learner's greedy return against environment steps, task by task, with the goal.
"""

from __future__ import annotations

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rmac_mj.agents import display_name  # noqa: E402
from rmac_mj.evaluation import iqm_interval  # noqa: E402
from rmac_mj.experiments import panel  # noqa: E402
from rmac_mj.results import ResultStore  # noqa: E402

#: Where the figures go by default: the repository's docs/, wherever the script is run from.
DOCS = pathlib.Path(__file__).resolve().parents[2] / "docs"


def _directories(task: panel.PanelTask, roots: list[pathlib.Path]) -> list[pathlib.Path]:
    return [root / task.name for root in roots if (root / task.name / "config.json").is_file()]


def figure(roots: list[pathlib.Path], path: pathlib.Path) -> None:
    fig, axes = plt.subplots(2, 4, figsize=(20, 8.5), constrained_layout=True)
    for ax, task in zip(axes.flat, panel.TASKS):
        for directory in _directories(task, roots):
            store = ResultStore(directory)
            protocol = store.read_config()["protocol"]
            for algorithm in protocol["algorithms"]:
                if not store.finished(algorithm):
                    continue
                curves = store.load_curves(algorithm, None)
                at = np.asarray(curves.greedy_trials, dtype=int) - 1
                counted = curves.env_steps
                if counted is None:
                    continue
                steps = np.mean(counted[:, at], axis=0)
                greedy = curves.greedy_returns
                value = [iqm_interval(greedy[:, k]) for k in range(greedy.shape[1])]
                iqm = np.array([v.value for v in value])
                low, high = np.array([v.low for v in value]), np.array([v.high for v in value])
                (line,) = ax.plot(
                    steps, iqm, marker=".", label=f"{display_name(algorithm)} ({greedy.shape[0]})"
                )
                ax.fill_between(steps, low, high, color=line.get_color(), alpha=0.15, linewidth=0)
        ax.axhline(task.goal, color="black", linestyle="-.", linewidth=1.0, label="goal")
        ax.set_title(task.name, fontsize="medium")
        ax.set_xlabel("environment steps")
        ax.set_ylabel("greedy return (IQM, 95% CI)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="x-small", loc="lower right")
    for ax in axes.flat[len(panel.TASKS) :]:
        ax.set_visible(False)
    fig.suptitle(
        "The panel: greedy return against interaction (experiments per learner in brackets)"
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("roots", nargs="+", type=pathlib.Path)
    parser.add_argument("--out", type=pathlib.Path, default=DOCS)
    args = parser.parse_args()
    for task in panel.TASKS:
        rows = panel.panel_rows(task, _directories(task, args.roots))
        if rows:
            print(panel.format_rows(task, rows))
            print()
    figure(args.roots, args.out / "panel.png")
    print(f"figure: {args.out / 'panel.png'}")


if __name__ == "__main__":
    main()

"""Draw docs/external_benchmarks.png from two `rmac-mj reproduce --env` result directories.

    python scripts/reports/external_benchmarks_figure.py --pendulum DIR [DIR ...] --cartpole DIR [DIR ...]

Greedy return (mean and 95% interval over experiments) against environment steps, with the published
deep-RL levels of docs/external-benchmarks.md as horizontal lines (their sources are cited there).
"""

from __future__ import annotations

import argparse
import json
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rmac_mj import envs  # noqa: E402
from rmac_mj.agents import display_name  # noqa: E402
from rmac_mj.evaluation import confidence_interval  # noqa: E402
from rmac_mj.rollout import steps_per_trial  # noqa: E402

#: Where the figures go by default: the repository's docs/, wherever the script is run from.
DOCS = pathlib.Path(__file__).resolve().parents[2] / "docs"
#: Published deep-RL levels (docs/external-benchmarks.md cites them): a label and the returns drawn.
PUBLISHED = {
    "pendulum": ("SAC -157, TD3 -152 after 20k steps (rl-baselines3-zoo)", (-157.0, -152.0)),
    "cartpole": ("SAC 835 after 100k steps (TD-MPC2 repository)", (835.0,)),
}


def panel(ax, runs: list[pathlib.Path], published) -> None:
    for run in runs:
        curves(ax, run)
    label, values = published
    for value in values:
        ax.axhline(value, ls="--", lw=1, color="k")
    ax.annotate(
        label,
        (0.02, min(values)),
        xycoords=("axes fraction", "data"),
        va="top",
        fontsize=7,
        xytext=(0, -2),
        textcoords="offset points",
    )
    ax.set_xlabel("environment steps")
    ax.set_ylabel("greedy return (sum of rewards per episode)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")


def curves(ax, run: pathlib.Path) -> None:
    """Each learner's greedy returns in ``run``: mean and 95% interval against environment steps."""
    summary = json.loads((run / "summary.json").read_text())
    protocol = summary["protocol"]
    env = envs.load(
        protocol["env"],
        protocol["task_kwargs"],
        learner_state=protocol["learner_state"],
        action_repeat=protocol["action_repeat"],
        trial_steps=protocol["trial_steps"],
        control_timestep=protocol["control_timestep"],
    )
    env_steps = steps_per_trial(env) * protocol["action_repeat"]  # environment steps per episode
    for algo in protocol["algorithms"]:
        files = sorted((run / "curves" / algo).glob("exp_*.npz"))
        greedy = np.array(
            [np.load(f)["greedy_returns"] for f in files]
        )  # (experiments, evaluations)
        steps = np.load(files[0])["greedy_trials"] * env_steps
        mean, low, high = confidence_interval(greedy)
        (line,) = ax.plot(
            steps, mean, marker="o", ms=3, label=f"{display_name(algo)} ({len(files)} exp.)"
        )
        ax.fill_between(steps, low, high, color=line.get_color(), alpha=0.2)
    ax.set_title(protocol["env"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--pendulum",
        type=pathlib.Path,
        nargs="+",
        required=True,
        help="result directories of Pendulum-v1 runs",
    )
    parser.add_argument(
        "--cartpole",
        type=pathlib.Path,
        nargs="+",
        required=True,
        help="result directories of cartpole/swingup runs",
    )
    parser.add_argument("--out", type=pathlib.Path, default=DOCS / "external_benchmarks.png")
    args = parser.parse_args()
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    panel(axes[0], args.pendulum, PUBLISHED["pendulum"])
    panel(axes[1], args.cartpole, PUBLISHED["cartpole"])
    fig.tight_layout()
    fig.savefig(args.out, dpi=90)


if __name__ == "__main__":
    main()

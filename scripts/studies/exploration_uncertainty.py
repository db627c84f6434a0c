"""The process model's uncertainty as RMAC's where='uncertain' rule sees it (docs/studies/exploration-schedule.md).

Usage: python scripts/studies/exploration_uncertainty.py [THRESHOLD] [--experiments N] [--trials T]

Runs experiments 0..N-1 of the sweep's protocol (seed 0, the same task and agent seeds as
`rmac-mj sweep`) with Exploration(where='uncertain', uncertainty_threshold=THRESHOLD), records
``model_uncertainty`` on every scheduled exploring step (every 3rd step), and prints its
percentiles and the fraction of scheduled steps that explored, per range of trials, then for
trials 201-600 near upright (|phi| < 0.3 rad) and elsewhere. THRESHOLD 0
(the default) explores on every scheduled step, draw for draw as the paper's schedule, so it
measures the distribution in a normal run.
"""

import argparse

import numpy as np

from rmac_mj import tasks
from rmac_mj.agents import RMAC, Exploration, RMACConfig
from rmac_mj.experiments import experiment_seeds
from rmac_mj.rollout import action_space_of, run_trial, state_space_of

RANGES = ((0, 10), (10, 50), (50, 200), (200, 600))
THRESHOLDS = (0.6, 0.8, 1.0, 1.2, 1.5)


def run(index: int, threshold: float, trials: int) -> np.ndarray:
    """(trial, uncertainty, |phi|) of every scheduled step of experiment ``index``."""
    seen = []
    agent = None

    def recording(memory, query):
        value = model_uncertainty(memory, query)
        seen.append((agent.trial, value, abs(float(query[0]))))
        return value

    model_uncertainty = recording
    agent_seq, task_seed = experiment_seeds(0, index)
    env = tasks.load("dc_pendulum", "swingup", task_kwargs={"random": task_seed})
    agent = RMAC(
        state_space_of(env),
        action_space_of(env),
        RMACConfig(exploration=Exploration(where="uncertain", uncertainty_threshold=threshold)),
        seed=np.random.default_rng(agent_seq),
    )
    for trial in range(1, trials + 1):
        run_trial(env, agent)
        if trial % 10 == 0:  # the sweep's greedy trials (evaluate_every = 10) do not explore
            run_trial(env, agent, learn=False)
    return np.array(seen)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("threshold", type=float, nargs="?", default=0.0)
    parser.add_argument("--experiments", type=int, default=2)
    parser.add_argument("--trials", type=int, default=600)
    args = parser.parse_args()
    data = np.concatenate([run(i, args.threshold, args.trials) for i in range(args.experiments)])
    print(
        f"threshold {args.threshold:g}, experiments 0..{args.experiments - 1}, "
        f"{len(data)} scheduled steps; {int(np.isinf(data[:, 1]).sum())} with fewer than K samples"
    )
    print(
        "| trials | percentiles 10 / 25 / 50 / 75 / 90 | explored | "
        + " | ".join(f"P(>= {t:g})" for t in THRESHOLDS)
        + " |"
    )
    print("|---|---|---|" + "---|" * len(THRESHOLDS))
    for lo, hi in RANGES:
        v = data[(data[:, 0] >= lo) & (data[:, 0] < hi), 1]
        if not len(v):
            continue
        q = np.percentile(v[np.isfinite(v)], [10, 25, 50, 75, 90])
        print(
            f"| {lo + 1}-{hi} | "
            + " / ".join(f"{x:.2f}" for x in q)
            + f" | {np.mean(v >= args.threshold):.2f} | "
            + " | ".join(f"{np.mean(v >= t):.2f}" for t in THRESHOLDS)
            + " |"
        )
    late = data[data[:, 0] >= 200]
    print()
    print(
        "| trials 201-600 | share of scheduled steps | median | explored | "
        + " | ".join(f"P(>= {t:g})" for t in THRESHOLDS)
        + " |"
    )
    print("|---|---|---|---|" + "---|" * len(THRESHOLDS))
    for label, rows in (
        ("near upright, abs(phi) < 0.3", late[late[:, 2] < 0.3]),
        ("elsewhere", late[late[:, 2] >= 0.3]),
    ):
        v = rows[:, 1]
        print(
            f"| {label} | {len(v) / len(late):.2f} | {np.median(v):.2f} | "
            f"{np.mean(v >= args.threshold):.2f} | "
            + " | ".join(f"{np.mean(v >= t):.2f}" for t in THRESHOLDS)
            + " |"
        )


if __name__ == "__main__":
    main()

"""Learning curves of RMAC on dc_pendulum/swingup (the measurements in docs/rmac.md).

    python docs/rmac_learning_curve.py --experiments 10 --trials 600 --out curves.npz \
        [--set key=value ...]   # RMACConfig overrides, values parsed as Python literals

Experiment i uses the i-th child of numpy.random.SeedSequence(seed): one stream for the agent's
exploration. The task itself is deterministic (x_0 = [pi, 0]). Writes the raw per-trial sums of
rewards (experiments x trials) with the config, seeds and versions; prints the summary.
"""

from __future__ import annotations

import argparse
import ast
import json
import multiprocessing as mp
import subprocess
import time

import numpy as np


def run(args):
    config_kwargs, seed_seq, trials = args
    from rmac_mj import tasks
    from rmac_mj.agents.base import Exploration
    from rmac_mj.agents.rmac import RMAC, RMACConfig
    from rmac_mj.experiments.episode import action_space_of, run_trial, state_space_of
    kwargs = dict(config_kwargs)
    if "exploration" in kwargs:
        kwargs["exploration"] = Exploration(**kwargs["exploration"])
    env = tasks.load("dc_pendulum", "swingup")
    agent = RMAC(state_space_of(env), action_space_of(env), RMACConfig(**kwargs),
                 seed=np.random.default_rng(seed_seq))
    returns = np.array([run_trial(env, agent) for _ in range(trials)])
    greedy = run_trial(env, agent, learn=False)
    return returns, greedy


def minutes_to_final(curve: np.ndarray, trial_seconds: float = 3.0) -> float | None:
    """Simulated minutes until the 10-trial running mean of ``curve`` first comes within 10% of its
    final level (the mean of the last 50 trials)."""
    final = curve[-50:].mean()
    running = np.convolve(curve, np.ones(10) / 10, mode="valid")
    inside = np.flatnonzero(np.abs(running - final) <= 0.1 * abs(final))
    return None if not len(inside) else (int(inside[0]) + 10) * trial_seconds / 60


def summary(curves: np.ndarray, trial_seconds: float = 3.0) -> dict:
    mean = curves.mean(axis=0)
    final = mean[-50:].mean()
    per_experiment = [minutes_to_final(c, trial_seconds) for c in curves]
    out = {f"trial_{t}": float(mean[t - 1]) for t in (1, 10, 50, 100, 300, 600) if t <= len(mean)}
    out["last50"] = float(final)
    out["last50_per_experiment"] = [float(c[-50:].mean()) for c in curves]
    out["minutes_to_10pct"] = minutes_to_final(mean, trial_seconds)  # of the mean curve
    out["minutes_to_10pct_median_experiment"] = float(np.median(
        [np.inf if m is None else m for m in per_experiment]))
    out["last50_sem"] = float(np.std([c[-50:].mean() for c in curves], ddof=1)
                              / np.sqrt(len(curves))) if len(curves) > 1 else None
    out["worse_than_-1500"] = int(sum(c[-50:].mean() < -1500 for c in curves))
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--experiments", type=int, default=10)
    parser.add_argument("--trials", type=int, default=600)
    parser.add_argument("--seed", type=int, default=2013)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", default=None)
    parser.add_argument("--set", action="append", default=[])
    args = parser.parse_args()
    overrides = {}
    for item in args.set:
        key, value = item.split("=", 1)
        overrides[key] = ast.literal_eval(value)
    seeds = np.random.SeedSequence(args.seed).spawn(args.experiments)
    start = time.time()
    with mp.get_context("fork").Pool(args.workers) as pool:
        results = pool.map(run, [(overrides, s, args.trials) for s in seeds])
    curves = np.array([r[0] for r in results])
    greedy = np.array([r[1] for r in results])
    info = summary(curves)
    info["greedy_final"] = float(greedy.mean())
    info["overrides"] = overrides
    info["wall_seconds"] = time.time() - start
    print(json.dumps(info))
    if args.out:
        import mujoco
        import numba
        commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True).stdout
        meta = dict(config=overrides, seed=args.seed, experiments=args.experiments,
                    versions=dict(numpy=np.__version__, mujoco=mujoco.__version__,
                                  numba=numba.__version__), commit=commit.strip(), summary=info)
        np.savez(args.out, curves=curves, greedy=greedy, meta=json.dumps(meta, default=str))


if __name__ == "__main__":
    main()

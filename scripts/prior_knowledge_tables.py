"""The tables of docs/prior-knowledge.md from finished `rmac-mj reproduce` result directories.

    python scripts/prior_knowledge_tables.py results/prior/none results/prior/demo ... [--replay 10]

Learning curves come from the runs' files. Whether a trial swings up is not in them (they hold sums of
rewards), so the first ``--replay`` trials of every experiment are replayed: the runner is
deterministic, so rebuilding each experiment with ``experiment.build_experiment`` (as the runner does)
reproduces its trials, and every replayed return is checked against the stored one to 1e-9.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np
from scipy import stats

from rmac_mj.agents import make_agent
from rmac_mj.evaluation import (
    FIRST_MINUTES,
    confidence_interval,
    early_returns,
    final_returns,
    stuck_threshold,
)
from rmac_mj.experiments import Protocol, build_experiment, demonstration_for
from rmac_mj.results import ResultStore
from rmac_mj.rollout import run_trial

#: A learning trial counts as "worse than the demonstrator" below its mean return minus this.
MARGIN = 500.0
#: "Up": |phi| < this (rad); "held": for every step of the last second of the trial.
UPRIGHT = 0.2
LAST_SECOND_STEPS = 34


def replay(protocol: Protocol, algorithm: str, index: int, returns: np.ndarray, trials: int):
    """Rows (return, reached upright, held the last second, greedy return after it): row 0 a greedy
    trial right after seeding, rows 1..trials the first learning trials of one experiment."""
    if protocol.prior_file is not None:
        raise SystemExit("replaying a file prior is not supported here")
    experiment = build_experiment(protocol, algorithm, index)
    env, agent = experiment.env, experiment.agent

    def flags(angles):
        a = np.abs(angles)
        return bool(a.min() < UPRIGHT), bool(np.all(a[-LAST_SECOND_STEPS:] < UPRIGHT))

    # The policy as seeded, before any learning, and after each replayed trial.
    def greedy_now() -> tuple[float, list[float]]:
        """A greedy trial of a copy of the agent as it is now (the original is untouched)."""
        twin = make_agent(
            algorithm,
            experiment.state_space,
            experiment.action_space,
            config=protocol.agent_configs.get(algorithm),
        )
        twin.load_state_dict(agent.state_dict())
        angles: list[float] = []
        ret = run_trial(
            env, twin, learn=False, on_step=lambda e, u, r: angles.append(e.physics.angle())
        )
        return ret, angles

    greedy, angles = greedy_now()
    out = [(greedy, *flags(angles), greedy)]
    for trial in range(1, trials + 1):
        angles: list[float] = []
        ret = run_trial(env, agent, on_step=lambda e, u, r: angles.append(e.physics.angle()))  # noqa: B023
        if abs(ret - returns[trial - 1]) > 1e-9:
            raise SystemExit(
                f"replay of experiment {index} trial {trial} differs: {ret} vs {returns[trial - 1]}"
            )
        out.append((ret, *flags(angles), greedy_now()[0]))
        if protocol.evaluate_every and trial % protocol.evaluate_every == 0:
            run_trial(env, agent, learn=False)
    return out


def analyse(out: pathlib.Path, replay_trials: int) -> dict:
    store = ResultStore(out)
    protocol = Protocol.from_dict(store.read_config()["protocol"])
    (algorithm,) = protocol.algorithms
    curves = store.load_curves(algorithm, protocol.experiments)
    returns, greedy = curves.returns, curves.greedy_returns
    if protocol.prior is None:  # the demonstration the same experiment would have been seeded with
        seeded = Protocol(algorithms=protocol.algorithms, seed=protocol.seed, prior="demo")
        demo = np.array(
            [
                demonstration_for(seeded, i).trial_returns().mean()
                for i in range(protocol.experiments)
            ]
        )
    else:
        demo = (
            curves.demonstration_returns.mean(axis=1)
            if curves.demonstration_returns.size
            else np.full(protocol.experiments, np.nan)
        )
    finals = final_returns(returns)
    seconds = store.read_summary()["trial_seconds"]
    optimal = store.read_summary().get("optimal_return")
    stuck_below = stuck_threshold(optimal) if optimal is not None else -1500.0
    row = {
        "name": out.name,
        "experiments": protocol.experiments,
        "prior": protocol.prior,
        "parts": protocol.prior_parts,
        "trial": {
            t: float(returns[:, t - 1].mean())
            for t in (1, 2, 3, 5, 10, 50, 100, 600)
            if t <= returns.shape[1]
        },
        "last50": confidence_interval(finals),
        "finals": finals,
        "first5": confidence_interval(early_returns(returns, FIRST_MINUTES, seconds)),
        "first10": confidence_interval(early_returns(returns, 2 * FIRST_MINUTES, seconds)),
        "stuck": int((finals < stuck_below).sum()),
        "worst_final": float(finals.min()),
        "greedy_end": float(greedy[:, -1].mean()) if greedy.size else None,
        "demo_mean": float(np.nanmean(demo)) if np.isfinite(demo).any() else None,
        "worst_trial_mean": float(returns.min(axis=1).mean()),
        "worst_trial": float(returns.min()),
        "worst_first10": float(returns[:, :10].min()),
    }
    below = returns < (demo - MARGIN)[:, None]
    row["exp_below_demo"] = int(below.any(axis=1).sum())
    row["trials_below_demo"] = int(below.sum())
    row["trials_below_demo_first100"] = int(below[:, :100].sum())
    row["last_trial_below_demo"] = (
        int(np.max(np.where(below.any(axis=0))[0]) + 1) if below.any() else 0
    )
    row["final_vs_demo"] = float((finals - demo).mean())
    if replay_trials:
        flags = np.array(
            [
                replay(protocol, algorithm, i, returns[i], replay_trials)
                for i in range(protocol.experiments)
            ]
        )  # (experiments, 1 + trials, 3)
        row["greedy0"] = float(flags[:, 0, 0].mean())
        row["greedy0_held"] = int(flags[:, 0, 2].sum())
        row["first_up"] = int(flags[:, 1, 1].sum())
        row["first_held"] = int(flags[:, 1, 2].sum())
        row["held_first_n"] = flags[:, 1:, 2].mean(axis=0).tolist()
        row["greedy_first_n"] = flags[:, :, 3].mean(axis=0).tolist()
    return row


def fmt_ci(ci) -> str:
    mean, low, high = ci
    return f"{mean:.0f} [{low:.0f}, {high:.0f}]"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dirs", nargs="+", type=pathlib.Path)
    parser.add_argument("--replay", type=int, default=10, help="trials replayed per experiment")
    parser.add_argument("--baseline", default="none", help="run the others are tested against")
    args = parser.parse_args()
    rows = [analyse(d, args.replay) for d in args.dirs]
    base = next((r for r in rows if r["name"] == args.baseline), None)
    print(
        "| run | exp. | trial 1 | 2 | 3 | 10 | 50 | 100 | 600 | last 50 [95% CI] | first 5 min "
        "[95% CI] | first 10 min | stuck | greedy at 600 | p (last 50 vs none) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        t = r["trial"]
        p = (
            stats.ttest_ind(r["finals"], base["finals"], equal_var=False).pvalue
            if base is not None and r is not base
            else None
        )
        print(
            f"| {r['name']} | {r['experiments']} | {t[1]:.0f} | {t[2]:.0f} | {t[3]:.0f} | "
            f"{t[10]:.0f} | {t[50]:.0f} | {t[100]:.0f} | {t[600]:.0f} | {fmt_ci(r['last50'])} | "
            f"{fmt_ci(r['first5'])} | {r['first10'][0]:.0f} | {r['stuck']}/{r['experiments']} | "
            f"{r['greedy_end']:.0f} | {'' if p is None else f'{p:.2g}'} |"
        )
    print()
    print(
        "| run | demonstrator mean return | greedy before learning (held) | greedy after trials "
        "0..10 | trial 1 up / held | "
        "held, trials 1..10 | worst trial (mean of exps; all) | exps with a trial < demo - "
        f"{MARGIN:.0f} | such trials (first 100; last one) | last 50 - demo |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        demo = f"{r['demo_mean']:.0f}" if r["demo_mean"] is not None else "-"
        held = " ".join(f"{v * r['experiments']:.0f}" for v in r.get("held_first_n", []))
        up = f"{r.get('first_up', '-')}/{r.get('first_held', '-')} of {r['experiments']}"
        below = (
            (
                f"{r['exp_below_demo']}/{r['experiments']} | {r['trials_below_demo']} "
                f"({r['trials_below_demo_first100']}; trial {r['last_trial_below_demo']}) | "
                f"{r['final_vs_demo']:+.0f}"
            )
            if "exp_below_demo" in r
            else "- | - | -"
        )
        greedy0 = (
            f"{r['greedy0']:.0f} ({r['greedy0_held']}/{r['experiments']})"
            if "greedy0" in r
            else "-"
        )
        greedy_n = " ".join(f"{v:.0f}" for v in r.get("greedy_first_n", []))
        print(
            f"| {r['name']} | {demo} | {greedy0} | {greedy_n} | {up} | {held} | {r['worst_trial_mean']:.0f}; "
            f"{r['worst_trial']:.0f} | {below} |"
        )


if __name__ == "__main__":
    main()

"""Why RMAC with planning learns the arm fast and then falls apart: per real trial, the model's
errors, what the memories hold and how far the critic drifts from the returns it predicts.

    python scripts/studies/arm_planning_diagnosis.py --experiments 5 --trials 60 --out arm-diag.npz
    python scripts/studies/arm_planning_diagnosis.py ... --set planning.start=trajectory \
        --set planning.horizon=10

RMAC with the settings of ``arm-fastest.toml`` (gamma 0.98, alpha_r 0.05, planning 30 steps) and
the arm's memory sizes and exploration of that run (Table 2's, not grown with the dimension), unless
``--set`` changes them. Printed per trial: the mean greedy return, the critic's V(x0) against the
greedy trial's discounted return from x0, the model's one-step and open-loop (whole-trial) errors on
the next real trial (the model as it was before that trial), the fraction of the critic's and the
reference's samples inserted while rehearsing, and the fraction of simulated states clipped to the
speed box.
"""

from __future__ import annotations

import argparse
import copy
import json

import numpy as np

from rmac_mj import tasks
from rmac_mj.agents import make_agent
from rmac_mj.rollout import action_space_of, learner_state_of, state_of, state_space_of

#: arm-fastest.toml's RMAC with planning, with the sizes and noise that run had (before the
#: settings followed the task's units).
ARM_FASTEST = {
    "gamma": 0.98,
    "lam": 0.65,
    "alpha_r": 0.05,
    "planning": {"steps": 30},
    "critic": {"capacity": 2000, "neighbours": 20},
    "process": {"capacity": 100, "neighbours": 9},
    "reference": {"capacity": 2000, "neighbours": 20},
    "exploration": {"sigma": 1.0},
}


def _nested(settings: list[str]) -> dict:
    out: dict = {}
    for item in settings:
        path, value = item.split("=", 1)
        *parents, leaf = path.split(".")
        node = out
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = json.loads(value) if value[:1] in '0123456789-[{tfn"' else value
    return out


def _merge(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in b.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def _trial(env, agent, learn: bool):
    """One trial; returns (states (K+1, n), actions (K, m), rewards (K,))."""
    keys = learner_state_of(env).keys
    ts = env.reset()
    x = state_of(ts.observation, keys)
    states, actions, rewards = [x], [], []
    if not learn:
        agent.begin_greedy_trial()
    u = agent.start(x) if learn else agent.greedy_action(x)
    while True:
        actions.append(np.clip(u, agent.action_space.low, agent.action_space.high))
        ts = env.step(u)
        x = state_of(ts.observation, keys)
        states.append(x)
        rewards.append(float(ts.reward))
        if ts.last():
            if learn:
                agent.stop(rewards[-1], x)
            return np.array(states), np.array(actions), np.array(rewards)
        u = agent.step(rewards[-1], x) if learn else agent.greedy_action(x)


def _memory(agent, name: str):
    """RMAC's LLR memory ``name`` ('critic', 'reference', 'process')."""
    memory = getattr(agent, name)
    return getattr(memory, "memory", memory)


def _latest_stamp(memory) -> int:
    n = memory.n_samples_
    return int(memory.stamp_[:n].max()) + 1 if n else 0


def _simulated_fraction(memory, intervals) -> float:
    stamps = memory.stamp_[: memory.n_samples_]
    if not len(stamps):
        return 0.0
    simulated = np.zeros(len(stamps), bool)
    for lo, hi in intervals:
        simulated |= (stamps >= lo) & (stamps < hi)
    return float(simulated.mean())


def run(seed: int, trials: int, config: dict, every: int) -> dict[str, np.ndarray]:
    env = tasks.load("two_link_arm", "reach", task_kwargs={"random": seed})
    space, actions_space = state_space_of(env), action_space_of(env)
    agent = make_agent("rmac", space, actions_space, config=config, seed=seed)
    gamma = agent.config.gamma
    speed = ~space.periodic
    weights = np.asarray(agent.config.critic.weights)
    intervals = {"critic": [], "reference": []}
    clipped = [0, 0]
    rewards_seen = [-np.inf, 0, 0]  # the largest real reward; simulated rewards, those above it
    rehearsal = agent.rehearsal
    original_after, original_predict = rehearsal.after_trial, rehearsal.model.predict

    def after_trial(a):
        before = {name: _latest_stamp(_memory(a, name)) for name in intervals}
        original_after(a)
        for name in intervals:
            intervals[name].append((before[name], _latest_stamp(_memory(a, name))))

    def predict(x, u):
        x_next, r = original_predict(x, u)
        clipped[0] += 1
        clipped[1] += bool(np.any(np.abs(x_next[speed]) >= space.high[speed] - 1e-12))
        rewards_seen[1] += 1
        rewards_seen[2] += r > rewards_seen[0] + 1e-9
        return x_next, r

    rehearsal.after_trial, rehearsal.model.predict = after_trial, predict
    rows = []
    for t in range(trials):
        model_before = copy.deepcopy(rehearsal.model)
        states, actions, rewards = _trial(env, agent, learn=True)
        rewards_seen[0] = max(rewards_seen[0], float(rewards.max()))
        row = {"trial": t + 1, "reward_above_real": rewards_seen[2] / max(rewards_seen[1], 1)}
        rewards_seen[1:] = [0, 0]
        if t > 0:  # the model as it was before this trial, on this trial's real transitions
            one = [model_before.predict(states[k], actions[k])[0] for k in range(len(actions))]
            err = space.canonical(np.array(one) - states[1:])
            row["one_step_error"] = float(np.mean(np.abs(err) @ weights))
            x = states[0]
            for k in range(len(actions)):
                x = model_before.predict(x, actions[k])[0]
            row["open_loop_error"] = float(np.abs(space.canonical(x - states[-1])) @ weights)
            step = space.canonical(states[1:] - states[:-1])
            row["state_change"] = float(np.mean(np.abs(step) @ weights))
        for name in intervals:
            row[f"simulated_{name}"] = _simulated_fraction(_memory(agent, name), intervals[name])
        row["clipped"] = clipped[1] / max(clipped[0], 1)
        clipped[:] = [0, 0]
        if (t + 1) % every == 0:
            g_states, _, g_rewards = _trial(env, agent, learn=False)
            row["greedy_return"] = float(g_rewards.sum())
            row["greedy_discounted"] = float(np.sum(g_rewards * gamma ** np.arange(len(g_rewards))))
            row["value_x0"] = agent.value(g_states[0])
        rows.append(row)
    keys = sorted({k for r in rows for k in r if r[k] is not None})
    return {
        k: np.array([r.get(k, np.nan) if r.get(k) is not None else np.nan for r in rows])
        for k in keys
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiments", type=int, default=5)
    parser.add_argument("--trials", type=int, default=60)
    parser.add_argument("--every", type=int, default=5)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--set", action="append", default=[])
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    config = _merge(ARM_FASTEST, _nested(args.set))
    seeds = np.random.SeedSequence(args.seed).spawn(args.experiments)
    runs = [run(int(s.generate_state(1)[0]), args.trials, config, args.every) for s in seeds]
    keys = runs[0].keys()
    mean = {k: np.nanmean(np.array([r[k] for r in runs]), axis=0) for k in keys}
    print("config:", json.dumps(config))
    cols = [
        "greedy_return",
        "greedy_discounted",
        "value_x0",
        "one_step_error",
        "open_loop_error",
        "state_change",
        "simulated_critic",
        "simulated_reference",
        "clipped",
        "reward_above_real",
    ]
    print("trial " + " ".join(f"{c[:12]:>12}" for c in cols))
    for i in range(args.every - 1, args.trials, args.every):
        print(f"{i + 1:5d} " + " ".join(f"{mean[c][i]:12.3f}" for c in cols))
    stuck = [float(np.nanmean(r["greedy_return"][-10:])) for r in runs]
    print("last greedy returns per experiment:", " ".join(f"{s:.0f}" for s in stuck))
    if args.out:
        np.savez(args.out, **{f"exp{i}_{k}": v for i, r in enumerate(runs) for k, v in r.items()})


if __name__ == "__main__":
    main()

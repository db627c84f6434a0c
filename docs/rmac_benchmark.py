"""Microseconds per RMAC learner step and per LLR query + insert, next to one env.step.

    python docs/rmac_benchmark.py

The agent first learns for 30 trials so that its critic and reference memories are full (2000
samples) and its process memory too (100). Then trials are replayed: env.step and agent.step are
timed separately with time.perf_counter, and the median over all steps is reported.
"""

from __future__ import annotations

import time

import numpy as np

from rmac_mj import tasks
from rmac_mj.agents.rmac import RMAC, RMACConfig
from rmac_mj.approximators.llr import LLRMemory
from rmac_mj.experiments.episode import action_space_of, run_trial, state_of, state_space_of


def time_trials(env, agent, trials: int) -> tuple[np.ndarray, np.ndarray]:
    env_us, agent_us = [], []
    for _ in range(trials):
        ts = env.reset()
        u = agent.start(state_of(ts.observation))
        while True:
            t0 = time.perf_counter()
            ts = env.step(u)
            t1 = time.perf_counter()
            x = state_of(ts.observation)
            if ts.last():
                agent.stop(ts.reward, x)
                break
            t2 = time.perf_counter()
            u = agent.step(ts.reward, x)
            t3 = time.perf_counter()
            env_us.append(t1 - t0)
            agent_us.append(t3 - t2)
    return 1e6 * np.array(env_us), 1e6 * np.array(agent_us)


def time_llr(algorithm: str, repeats: int) -> float:
    rng = np.random.default_rng(0)
    memory = LLRMemory(2, 1, 2000, 20, input_weights=[1, 0.1], input_period=[2 * np.pi, 0],
                       clip=True, algorithm=algorithm)
    X = np.c_[rng.uniform(-np.pi, np.pi, 2000), rng.uniform(-60, 60, 2000)]
    memory.fit(X, rng.normal(size=(2000, 1)))
    queries = np.c_[rng.uniform(-np.pi, np.pi, repeats), rng.uniform(-60, 60, repeats)]
    y = np.array([1.0])
    memory.query(queries[0]), memory.insert(queries[0], y)  # compile
    times = []
    for x in queries:
        t0 = time.perf_counter()
        memory.query(x)
        memory.insert(x, y)
        times.append(time.perf_counter() - t0)
    return 1e6 * float(np.median(times))


def main() -> None:
    env = tasks.load("dc_pendulum", "swingup")
    S, U = state_space_of(env), action_space_of(env)
    for backend, trials in (("numba", 20), ("numpy", 2)):
        agent = RMAC(S, U, RMACConfig(backend=backend), seed=0)
        for _ in range(30 if backend == "numba" else 21):
            run_trial(env, agent)
        env_us, agent_us = time_trials(env, agent, trials)
        print(f"{backend:5s} memories {agent.critic.n_samples_}/{agent.reference.n_samples_}/"
              f"{agent.process.n_samples_}: env.step median {np.median(env_us):6.1f} us, "
              f"RMAC step (act + update) median {np.median(agent_us):7.1f} us "
              f"({np.median(agent_us) / np.median(env_us):.2f} x env.step)")
    for algorithm, repeats in (("numba", 5000), ("numpy", 300)):
        print(f"LLR query + insert on a full 2000-sample memory ({algorithm}): "
              f"{time_llr(algorithm, repeats):7.1f} us (median)")


if __name__ == "__main__":
    main()

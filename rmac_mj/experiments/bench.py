"""``rmac-mj bench``: where the microseconds of a control step go, as ratios to ``env.step``.

Everything is measured in one process, one figure after the other, as the median over repeats of the
mean time per call in a batch, after a warm-up (numba compilation included in the warm-up). Shared
machines are noisy, so the targets are ratios within one run, never absolute times:

    S-AC learner step  <= 1 x env.step        RMAC learner step <= 2 x env.step
    LLR query + insert <= 0.5 x env.step      full protocol (40 + 40 x 600 trials) <= 10 min wall
"""

from __future__ import annotations

import os
import platform
import time
from typing import Any, Callable

import mujoco
import numpy as np

from rmac_mj import tasks
from rmac_mj.agents import make_agent
from rmac_mj.approximators.llr import LLRMemory
from rmac_mj.experiments.episode import action_space_of, run_trial, state_of, state_space_of

#: Targets as ratios to env.step (learners, LLR) and minutes of wall time (protocol).
TARGETS = {"sac_step_us": 1.0, "rmac_step_us": 2.0, "llr_query_insert_us": 0.5,
           "protocol_projected_min": 10.0}
PAPER_EXPERIMENTS, PAPER_TRIALS = 40, 600


def _median_us(call: Callable[[int], None], calls: int, repeats: int) -> float:
    """Median over ``repeats`` of the mean microseconds per call of ``call(i)``, i in range(calls)."""
    call(0)  # warm-up
    samples = []
    for _ in range(repeats):
        start = time.perf_counter_ns()
        for i in range(calls):
            call(i)
        samples.append((time.perf_counter_ns() - start) / calls / 1e3)
    return float(np.median(samples))


def physics_step_us(calls: int, repeats: int) -> float:
    """One 0.03 s control step as raw ``mujoco.mj_step`` calls: the physics floor."""
    env = tasks.load("dc_pendulum", "swingup")
    model, data = env.physics.model.ptr, env.physics.data.ptr
    n_sub = round(0.03 / model.opt.timestep)
    rng = np.random.default_rng(0)
    voltages = rng.uniform(-3, 3, calls)

    def step(i):
        data.ctrl[0] = voltages[i]
        for _ in range(n_sub):
            mujoco.mj_step(model, data)
    return _median_us(step, calls, repeats)


def env_step_us(calls: int, repeats: int) -> float:
    """``env.step`` of dc_pendulum/swingup through dm-control (resets excluded)."""
    env = tasks.load("dc_pendulum", "swingup")
    rng = np.random.default_rng(0)
    actions = rng.uniform(-3, 3, (100, 1))
    samples = []
    env.reset()
    for repeat in range(repeats + 1):
        env.reset()
        start = time.perf_counter_ns()
        for k in range(99):
            env.step(actions[k])
        if repeat:  # the first pass is the warm-up
            samples.append((time.perf_counter_ns() - start) / 99 / 1e3)
    return float(np.median(samples))


def llr_query_insert_us(calls: int, repeats: int) -> float:
    """A query and an insertion on a full critic-like memory: N = 2000, K = 20, 2 inputs."""
    memory = LLRMemory(input_dim=2, output_dim=1, capacity=2000, n_neighbours=20,
                       input_weights=[1.0, 0.1], input_period=[2 * np.pi, 0.0])
    rng = np.random.default_rng(0)
    fill = np.column_stack([rng.uniform(-np.pi, np.pi, 2000), rng.uniform(-30, 30, 2000)])
    for x in fill:
        memory.insert(x, [-float(x @ x)])
    queries = np.column_stack([rng.uniform(-np.pi, np.pi, calls), rng.uniform(-30, 30, calls)])

    def query_insert(i):
        prediction, _, _ = memory.query(queries[i])
        memory.insert(queries[i], prediction)
    return _median_us(query_insert, calls, repeats)


def learner_step_us(algorithm: str, repeats: int, warmup_trials: int = 25) -> float:
    """One learner step (act + update) with full memories, the environment excluded.

    The agent first learns for ``warmup_trials`` trials (RMAC's 2000-sample memories are full after
    20); then the states and rewards of one more trial are replayed through ``agent.step``.
    """
    env = tasks.load("dc_pendulum", "swingup")
    agent = make_agent(algorithm, state_space_of(env), action_space_of(env), seed=0)
    for _ in range(warmup_trials):
        run_trial(env, agent, learn=True)
    transitions = []
    timestep = env.reset()
    u = agent.start(state_of(timestep.observation))
    while not timestep.last():
        timestep = env.step(u)
        x = state_of(timestep.observation)
        transitions.append((float(timestep.reward), x))
        u = agent.step(*transitions[-1])
    samples = []
    for _ in range(repeats):
        agent.start(transitions[0][1])
        start = time.perf_counter_ns()
        for reward, x in transitions:
            agent.step(reward, x)
        samples.append((time.perf_counter_ns() - start) / len(transitions) / 1e3)
    return float(np.median(samples))


def experiment_wall_s(algorithm: str, trials: int) -> float:
    """Wall time of one learning experiment of ``trials`` trials (environment included)."""
    env = tasks.load("dc_pendulum", "swingup")
    agent = make_agent(algorithm, state_space_of(env), action_space_of(env), seed=0)
    run_trial(env, agent, learn=True)  # compile outside the timing
    agent = make_agent(algorithm, state_space_of(env), action_space_of(env), seed=1)
    start = time.perf_counter()
    for _ in range(trials):
        run_trial(env, agent, learn=True)
    return time.perf_counter() - start


def _cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as handle:
            for line in handle:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def run(quick: bool = False, algorithms: tuple[str, ...] = ("s-ac", "rmac")) -> dict[str, Any]:
    """Measure everything; return the report (the keys of ``--json``)."""
    calls, repeats = (200, 5) if quick else (1000, 9)
    trials = 60 if quick else PAPER_TRIALS
    report: dict[str, Any] = {
        "physics_step_us": physics_step_us(calls, repeats),
        "env_step_us": env_step_us(calls, repeats),
        "llr_query_insert_us": llr_query_insert_us(calls, repeats),
        "sac_step_us": learner_step_us("s-ac", repeats),
        "rmac_step_us": learner_step_us("rmac", repeats),
    }
    walls = {name: experiment_wall_s(name, trials) * PAPER_TRIALS / trials for name in algorithms}
    cores = os.cpu_count() or 1
    report["experiment_wall_s"] = walls
    report["experiment_trials_measured"] = trials
    # Experiments are independent and run one per core; the projection assumes perfect scaling.
    report["protocol_projected_min"] = PAPER_EXPERIMENTS * sum(walls.values()) / cores / 60.0
    report["machine"] = {"cores": cores, "cpu": _cpu_name(), "python": platform.python_version()}
    return report


def format_table(report: dict[str, Any]) -> str:
    """The report as a table of microseconds, ratios to env.step and targets."""
    env = report["env_step_us"]
    rows = [("raw MuJoCo control step (3 x mj_step)", "physics_step_us"),
            ("env.step (dm-control)", "env_step_us"),
            ("LLR query + insert (N=2000, K=20)", "llr_query_insert_us"),
            ("S-AC learner step (act + update)", "sac_step_us"),
            ("RMAC learner step (act + update)", "rmac_step_us")]
    lines = [f"{'what':<40} {'us':>9} {'x env.step':>10} {'target':>8}", "-" * 71]
    for label, key in rows:
        value = report[key]
        target = TARGETS.get(key)
        verdict = "" if target is None else (f"<= {target:g} " + ("met" if value / env <= target
                                                                    else "MISSED"))
        lines.append(f"{label:<40} {value:>9.1f} {value / env:>10.2f} {verdict:>8}")
    lines.append("")
    measured = report.get("experiment_trials_measured", PAPER_TRIALS)
    for name, seconds in report["experiment_wall_s"].items():
        note = "" if measured == PAPER_TRIALS else f" (projected from {measured} trials)"
        lines.append(f"one experiment of {PAPER_TRIALS} trials, {name:<5} {seconds:>8.1f} s{note}")
    projected = report["protocol_projected_min"]
    verdict = "met" if projected <= TARGETS["protocol_projected_min"] else "MISSED"
    lines.append(f"full protocol (40 + 40 experiments) on {report['machine']['cores']} cores: "
                 f"{projected:.1f} min projected (target <= 10: {verdict})")
    lines.append(f"machine: {report['machine']['cpu']}, {report['machine']['cores']} cores")
    return "\n".join(lines)

"""``rmac-mj bench``: where the microseconds of a control step go, as ratios to ``env.step``.

Everything is measured in one process, one figure after the other, as the median over repeats of the
mean time per call in a batch, after a warm-up (numba compilation included in the warm-up). Shared
machines are noisy, so the targets are ratios within one run, never absolute times:

    S-AC learner step  <= 1 x env.step        RMAC learner step <= 2 x env.step
    LLR query + insert <= 0.5 x env.step      full protocol (40 + 40 x 600 trials) <= 10 min wall
"""

from __future__ import annotations

import math
import os
import platform
import time
from typing import Any, Callable

import mujoco
import numpy as np

from rmac_mj import tasks
from rmac_mj.agents import make_agent
from rmac_mj.approximators.llr import LLRMemory
from rmac_mj.experiments.episode import (action_space_of, learner_state_of, n_sub_steps, run_trial,
                                         state_of, state_space_of, steps_per_trial)

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


def check_task(domain: str, task: str) -> None:
    """ValueError naming the choices unless ``domain``/``task`` is a task of the suite."""
    tasks.load(domain, task)


def _random_actions(env, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` actions drawn uniformly from the action bounds; shape (count, m)."""
    space = action_space_of(env)
    return rng.uniform(space.low, space.high, (count, space.dim))


def physics_step_us(calls: int, repeats: int, domain: str = "dc_pendulum",
                    task: str = "swingup") -> float:
    """One control step of the task as raw ``mujoco.mj_step`` calls: the physics floor."""
    env = tasks.load(domain, task)
    model, data = env.physics.model.ptr, env.physics.data.ptr
    n_sub = n_sub_steps(env)
    controls = _random_actions(env, calls, np.random.default_rng(0))

    def step(i):
        data.ctrl[:] = controls[i]
        for _ in range(n_sub):
            mujoco.mj_step(model, data)
    return _median_us(step, calls, repeats)


def env_step_us(calls: int, repeats: int, domain: str = "dc_pendulum", task: str = "swingup") -> float:
    """``env.step`` of the task through dm-control (resets excluded)."""
    env = tasks.load(domain, task)
    steps = max(1, steps_per_trial(env) - 1)  # every step of a trial but the one that ends it
    actions = _random_actions(env, steps, np.random.default_rng(0))
    samples = []
    env.reset()
    for repeat in range(repeats + 1):
        env.reset()
        start = time.perf_counter_ns()
        for k in range(steps):
            env.step(actions[k])
        if repeat:  # the first pass is the warm-up
            samples.append((time.perf_counter_ns() - start) / steps / 1e3)
    return float(np.median(samples))


def llr_query_insert_us(calls: int, repeats: int, domain: str = "dc_pendulum",
                        task: str = "swingup") -> float:
    """A query and an insertion on a full critic-like memory (N = 2000, K = 20) over the task's state:
    its dimensions, weights and periods, filled uniformly over its box."""
    space = state_space_of(tasks.load(domain, task))
    memory = LLRMemory(input_dim=space.dim, output_dim=1, capacity=2000, n_neighbours=20,
                       input_weights=space.weights, input_period=space.period)
    rng = np.random.default_rng(0)
    fill = rng.uniform(space.low, space.high, (2000, space.dim))
    for x in fill:
        memory.insert(x, [-float(x @ x)])
    queries = rng.uniform(space.low, space.high, (calls, space.dim))

    def query_insert(i):
        prediction, _, _ = memory.query(queries[i])
        memory.insert(queries[i], prediction)
    return _median_us(query_insert, calls, repeats)


def learner_step_us(algorithm: str, repeats: int, warmup_trials: int | None = None,
                    domain: str = "dc_pendulum", task: str = "swingup") -> float:
    """One learner step (act + update) with full memories, the environment excluded.

    The agent first learns for ``warmup_trials`` trials (default: 2500 steps' worth, so that RMAC's
    2000-sample memories are full; 25 trials of dc_pendulum); then the states and rewards of one more
    trial are replayed through ``agent.step``.
    """
    env = tasks.load(domain, task)
    if warmup_trials is None:
        warmup_trials = math.ceil(2500 / steps_per_trial(env))
    agent = make_agent(algorithm, state_space_of(env), action_space_of(env), seed=0)
    for _ in range(warmup_trials):
        run_trial(env, agent, learn=True)
    learner_state = learner_state_of(env)
    transitions = []
    timestep = env.reset()
    u = agent.start(state_of(timestep.observation, learner_state))
    while not timestep.last():
        timestep = env.step(u)
        x = state_of(timestep.observation, learner_state)
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


def experiment_wall_s(algorithm: str, trials: int, domain: str = "dc_pendulum",
                      task: str = "swingup") -> float:
    """Wall time of one learning experiment of ``trials`` trials (environment included)."""
    env = tasks.load(domain, task)
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


def run(quick: bool = False, algorithms: tuple[str, ...] = ("s-ac", "rmac"),
        domain: str = "dc_pendulum", task: str = "swingup") -> dict[str, Any]:
    """Measure everything on ``domain``/``task``; return the report (the keys of ``--json``)."""
    calls, repeats = (200, 5) if quick else (1000, 9)
    trials = 60 if quick else PAPER_TRIALS
    on = {"domain": domain, "task": task}
    env = tasks.load(domain, task)
    report: dict[str, Any] = {
        **on,
        "control_timestep_s": env.control_timestep(),
        "n_sub_steps": n_sub_steps(env),
        "state_dim": state_space_of(env).dim,
        "physics_step_us": physics_step_us(calls, repeats, **on),
        "env_step_us": env_step_us(calls, repeats, **on),
        "llr_query_insert_us": llr_query_insert_us(calls, repeats, **on),
        "sac_step_us": learner_step_us("s-ac", repeats, **on),
        "rmac_step_us": learner_step_us("rmac", repeats, **on),
    }
    walls = {name: experiment_wall_s(name, trials, **on) * PAPER_TRIALS / trials
             for name in algorithms}
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
    rows = [(f"raw MuJoCo control step ({report.get('n_sub_steps', '?')} x mj_step)",
             "physics_step_us"),
            ("env.step (dm-control)", "env_step_us"),
            (f"LLR query + insert (N=2000, K=20, n={report.get('state_dim', '?')})",
             "llr_query_insert_us"),
            ("S-AC learner step (act + update)", "sac_step_us"),
            ("RMAC learner step (act + update)", "rmac_step_us")]
    lines = []
    if "domain" in report:
        lines.append(f"task {report['domain']}/{report['task']}: control step "
                     f"{report['control_timestep_s']:g} s of {report['n_sub_steps']} physics steps")
    lines += [f"{'what':<40} {'us':>9} {'x env.step':>10} {'target':>8}", "-" * 71]
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

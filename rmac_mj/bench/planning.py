"""``rmac-mj bench``'s planning and replay figures: CPU per rehearsed update and per minute.

CPU time of the measuring thread on a learner whose memories are full (every setting starts from the
same learned state, ``load_state_dict``): ``planning_update_us``/``replay_update_us`` per update,
and ``cpu_per_simulated_minute`` (environment included) at each number of steps per real step.
"""

from __future__ import annotations

import math
import time
from typing import Any

from rmac_mj import tasks
from rmac_mj.agents import make_agent
from rmac_mj.rollout import (
    action_space_of,
    run_trial,
    state_space_of,
    steps_per_trial,
    trial_seconds,
)

#: Planning and replay steps per real step at which the CPU per simulated minute is measured.
STEPS = (0, 5, 20, 100, 200)
KINDS = ("planning", "replay")


def _config(kind: str, steps: int) -> dict[str, Any]:
    return {kind: {"steps": steps}} if steps else {}


def _warm_state(algorithm: str, env) -> dict:
    """The state of a learner after 2500 steps' worth of trials with one planning and one replay
    step per real step (every memory, the model's and the stored trials included, filled)."""
    agent = make_agent(
        algorithm,
        state_space_of(env),
        action_space_of(env),
        seed=0,
        config={"planning": {"steps": 1}, "replay": {"steps": 1}},
    )
    for _ in range(math.ceil(2500 / steps_per_trial(env))):
        run_trial(env, agent, learn=True)
    return agent.state_dict()


def _agent_from(algorithm: str, env, state: dict, kind: str, steps: int):
    """A learner configured for ``steps`` of ``kind`` holding the warm state's memories: the parts
    of the state its configuration keeps (a learner without replay keeps no stored trials)."""
    agent = make_agent(
        algorithm, state_space_of(env), action_space_of(env), seed=1, config=_config(kind, steps)
    )
    own = agent.state_dict()
    agent.load_state_dict({key: value for key, value in state.items() if key in own})
    return agent


def rehearsal_costs(
    domain: str,
    task: str,
    algorithms: tuple[str, ...] = ("s-ac", "rmac", "mlac"),
    repeats: int = 5,
    trials: int = 2,
    steps: tuple[int, ...] = STEPS,
) -> dict[str, Any]:
    """Per learner on ``domain``/``task``: ``planning_update_us`` and ``replay_update_us`` (median
    over ``repeats`` rehearsals), and ``cpu_per_simulated_minute[kind][steps]`` (CPU s per simulated
    minute over ``trials`` real trials)."""
    env = tasks.load(domain, task)
    minutes_per_trial = trial_seconds(env) / 60.0
    report: dict[str, Any] = {}
    for name in algorithms:
        state = _warm_state(name, env)
        figures: dict[str, Any] = {"cpu_per_simulated_minute": {}}
        for kind in KINDS:
            agent = _agent_from(name, env, state, kind, 1)
            run_trial(
                env, agent, learn=True
            )  # a real trial to rehearse (and every kernel compiled)
            transitions = steps_per_trial(env)
            samples = []
            for _ in range(repeats):
                start = time.thread_time_ns()
                agent.rehearsal.after_trial(agent)
                samples.append((time.thread_time_ns() - start) / transitions / 1e3)
            figures[f"{kind}_update_us"] = sorted(samples)[len(samples) // 2]
            per_minute = {}
            for count in steps:
                agent = _agent_from(name, env, state, kind, count)
                start = time.thread_time_ns()
                for _ in range(trials):
                    run_trial(env, agent, learn=True)
                per_minute[count] = (
                    (time.thread_time_ns() - start) / 1e9 / (trials * minutes_per_trial)
                )
            figures["cpu_per_simulated_minute"][kind] = per_minute
        report[name] = figures
    return report


def format_lines(report: dict[str, Any], physics_step_us: float) -> list[str]:
    """The figures as text lines: the updates in us and x the raw control step, then the CPU per
    simulated minute against the steps per real step."""
    lines = []
    for name, figures in report.items():
        for kind in KINDS:
            value = figures[f"{kind}_update_us"]
            lines.append(
                f"{name} {kind} update (one {'simulated' if kind == 'planning' else 'stored'}"
                f" transition): {value:.1f} us = {value / physics_step_us:.2f} x raw"
            )
    steps = list(next(iter(report.values()))["cpu_per_simulated_minute"]["planning"])
    lines.append(
        "CPU s per simulated minute, by steps per real step: " + " / ".join(str(s) for s in steps)
    )
    for name, figures in report.items():
        for kind in KINDS:
            values = figures["cpu_per_simulated_minute"][kind]
            lines.append(f"  {name:<5} {kind:<9} " + " / ".join(f"{values[s]:.1f}" for s in steps))
    return lines


def format_markdown(report: dict[str, Any], physics_step_us: float) -> list[str]:
    """The figures as two Markdown tables: the updates, and the CPU per simulated minute."""
    lines = ["", "| rehearsed update (memories full) | us | x raw control step |", "|---|---|---|"]
    for name, figures in report.items():
        for kind in KINDS:
            value = figures[f"{kind}_update_us"]
            what = "simulated transition" if kind == "planning" else "stored transition, backwards"
            lines.append(
                f"| {name} {kind}: one {what} | {value:.1f} | {value / physics_step_us:.2f} |"
            )
    steps = list(next(iter(report.values()))["cpu_per_simulated_minute"]["planning"])
    lines += [
        "",
        "| CPU s per simulated minute | " + " | ".join(f"{s} steps" for s in steps) + " |",
        "|---|" + "---|" * len(steps),
    ]
    for name, figures in report.items():
        for kind in KINDS:
            values = figures["cpu_per_simulated_minute"][kind]
            lines.append(
                f"| {name} {kind} | " + " | ".join(f"{values[s]:.1f}" for s in steps) + " |"
            )
    return lines

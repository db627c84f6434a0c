"""The bench's measurements: a control step's parts and the learners' steps timed in process, and a
real run timed end to end.

The unit is the *raw control step*: one control step of the task as its ``mujoco.mj_step`` calls from
a Python loop, the least any implementation of the task must spend; for an outside environment
without a MuJoCo physics (Gymnasium's), its own ``step``. Every in-process figure is the median over
repeats of the mean time per call in a batch, after a warm-up (numba compilation included), in CPU
time of the measuring thread (``time.thread_time_ns``): on an idle core that is the wall time, and on
a shared, loaded machine it leaves out the time other processes hold the core. The raw step,
``env.step`` and the glue are measured interleaved, batch by batch, so that cache and frequency
effects reach all of them alike. The real run is timed both ways: wall clock, and the CPU time of its
processes.

The per-step overhead outside physics and learner is measured in two parts: ``env.step`` minus the
raw step (dm-control's ``Environment`` and the task), and the glue (``run_trial`` with an agent that
returns a constant action through the agents' checked boundary, minus the same episodes driven by
``env.step`` alone).
"""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from rmac_mj import tasks
from rmac_mj.agents import PolicyAgent, make_agent
from rmac_mj.approximators.llr import LLRMemory
from rmac_mj.rollout import (
    action_space_of,
    learner_state_of,
    n_sub_steps,
    run_trial,
    state_of,
    state_space_of,
    steps_per_trial,
)

#: The suite's default task, which the benchmark measures unless told otherwise.
_DOMAIN, _TASK = tasks.DEFAULT_TASK

#: The clock of every in-process figure: this thread's CPU time (see the module docstring).
_clock_ns = time.thread_time_ns


def _median_us(call: Callable[[int], None], calls: int, repeats: int) -> float:
    """Median over ``repeats`` of the mean microseconds per call of ``call(i)``, i in range(calls)."""
    call(0)  # warm-up
    samples = []
    for _ in range(repeats):
        start = _clock_ns()
        for i in range(calls):
            call(i)
        samples.append((_clock_ns() - start) / calls / 1e3)
    return float(np.median(samples))


def check_task(**where: Any) -> None:
    """ValueError naming the choices unless ``where`` is a task of the suite (``domain``/``task``)
    or an outside environment whose learner state is known (``env``, see
    :func:`measured_protocol`)."""
    measured_environment(**where)


def measured_protocol(
    domain: str = _DOMAIN,
    task: str = _TASK,
    env: str | None = None,
    learner_state: dict | None = None,
    action_repeat: int = 1,
):
    """What is measured, as a Protocol (the one place environments are built): a task of the suite
    (``domain``/``task``) or an outside environment (``env``, a SPEC, with its ``learner_state``
    declaration and ``action_repeat``, see ``rmac_mj.envs``)."""
    from rmac_mj.experiments.protocol import Protocol

    if env is not None:  # (domain/task other than the default are refused beside it)
        return Protocol(
            env=env,
            learner_state=learner_state,
            action_repeat=action_repeat,
            domain=domain,
            task=task,
        )
    return Protocol(domain=domain, task=task)


def measured_environment(**where):
    """A fresh environment of what is measured (see :func:`measured_protocol`)."""
    return measured_protocol(**where).make_environment(0)


def _raw_step(env, rng: np.random.Generator, calls: int) -> tuple[Callable[[], float], str]:
    """A batch of the environment's own steps, timed (us per step), and what it is called.

    For a MuJoCo physics (the suite, dm-control): ``n_sub_steps`` x ``mj_step`` from a Python loop.
    For an outside environment without one (Gymnasium's): its own ``step``, under everything this
    package adds (the dm_env adapter, the learner's x)."""
    controls = _random_actions(env, calls, rng)
    physics = getattr(env, "physics", None)
    if physics is not None:
        model, data = physics.model.ptr, physics.data.ptr
        n_sub = n_sub_steps(env)

        def raw_batch() -> float:
            start = _clock_ns()
            for i in range(calls):
                data.ctrl[:] = controls[i]
                for _ in range(n_sub):
                    mujoco.mj_step(model, data)
            return (_clock_ns() - start) / calls / 1e3

        return raw_batch, f"raw MuJoCo control step ({n_sub} x mj_step)"
    own = env.base.env  # a Gymnasium environment (rmac_mj.envs.GymnasiumEnvironment.env)
    space = own.action_space
    actions = controls.astype(space.dtype).reshape((calls,) + space.shape)

    def own_batch() -> float:
        elapsed = 0
        own.reset(seed=0)
        for i in range(calls):
            start = _clock_ns()
            _, _, terminated, truncated, _ = own.step(actions[i])
            elapsed += _clock_ns() - start
            if terminated or truncated:
                own.reset()
        return elapsed / calls / 1e3

    return own_batch, "the environment's own step (Gymnasium)"


def _random_actions(env, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` actions drawn uniformly from the action bounds; shape (count, m)."""
    space = action_space_of(env)
    return rng.uniform(space.low, space.high, (count, space.dim))


def _episode_batches(env, rng: np.random.Generator, calls: int) -> tuple[Callable[[], float], ...]:
    """Three timed batches of about ``calls`` steps of ``env`` (us per step): ``env.step`` with
    random actions (resets excluded); episodes through ``run_trial`` with a constant-action agent;
    the same episodes through ``env.reset`` and ``env.step`` alone."""
    per_trial = steps_per_trial(env)
    episodes = max(1, round(calls / per_trial))
    actions = _random_actions(env, per_trial, rng)

    def env_batch() -> float:
        elapsed = 0
        for _ in range(episodes):
            env.reset()
            start = _clock_ns()
            for k in range(per_trial):
                env.step(actions[k])
            elapsed += _clock_ns() - start
        return elapsed / (episodes * per_trial) / 1e3

    constant = np.full(action_space_of(env).dim, 0.5)
    # What run_trial costs around a learner: an agent that learns nothing and always applies the same
    # action, every call still going through the agents' checked boundary.
    agent = PolicyAgent(state_space_of(env), action_space_of(env), lambda x: constant)

    def trial_batch() -> float:
        start = _clock_ns()
        for _ in range(episodes):
            run_trial(env, agent, learn=True)
        return (_clock_ns() - start) / (episodes * per_trial) / 1e3

    def episode_batch() -> float:
        start = _clock_ns()
        for _ in range(episodes):
            timestep = env.reset()
            while not timestep.last():
                timestep = env.step(constant)
        return (_clock_ns() - start) / (episodes * per_trial) / 1e3

    return env_batch, trial_batch, episode_batch


def step_costs(calls: int, repeats: int, **where: Any) -> dict[str, Any]:
    """The raw control step, ``env.step`` and the glue per step (us), measured interleaved.

    Each repeat times, one after the other: ``calls`` raw control steps (``n_sub_steps`` x
    ``mj_step`` with a random action); about ``calls`` ``env.step`` calls with random actions
    (resets excluded); and
    the same number of episodes once through ``run_trial`` with a constant-action agent and once
    through ``env.reset`` and ``env.step`` alone. Returns medians over the repeats:
    ``physics_step_us``, ``env_step_us`` and ``glue_step_us`` (the median of the per-repeat
    difference between the two episode loops, per step), and ``raw_step`` (what the raw step is,
    see :func:`_raw_step`). ``where``: see :func:`measured_protocol`.
    """
    physics_env = measured_environment(**where)
    physics_env.reset()
    rng = np.random.default_rng(0)
    raw_batch, raw_label = _raw_step(physics_env, rng, calls)

    env_batch, trial_batch, episode_batch = _episode_batches(
        measured_environment(**where), rng, calls
    )
    for batch in (raw_batch, env_batch, trial_batch, episode_batch):  # warm-up
        batch()
    raw, env_step, glue = [], [], []
    for _ in range(repeats):
        raw.append(raw_batch())
        env_step.append(env_batch())
        glue.append(trial_batch() - episode_batch())
    return {
        "physics_step_us": float(np.median(raw)),
        "env_step_us": float(np.median(env_step)),
        "glue_step_us": float(np.median(glue)),
        "raw_step": raw_label,
    }


def physics_step_us(calls: int, repeats: int, **where: Any) -> float:
    """The raw control step of the task alone (see :func:`step_costs`)."""
    return step_costs(calls, repeats, **where)["physics_step_us"]


def env_step_us(calls: int, repeats: int, **where: Any) -> float:
    """``env.step`` of the task alone (see :func:`step_costs`)."""
    return step_costs(calls, repeats, **where)["env_step_us"]


def llr_query_insert_us(calls: int, repeats: int, **where: Any) -> float:
    """A query and an insertion on a full critic-like memory (N = 2000, K = 20) over the task's state:
    its dimensions, weights and periods, filled uniformly over its box."""
    space = state_space_of(measured_environment(**where))
    memory = LLRMemory(
        input_dim=space.dim,
        output_dim=1,
        capacity=2000,
        n_neighbours=20,
        input_weights=space.input_weights,
        input_period=space.period,
    )
    rng = np.random.default_rng(0)
    fill = rng.uniform(space.low, space.high, (2000, space.dim))
    for x in fill:
        memory.insert(x, [-float(x @ x)])
    queries = rng.uniform(space.low, space.high, (calls, space.dim))

    def query_insert(i):
        prediction, _, _ = memory.query(queries[i])
        memory.insert(queries[i], prediction)

    return _median_us(query_insert, calls, repeats)


def learner_step_us(
    algorithm: str, repeats: int, warmup_trials: int | None = None, **where: Any
) -> float:
    """One learner step (act + update) with full memories, the environment excluded.

    The agent first learns for ``warmup_trials`` trials (default: 2500 steps' worth, so that RMAC's
    2000-sample memories are full; 25 trials of the pendulum); then the states and rewards of one more
    trial are replayed through ``agent.step``.
    """
    env = measured_environment(**where)
    if warmup_trials is None:
        warmup_trials = math.ceil(2500 / steps_per_trial(env))
    agent = _timing_agent(algorithm, env, seed=0)
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
        start = _clock_ns()
        for reward, x in transitions:
            agent.step(reward, x)
        samples.append((_clock_ns() - start) / len(transitions) / 1e3)
    return float(np.median(samples))


def _timing_agent(algorithm: str, env, seed: int):
    """``algorithm`` with its defaults on ``env``; where the environment does not declare the
    reward's action cost (an outside one) and the learner needs it (MLAC), with 0, which costs the
    same time."""
    space = action_space_of(env)
    config = {"action_cost": 0.0} if (space.cost is None and algorithm == "mlac") else None
    return make_agent(algorithm, state_space_of(env), space, config=config, seed=seed)


def experiment_s(algorithm: str, trials: int, **where: Any) -> float:
    """Seconds of one learning experiment of ``trials`` trials (environment included), in CPU time
    of this thread (its wall time on an idle core)."""
    env = measured_environment(**where)
    agent = _timing_agent(algorithm, env, seed=0)
    run_trial(env, agent, learn=True)  # compile outside the timing
    agent = _timing_agent(algorithm, env, seed=1)
    start = _clock_ns()
    for _ in range(trials):
        run_trial(env, agent, learn=True)
    return (_clock_ns() - start) / 1e9


def _process_cpu_s() -> float | None:
    """CPU seconds (user + system) of this process and of its finished, waited-for children."""
    try:
        import resource
    except ImportError:  # not on Unix: only wall time is reported
        return None
    return sum(
        u.ru_utime + u.ru_stime
        for u in (
            resource.getrusage(resource.RUSAGE_SELF),
            resource.getrusage(resource.RUSAGE_CHILDREN),
        )
    )


def real_run(
    experiments: int, trials: int, jobs: int, physics_step_us: float, **where: Any
) -> dict[str, Any]:
    """Run ``run_protocol`` (both learners, ``experiments`` x ``trials`` each, on ``jobs`` worker
    processes, into a temporary directory, no figures) and time it end to end.

    Returns the steps it ran and the raw physics time of those steps per worker
    (``steps x physics_step_us / workers``), with, as multiples of it:
      - ``wall_s``: the measured wall time of ``run_protocol``, worker start-up and writing included;
      - ``cpu_s``: the CPU time of the driver and the workers, divided by the workers: the wall time
        the run takes on idle cores (None where ``resource`` is missing);
      - ``in_experiments_s``: the time the workers spent inside experiments (per worker), so that
        ``wall_s - in_experiments_s`` is what starting workers, importing and writing cost.
    """
    import dataclasses

    from rmac_mj.experiments import RunOptions, run_protocol

    protocol = dataclasses.replace(
        measured_protocol(**where), experiments=experiments, trials=trials
    )
    steps = (
        experiments
        * len(protocol.algorithms)
        * trials
        * steps_per_trial(protocol.make_environment(0))
    )
    workers = min(jobs, experiments * len(protocol.algorithms))
    with tempfile.TemporaryDirectory(prefix="rmac-mj-bench-") as out:
        cpu_before = _process_cpu_s()
        start = time.perf_counter()
        summary = run_protocol(protocol, out, RunOptions(jobs=jobs, progress=False, figures=False))
        wall = time.perf_counter() - start
        cpu_after = _process_cpu_s()
    cpu = None if cpu_before is None else (cpu_after - cpu_before) / workers
    in_experiments = (
        sum(summary[name]["experiment_wall_s_mean"] * experiments for name in protocol.algorithms)
        / workers
    )
    physics = steps * physics_step_us * 1e-6 / workers
    return {
        "experiments_per_learner": experiments,
        "trials": trials,
        "workers": workers,
        "steps": steps,
        "physics_s": physics,
        "wall_s": wall,
        "x_physics": wall / physics,
        "cpu_s": cpu,
        "cpu_x_physics": None if cpu is None else cpu / physics,
        "in_experiments_s": in_experiments,
        "in_experiments_x_physics": in_experiments / physics,
    }

"""The trial loop: one trial of an agent on a dm_env environment (:func:`run_trial`).

x is the concatenation of the observation entries ``learner_state.keys``
(:class:`rmac_mj.tasks.common.LearnerStateSpec`); the trial length is the environment's number of
control steps times its control timestep.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from dm_control.rl import control

from rmac_mj.agents import ActionSpace, Agent, StateSpace
from rmac_mj.agents.base import RefusedTransition
from rmac_mj.errors import EnvironmentFailure
from rmac_mj.tasks.common import LearnerStateSpec


def learner_state_of(env: control.Environment) -> LearnerStateSpec:
    """The description of the learners' state: the task's (``env.task.learner_state``, the suite) or
    the environment's own (an outside environment adapted by :mod:`rmac_mj.envs`)."""
    learner_state = getattr(env, "learner_state", None)
    if learner_state is None:
        learner_state = getattr(getattr(env, "task", None), "learner_state", None)
    if not isinstance(learner_state, LearnerStateSpec):
        owner = type(getattr(env, "task", env)).__name__
        raise ValueError(
            f"{owner} declares no learner_state (a rmac_mj.tasks.common.LearnerStateSpec; "
            f"an outside environment gets one through rmac_mj.envs.load), got "
            f"{learner_state!r}"
        )
    return learner_state


def state_of(observation, learner_state: LearnerStateSpec | Sequence[str]) -> np.ndarray:
    """x: the observation entries of ``learner_state.keys`` (or of a sequence of keys) concatenated;
    ndarray of shape (n,)."""
    keys = learner_state.keys if isinstance(learner_state, LearnerStateSpec) else learner_state
    # One numpy call (axis=None flattens each entry, dtype=float converts): once per control step.
    return np.concatenate([observation[key] for key in keys], axis=None, dtype=float)


def state_space_of(env: control.Environment) -> StateSpace:
    """The task's nominal state box, periodic dimensions, state weightings, state cost, control step
    and reward scale as a StateSpace."""
    learner_state = learner_state_of(env)
    return StateSpace(
        low=learner_state.low,
        high=learner_state.high,
        periodic=learner_state.periodic,
        input_weights=learner_state.input_weights,
        cost=learner_state.state_cost,
        timestep=float(env.control_timestep()),
        reward_scale=learner_state.reward_scale,
    )


def action_space_of(env: control.Environment) -> ActionSpace:
    """The bounded action spec, with the task's action weightings and action cost, as an
    :class:`ActionSpace`."""
    spec = env.action_spec()
    low = np.broadcast_to(spec.minimum, spec.shape)
    learner_state = learner_state_of(env)
    weights = learner_state.action_input_weights
    if len(weights) != low.size:
        raise ValueError(
            f"task {type(env.task).__name__}: learner_state.action_input_weights has "
            f"{len(weights)} entries, the action spec {low.size}"
        )
    return ActionSpace(
        low=low,
        high=np.broadcast_to(spec.maximum, spec.shape),
        input_weights=weights,
        cost=learner_state.action_cost,
    )


def steps_per_trial(env: control.Environment) -> int:
    """Control steps of one episode of ``env`` (dm-control ends it once ``step_count >= limit``).

    dm-control keeps the step limit (time limit / control timestep) private; it is read here, the one
    place that does, rather than running an episode, which would draw from the task's random state.
    An environment adapted by :mod:`rmac_mj.envs` says it (``steps_per_trial``).
    """
    own = getattr(env, "steps_per_trial", None)
    if isinstance(own, int):
        return own
    limit = getattr(env, "_step_limit", None)
    if limit is None or not math.isfinite(limit) or limit <= 0:
        raise ValueError(
            f"the environment must have a finite time limit (trials end on it), got a "
            f"step limit of {limit!r}"
        )
    return int(math.ceil(limit))


def trial_seconds(env: control.Environment) -> float:
    """Simulated seconds of one trial: steps per trial times the control timestep."""
    return steps_per_trial(env) * env.control_timestep()


def env_step_seconds(env: control.Environment) -> float:
    """Simulated seconds of one environment step: the control timestep, less an action repeat."""
    return env.control_timestep() / getattr(env, "action_repeat", 1)


def n_sub_steps(env: control.Environment) -> int:
    """Physics steps per control step."""
    return int(round(env.control_timestep() / env.physics.timestep()))


def run_trial(
    env: control.Environment,
    agent: Agent,
    learn: bool = True,
    on_step: Callable[[control.Environment, np.ndarray, float], None] | None = None,
) -> float:
    """Run one episode; return the sum of rewards.

    With ``learn=True`` the agent follows its online protocol (``start``/``step``/``stop``: Algorithm
    1 or 2 with exploration); with ``learn=False`` it acts greedily (``greedy_action``) and nothing is
    learned, which is how a learned policy is evaluated. ``on_step(env, u, r)`` is called after every
    step (e.g. to record frames).
    """
    return run_counted_trial(env, agent, learn, on_step)[0]


def _name(env: control.Environment) -> str:
    """The environment as messages name it: an outside one's SPEC, a suite task's class."""
    return getattr(env, "name", None) or type(getattr(env, "task", env)).__name__


def env_steps_taken(env: control.Environment) -> int | None:
    """Base environment steps ``env`` has taken so far, where it counts them (an outside environment
    adapted by :mod:`rmac_mj.envs`, whose action repeat makes them differ from control steps); None
    for the suite's tasks, whose control steps are their environment steps."""
    counted = getattr(env, "base_steps", None)
    return counted if isinstance(counted, int) else None


def run_counted_trial(
    env: control.Environment,
    agent: Agent,
    learn: bool = True,
    on_step: Callable[[control.Environment, np.ndarray, float], None] | None = None,
) -> tuple[float, int]:
    """:func:`run_trial`, also returning the environment steps the episode took (control steps
    times the action repeat, less where the environment ended it mid-repeat). A learner's refusal
    of a transition whose learning overflows its arithmetic (the environment's reward of 1e308) is
    the environment's failure."""
    try:
        return _counted_trial(env, agent, learn, on_step)
    except RefusedTransition as refused:
        raise EnvironmentFailure(
            f"env {_name(env)!r}: its rewards are beyond what a learner can take: {refused}"
        ) from refused


def _counted_trial(
    env: control.Environment,
    agent: Agent,
    learn: bool,
    on_step: Callable[[control.Environment, np.ndarray, float], None] | None,
) -> tuple[float, int]:
    keys = learner_state_of(env).keys
    before = env_steps_taken(env)
    timestep = env.reset()
    x = state_of(timestep.observation, keys)
    if not learn:
        agent.begin_greedy_trial()
    u = agent.start(x) if learn else agent.greedy_action(x)
    total, steps = 0.0, 0
    while True:
        timestep = env.step(u)
        steps += 1
        reward = float(timestep.reward)
        total += reward
        if on_step is not None:
            on_step(env, u, reward)
        x = state_of(timestep.observation, keys)
        if timestep.last():
            if not math.isfinite(total):  # finite rewards whose sum is not: the environment's
                raise EnvironmentFailure(
                    f"env {_name(env)!r}: its rewards over a trial of {steps} steps sum to "
                    f"{total} (the last {reward!r}): no return can be recorded"
                )
            if learn:  # a termination (discount 0) is a terminal state; a time limit is not
                agent.stop(reward, x, terminal=timestep.discount == 0.0)
            after = env_steps_taken(env)
            return total, (steps if before is None or after is None else after - before)
        u = agent.step(reward, x) if learn else agent.greedy_action(x)

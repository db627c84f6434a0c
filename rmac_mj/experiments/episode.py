"""One trial of an agent on a dm-control environment: the glue between tasks and agents.

Agents see a flat state ``x``; tasks give an observation dict. The state is the concatenation of the
observation entries named in ``STATE_KEYS`` (for ``dc_pendulum``: x = [phi, phi_dot], phi wrapped),
and its box comes from the task's ``state_bounds`` when it has them.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np
from dm_control.rl import control

from rmac_mj.agents.base import ActionSpace, Agent, StateSpace

#: Observation entries that make up the learners' state, in order.
STATE_KEYS: tuple[str, ...] = ("angle", "velocity")


def state_of(observation, keys: Sequence[str] = STATE_KEYS) -> np.ndarray:
    """x: the named observation entries concatenated; ndarray of shape (n,)."""
    # One numpy call (axis=None flattens each entry, dtype=float converts): once per control step.
    return np.concatenate([observation[key] for key in keys], axis=None, dtype=float)


def state_space_of(env: control.Environment) -> StateSpace:
    """The task's nominal state box (``task.state_bounds``)."""
    bounds = getattr(env.task, "state_bounds", None)
    if bounds is None:
        raise ValueError(f"task {type(env.task).__name__} declares no state_bounds; "
                         "give the agent a StateSpace explicitly")
    low, high, periodic = bounds
    return StateSpace(low=low, high=high, periodic=periodic)


def action_space_of(env: control.Environment) -> ActionSpace:
    """The bounded action spec as an :class:`ActionSpace`."""
    spec = env.action_spec()
    return ActionSpace(low=np.broadcast_to(spec.minimum, spec.shape),
                       high=np.broadcast_to(spec.maximum, spec.shape))


def run_trial(env: control.Environment, agent: Agent, learn: bool = True,
              on_step: Callable[[control.Environment, np.ndarray, float], None] | None = None) -> float:
    """Run one episode; return the sum of rewards.

    With ``learn=True`` the agent follows its online protocol (``start``/``step``/``stop``: Algorithm
    1 or 2 with exploration); with ``learn=False`` it acts greedily (``greedy_action``) and nothing is
    learned, which is how a learned policy is evaluated. ``on_step(env, u, r)`` is called after every
    step (e.g. to record frames).
    """
    timestep = env.reset()
    x = state_of(timestep.observation)
    if not learn:
        agent.begin_greedy_trial()
    u = agent.start(x) if learn else agent.greedy_action(x)
    total = 0.0
    while True:
        timestep = env.step(u)
        reward = float(timestep.reward)
        total += reward
        if on_step is not None:
            on_step(env, u, reward)
        x = state_of(timestep.observation)
        if timestep.last():
            if learn:
                agent.stop(reward, x)
            return total
        u = agent.step(reward, x) if learn else agent.greedy_action(x)

"""Any environment for the learners: dm-control's suite, Gymnasium, or a factory of the user's.

``envs.load("gymnasium:Pendulum-v1", seed=0)`` (or ``dm_control:DOMAIN/TASK``, ``module:factory``)
returns an :class:`Environment` the trial loop drives like a suite task; what the specs leave open
of x comes from ``learner_state``, else is refused in one line.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rmac_mj.envs.environment import Environment
from rmac_mj.envs.observation_map import ObservationMap
from rmac_mj.envs.observations import infer_learner_state
from rmac_mj.envs.spec import EnvSpec, parse
from rmac_mj.tasks.common import LearnerStateSpec


def load(
    env: str,
    kwargs: Mapping[str, Any] | None = None,
    *,
    seed: int | None = None,
    learner_state: LearnerStateSpec | Mapping[str, Any] | None = None,
    action_repeat: int = 1,
    trial_steps: int | None = None,
    control_timestep: float | None = None,
    render: bool = False,
) -> Environment:
    """The environment named by the SPEC ``env``, seeded, as the learners see it.

    Arguments as the fields of :class:`EnvSpec`; ``seed`` seeds the environment's starts;
    ``render``: able to draw its frames (a Gymnasium environment is made with
    ``render_mode="rgb_array"``; a factory gets it if it takes ``render_mode``).
    """
    spec = EnvSpec(
        env,
        kwargs=kwargs or {},
        learner_state=learner_state,
        action_repeat=action_repeat,
        trial_steps=trial_steps,
        control_timestep=control_timestep,
    )
    return spec.make(seed, render=render)


def hint_for(domain: str) -> str:
    """Where a domain the suite does not have may be found outside it, as the end of a message
    (dm-control's ``pendulum``: ``"; dm-control has it: env dm_control:pendulum/swingup (...)"``)."""
    from dm_control import suite

    if not isinstance(domain, str) or domain not in suite.TASKS_BY_DOMAIN:
        return ""
    names = suite.TASKS_BY_DOMAIN[domain]
    return (
        f"; dm-control has {domain!r}, an outside environment: env dm_control:{domain}/"
        f"{names[0]} (its tasks: {', '.join(names)})"
    )


__all__ = [
    "EnvSpec",
    "Environment",
    "LearnerStateSpec",
    "ObservationMap",
    "infer_learner_state",
    "hint_for",
    "load",
    "parse",
]

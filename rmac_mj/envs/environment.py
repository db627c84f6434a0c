"""What the trial loop drives: any dm_env environment, its observation mapped to the learner's x.

:class:`Environment` wraps a ``dm_env.Environment`` and gives :func:`rmac_mj.rollout.run_trial` what
a suite task does: entries ``learner_state.keys``, the learner state, the trial length, and
``action_repeat`` (rewards summed).
"""

from __future__ import annotations

import math
from typing import Any

import dm_env
import numpy as np
from dm_env import specs

from rmac_mj.agents.spaces import STATE_LIMIT_WIDTHS, StateSpace
from rmac_mj.envs.failures import checked_reward, outside, read_observation
from rmac_mj.envs.observation_map import ObservationLayout, ObservationMap
from rmac_mj.errors import EnvironmentFailure, UserInputError
from rmac_mj.tasks.common import LearnerStateSpec


class Environment(dm_env.Environment):
    """``base`` seen by a learner.

    Args:
      base: the environment, a ``dm_env.Environment``.
      learner_state: what x is (its ``keys`` are entries over ``layout``, see
        :mod:`rmac_mj.envs.observation_map`).
      layout: the base's raw observation layout.
      base_timestep: seconds per step of ``base``.
      steps_per_trial: steps (of this environment, i.e. after the action repeat) after which a
        trial is truncated, or ends earlier when the base ends it.
      action_repeat: base steps per step, each with the same action; rewards are summed.
      name: the environment's SPEC, for messages and figures.

    Attributes:
      learner_state, steps_per_trial, action_repeat, name: as given.
      base: the wrapped environment.
      map: the :class:`~rmac_mj.envs.observation_map.ObservationMap` from raw observations to x.
      base_steps: base steps taken since it was made (an episode ended by the base mid-repeat
        counts the steps it really took): the interaction a budget in environment steps counts.
    """

    def __init__(
        self,
        base: dm_env.Environment,
        learner_state: LearnerStateSpec,
        layout: ObservationLayout,
        base_timestep: float,
        steps_per_trial: int,
        action_repeat: int = 1,
        name: str = "",
    ) -> None:
        self.base = base
        self.learner_state = learner_state
        self.map = ObservationMap(learner_state.keys, layout)
        if self.map.dim != len(learner_state.low):
            raise ValueError(
                f"{name}: learner_state.keys give {self.map.dim} dimensions, its low "
                f"and high {len(learner_state.low)}"
            )
        action = base.action_spec()
        m = int(np.prod(action.shape, dtype=int))
        if len(learner_state.action_input_weights) != m:
            raise ValueError(
                f"{name}: learner_state.action_input_weights has "
                f"{len(learner_state.action_input_weights)} entries, the action {m}"
            )
        self._action_spec = specs.BoundedArray(
            shape=(m,),
            dtype=float,
            name="action",
            minimum=np.broadcast_to(action.minimum, action.shape).reshape(m).astype(float),
            maximum=np.broadcast_to(action.maximum, action.shape).reshape(m).astype(float),
        )
        self._base_shape = action.shape
        self._raw_size = sum(layout.sizes.values())
        # What a learner accepts (finite, within its limit around the box): refused here, in the
        # environment's name, before a learner sees it.
        self._accepted = StateSpace(learner_state.low, learner_state.high, learner_state.periodic)
        self.base_timestep = float(base_timestep)
        self.steps_per_trial = int(steps_per_trial)
        self.action_repeat = int(action_repeat)
        self.name = name
        self._step = 0
        self.base_steps = 0

    # ------------------------------------------------------------------------------ dm_env interface
    def reset(self) -> dm_env.TimeStep:
        self._step = 0
        with outside(self.name, "reset"):
            timestep = self.base.reset()
        return timestep._replace(observation=self._entries(timestep.observation, "reset"))

    def step(self, action: Any) -> dm_env.TimeStep:
        """Apply ``action`` for ``action_repeat`` base steps; the reward is their sum, the discount
        their product (0 once the base terminates)."""
        action = np.asarray(action, dtype=float).reshape(self._base_shape)
        reward, discount = 0.0, 1.0
        for _ in range(self.action_repeat):
            with outside(self.name, "step"):
                timestep = self.base.step(action)
                last = timestep.last()
                discount *= 1.0 if timestep.discount is None else float(timestep.discount)
            self.base_steps += 1
            reward += checked_reward(self.name, "step", timestep.reward)
            if last:
                break
        if not math.isfinite(reward):  # each finite, their sum not (1e308 and 1e308)
            raise EnvironmentFailure(
                f"env {self.name!r}: its rewards over an action repeat of {self.action_repeat} "
                f"sum to {reward}, each {timestep.reward!r} or so: no learner can take them"
            )
        self._step += 1
        observation = self._entries(timestep.observation, "step")
        if timestep.last() or self._step >= self.steps_per_trial:
            return dm_env.TimeStep(dm_env.StepType.LAST, reward, discount, observation)
        return dm_env.TimeStep(dm_env.StepType.MID, reward, discount, observation)

    def _entries(self, observation: Any, phase: str) -> dict[str, np.ndarray]:
        """The learner's entries of the raw ``observation`` that ``phase`` gave;
        :class:`EnvironmentFailure` when it is not numbers of its spec's size, or not a state a
        learner accepts (non-finite, or beyond :data:`STATE_LIMIT_WIDTHS` box widths)."""
        flat = read_observation(self.name, phase, self.map.flat, observation, self._raw_size)
        x = self.map.state_of_flat(flat)
        values = x.tolist()
        if not self._accepted.accepts(values):
            low, high = self._accepted.limit
            i = int(np.argmax((x < low) | (x > high)))
            label = self.learner_state.labels[i]
            named = f"x[{i}]" if label == f"x[{i}]" else f"x[{i}] ({label})"
            raise EnvironmentFailure(
                f"env {self.name!r}: its {phase} gave {named} = {values[i]:g}, beyond what a "
                f"learner accepts, [{low[i]:g}, {high[i]:g}] ({STATE_LIMIT_WIDTHS:g} widths of "
                f"the state box around it)"
            )
        return self.map.split(x)

    def observation_spec(self) -> dict[str, specs.Array]:
        sizes = [e.size for e in self.map.entries_]
        return {
            name: specs.Array(shape=(size,), dtype=float, name=name)
            for name, size in zip(self.map.names, sizes)
        }

    def action_spec(self) -> specs.BoundedArray:
        return self._action_spec

    def close(self) -> None:
        self.base.close()

    # ----------------------------------------------------------------------------------- time
    def control_timestep(self) -> float:
        """Seconds per step: the base's step times the action repeat."""
        return self.base_timestep * self.action_repeat

    @property
    def trial_seconds(self) -> float:
        """Simulated seconds of a trial that runs to its limit."""
        return self.steps_per_trial * self.control_timestep()

    @property
    def physics(self) -> Any:
        """The base's MuJoCo physics, where it has one (dm-control); AttributeError otherwise."""
        physics = getattr(self.base, "physics", None)
        if physics is None:
            raise AttributeError(f"{self.name or type(self.base).__name__} has no physics")
        return physics

    def observation_at(self, physics: Any) -> dict[str, np.ndarray]:
        """The observation (learner entries) a dm-control base would give in ``physics``, e.g. a
        scratch copy stepped to draw the frames between two control steps."""
        return self.map.entries(self.base.task.get_observation(physics))

    def render_frame(self, width: int = 320, height: int = 240) -> np.ndarray:
        """The current picture, uint8 of shape (H, W, 3): a MuJoCo physics' from its first camera
        at ``width`` x ``height``; a Gymnasium environment's own ``render()`` (its size; made with
        ``render_mode="rgb_array"``, see ``envs.load(..., render=True)``)."""
        physics = getattr(self.base, "physics", None)
        if physics is not None:
            return physics.render(height, width, camera_id=0 if physics.model.ncam > 0 else -1)
        gymnasium_env = getattr(self.base, "env", None)
        if gymnasium_env is None:
            raise UserInputError(
                f"{self.name}: a dm_env without a MuJoCo physics cannot be rendered"
            )
        if gymnasium_env.render_mode != "rgb_array":
            raise UserInputError(
                f"{self.name} cannot be rendered: it was made without render_mode='rgb_array'. A "
                "factory is asked for frames through a render_mode argument: take it, pass it to "
                "the environment and let its render() return an RGB array (in Python: "
                "envs.load(SPEC, render=True))"
            )
        try:
            frame = gymnasium_env.render()
        except Exception as error:  # e.g. gymnasium's DependencyNotInstalled (pygame)
            raise UserInputError(f"{self.name} cannot render: {error}") from None
        return np.asarray(frame, dtype=np.uint8)

    def __repr__(self) -> str:
        return (
            f"Environment({self.name!r}, x=[{', '.join(self.learner_state.keys)}], "
            f"{self.steps_per_trial} steps of {self.control_timestep():g} s)"
        )


def trial_steps(base_steps: int, action_repeat: int) -> int:
    """Steps of a trial of ``base_steps`` base steps under ``action_repeat`` (the last may be short)."""
    return int(math.ceil(base_steps / action_repeat))

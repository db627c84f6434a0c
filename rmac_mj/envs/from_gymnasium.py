"""A Gymnasium environment seen through dm_env, the interface of the suite and of the trial loop.

``terminated`` becomes a termination (discount 0), ``truncated`` a truncation (discount 1, the
learner bootstraps); the first ``reset`` passes the seed and later ones continue the environment's
stream.
"""

from __future__ import annotations

from typing import Any

import dm_env
import numpy as np
from dm_env import specs

from rmac_mj.envs.failures import checked_reward
from rmac_mj.envs.observation_map import OBSERVATION, layout_of_gymnasium
from rmac_mj.tasks.common import box_problem


class GymnasiumEnvironment(dm_env.Environment):
    """``env`` (a ``gymnasium.Env`` with a bounded Box action space) as a ``dm_env.Environment``.

    Observations are a dict: ``{"observation": obs}`` for a Box space, the space's own dict for a
    Dict space. Actions are float arrays of shape (m,), cast to the space's dtype.

    Attributes:
      env: the Gymnasium environment (with its wrappers, e.g. ``TimeLimit``).
      layout: the observation's entries and bounds (:class:`~rmac_mj.envs.observation_map.ObservationLayout`).
    """

    def __init__(self, env: Any, seed: int | None = None, name: str = "gymnasium") -> None:
        from gymnasium import spaces

        space = env.action_space
        if not isinstance(space, spaces.Box):
            raise ValueError(
                f"{name}: the action space is {type(space).__name__}; the learners "
                f"need a bounded Box"
            )
        low, high = np.asarray(space.low, dtype=float), np.asarray(space.high, dtype=float)
        problem = box_problem(low, high, [f"u[{i}]" for i in range(low.size)])
        if problem is not None:
            raise ValueError(
                f"{name}: the action space must be bounded (finite low < high): {problem}"
            )
        self.env = env
        self.name = name
        self.layout = layout_of_gymnasium(env.observation_space)
        self._dict_observation = isinstance(env.observation_space, spaces.Dict)
        self._shape, self._dtype = space.shape, space.dtype
        self._action_spec = specs.BoundedArray(
            shape=(low.size,), dtype=float, minimum=low.ravel(), maximum=high.ravel(), name="action"
        )
        self._seed = seed
        self._reset_next_step = True

    # ------------------------------------------------------------------------------ dm_env interface
    def reset(self) -> dm_env.TimeStep:
        observation, _ = self.env.reset(seed=self._seed)
        self._seed = None  # later resets continue the seeded stream
        self._reset_next_step = False
        return dm_env.restart(self._observation(observation))

    def step(self, action: Any) -> dm_env.TimeStep:
        if self._reset_next_step:
            return self.reset()
        action = np.asarray(action, dtype=self._dtype).reshape(self._shape)
        observation, reward, terminated, truncated, _ = self.env.step(action)
        observation = self._observation(observation)
        reward = checked_reward(self.name, "step", reward)
        if terminated:
            self._reset_next_step = True
            return dm_env.termination(reward, observation)
        if truncated:
            self._reset_next_step = True
            return dm_env.truncation(reward, observation)
        return dm_env.transition(reward, observation)

    def observation_spec(self) -> dict[str, specs.Array]:
        return {
            key: specs.Array(shape=(size,), dtype=float, name=key)
            for key, size in self.layout.sizes.items()
        }

    def action_spec(self) -> specs.BoundedArray:
        return self._action_spec

    def close(self) -> None:
        self.env.close()

    # ----------------------------------------------------------------------------------- time
    def control_timestep(self) -> float | None:
        """Seconds per step (the environment's ``dt``), None when it does not say."""
        dt = getattr(self.env.unwrapped, "dt", None)
        return float(dt) if dt is not None else None

    def step_limit(self) -> int | None:
        """Steps per episode from the time limit: the shortest of the ``TimeLimit`` wrappers around
        the environment (a factory's own ``TimeLimit(env, 20)`` too, which the spec of an
        environment made without ``gymnasium.make`` does not hold) and ``spec.max_episode_steps``;
        None without one."""
        from gymnasium import Wrapper
        from gymnasium.wrappers import TimeLimit

        limits = []
        spec = getattr(self.env, "spec", None)
        if getattr(spec, "max_episode_steps", None) is not None:
            limits.append(int(spec.max_episode_steps))
        wrapped = self.env
        while isinstance(wrapped, Wrapper):
            if isinstance(wrapped, TimeLimit):  # its limit, private there, as the wrapper reads it
                limits.append(int(wrapped._max_episode_steps))
            wrapped = wrapped.env
        return min(limits) if limits else None

    def _observation(self, observation: Any) -> dict[str, np.ndarray]:
        if self._dict_observation:
            return {key: np.asarray(value) for key, value in observation.items()}
        return {OBSERVATION: np.asarray(observation)}

"""The task suite as Gymnasium environments, registered when ``rmac_mj.tasks`` is imported.

``gymnasium.make("rmac_mj/DCPendulum-Swingup-v0")``: each task is ``rmac_mj/<Domain>-<Task>-v0``
(:func:`env_id`), the dm-control task stepped unchanged behind :class:`SuiteEnv` (observation,
action, seeding and trial end are listed there).
"""

from __future__ import annotations

import math
import weakref
from typing import Any

import gymnasium
import numpy as np

#: The namespace of the suite's ids.
NAMESPACE = "rmac_mj"


def env_id(domain: str, task: str) -> str:
    """The Gymnasium id of ``domain``/``task``, e.g. ``rmac_mj/DCPendulum-Swingup-v0``."""

    def title(name: str) -> str:
        return "".join(
            word.upper() if len(word) <= 2 else word.capitalize() for word in name.split("_")
        )

    return f"{NAMESPACE}/{title(domain)}-{title(task)}-v0"


def register_suite() -> None:
    """Register every task of ``rmac_mj.tasks`` with Gymnasium (idempotent)."""
    from rmac_mj.tasks import ALL_TASKS

    for domain, task in ALL_TASKS:
        name = env_id(domain, task)
        if name not in gymnasium.registry:
            gymnasium.register(
                name, entry_point=f"{__name__}:SuiteEnv", kwargs={"domain": domain, "task": task}
            )


class SuiteEnv(gymnasium.Env):
    """One task of the suite behind Gymnasium's API.

    Args:
      domain, task: the task, as for ``rmac_mj.tasks.load``.
      task_kwargs: its keyword arguments (not ``random``: seed through ``reset(seed=...)``).
      render_mode: None or ``"rgb_array"``.
      width, height: the size of rendered frames, in pixels.

    * **Observation**: the task's learner state x (``learner_state.keys``) with every periodic
      dimension as (cos, sin), in order; float64. On the pendulum ``[cos phi, sin phi, phi_dot]``,
      as Gymnasium's Pendulum-v1 (neural networks want (cos, sin) rather than an angle that jumps at
      +-pi).
    * **Action**: the task's action box, float32 (Gymnasium's default dtype); applied as float64.
    * **Trial end** is a truncation (``truncated=True``, ``terminated`` never): a learner
      bootstraps.
    * **Seeding**: ``reset(seed=s)`` gives the task the random state of ``rmac_mj.tasks.load(...,
      task_kwargs={"random": s})``; a reset without a seed continues that stream.
    * **Rendering**: ``render_mode="rgb_array"`` draws the model's first camera off-screen
      (:func:`rmac_mj._gl.open_renderer`), ``width`` x ``height`` pixels.
    """

    metadata = {"render_modes": ["rgb_array"]}

    def __init__(
        self,
        domain: str,
        task: str,
        task_kwargs: dict[str, Any] | None = None,
        render_mode: str | None = None,
        width: int = 320,
        height: int = 240,
    ) -> None:
        from rmac_mj import tasks

        task_kwargs = dict(task_kwargs or {})
        if "random" in task_kwargs:
            raise ValueError("task_kwargs must not set 'random': seed through reset(seed=...)")
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(
                f"render_mode must be None or one of {self.metadata['render_modes']}, "
                f"got {render_mode!r}"
            )
        self.domain, self.task, self.task_kwargs = domain, task, task_kwargs
        self.render_mode, self.width, self.height = render_mode, width, height
        self.dm_env = tasks.load(domain, task, task_kwargs=task_kwargs)
        learner_state = self.dm_env.task.learner_state
        self._keys = learner_state.keys
        self._periodic = np.asarray(learner_state.periodic)
        bounds = np.concatenate([[1.0, 1.0] if wraps else [np.inf] for wraps in self._periodic])
        self.observation_space = gymnasium.spaces.Box(-bounds, bounds, dtype=np.float64)
        spec = self.dm_env.action_spec()
        self.action_space = gymnasium.spaces.Box(
            np.broadcast_to(spec.minimum, spec.shape).astype(np.float32),
            np.broadcast_to(spec.maximum, spec.shape).astype(np.float32),
            dtype=np.float32,
        )
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.dm_env.control_timestep()}
        self._renderer = None

    def _observation(self, timestep) -> np.ndarray:
        x = np.concatenate([timestep.observation[key] for key in self._keys], axis=None)
        parts = []
        for value, wraps in zip(x.tolist(), self._periodic.tolist()):
            parts.extend((math.cos(value), math.sin(value)) if wraps else (value,))
        return np.array(parts, dtype=np.float64)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        if seed is not None:  # the task's random state, as tasks.load(..., random=seed) makes it
            from rmac_mj import tasks

            self.dm_env = tasks.load(
                self.domain, self.task, task_kwargs={**self.task_kwargs, "random": seed}
            )
        return self._observation(self.dm_env.reset()), {}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        timestep = self.dm_env.step(np.asarray(action, dtype=np.float64))
        return self._observation(timestep), float(timestep.reward), False, timestep.last(), {}

    def render(self) -> np.ndarray | None:
        """The current state as uint8 (height, width, 3), with render_mode 'rgb_array'."""
        if self.render_mode is None:
            gymnasium.logger.warn(
                "render() without a render_mode: pass render_mode='rgb_array' to gymnasium.make"
            )
            return None
        from rmac_mj._gl import open_renderer

        physics = self.dm_env.physics
        if self._renderer is None:
            self._renderer = open_renderer(physics.model.ptr, self.width, self.height)
            # closed by close(), or at the latest at exit, before the GL library is torn down
            self._close_renderer = weakref.finalize(self, self._renderer.close)
        self._renderer.update_scene(physics.data.ptr, camera=0 if physics.model.ncam > 0 else -1)
        return self._renderer.render()

    def close(self) -> None:
        if self._renderer is not None:
            self._close_renderer()
            self._renderer = None

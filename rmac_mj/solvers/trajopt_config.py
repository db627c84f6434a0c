"""How hard the trajectory-optimisation solver (:mod:`rmac_mj.solvers.trajopt`) searches."""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class TrajoptConfig:
    """How hard to search. The problem itself (model, horizon, reward, x_0) comes from the environment."""

    max_iterations: int = 300
    """iLQR iterations per start and phase (each: derivatives, a backward pass, a line search)."""
    tolerance: float = 1e-9
    """A phase stops when the gain its quadratic model predicts for a full step is below this fraction
    of (1 + |return|)."""
    random_starts: int = 2
    """Random starts (uniform in the action box) in addition to the zero, corner and switched starts."""
    corner_starts: bool = True
    """Also start from every corner of the action box held throughout, and from every corner switched
    to its opposite half way through the trial (2 * 2^m starts)."""
    fd_step: float = 1e-6
    """Finite-difference step of the dynamics: in each of qpos and qvel (rad, rad/s) and as a fraction of
    each action's range."""
    reward_fd_step: float = 1e-4
    """Finite-difference step of the reward's gradient and Hessian in x and u (exact for a quadratic
    reward up to rounding)."""
    seed: int = 0
    """Seed of the random starts."""
    n_threads: int = 0
    """Threads for the batched rollouts; 0 means ``os.cpu_count()``. Does not change results."""

    def __post_init__(self) -> None:
        for name in ("max_iterations", "random_starts", "seed", "n_threads"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool):
                raise TypeError(f"TrajoptConfig.{name} must be an int, got {value!r}")
            if value < 0:
                raise ValueError(f"TrajoptConfig.{name} must be >= 0, got {value}")
        if self.max_iterations < 1:
            raise ValueError(
                f"TrajoptConfig.max_iterations must be >= 1, got {self.max_iterations}"
            )
        if not isinstance(self.corner_starts, (bool, np.bool_)):
            raise TypeError(
                f"TrajoptConfig.corner_starts must be a bool, got {self.corner_starts!r}"
            )
        for name in ("tolerance", "fd_step", "reward_fd_step"):
            value = getattr(self, name)
            if not (np.isscalar(value) and np.isfinite(value) and 0 < value < 1):
                raise ValueError(f"TrajoptConfig.{name} must be a number in (0, 1), got {value!r}")
            object.__setattr__(self, name, float(value))
        object.__setattr__(self, "corner_starts", bool(self.corner_starts))

"""How finely the dynamic programme (:mod:`rmac_mj.solvers.dynamic_programming`) solves: its grid and
action sets."""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class OptimalConfig:
    """How finely the problem is solved (the problem itself comes from the environment:
    :class:`~rmac_mj.solvers.dynamic_programming_grid.Problem`).

    A task's optimum declares the settings it needs (``Optimum.settings``); the defaults are the
    DC-motor pendulum's converged grid (docs/optimal.md).
    """

    n_phi: int = 361
    """Grid nodes in the angle over one period (periodic; spacing period / n_phi)."""
    n_phi_dot: int = 241
    """Grid nodes in the speed over [-max_phi_dot, max_phi_dot], ends included."""
    max_phi_dot: float = 20.0
    """Half-width of the speed grid (rad/s). Next states beyond it are clipped to its edge; the solver
    raises if the greedy trajectory comes within 10% of the edge."""
    n_actions: int = 25
    """Actions evenly spaced over the action range, extremes included."""
    lookahead_actions: int = 121
    """Actions (same range) the greedy policy chooses from when simulated: its one-step look-ahead is
    cheap, so it may search finer than the DP's backups."""
    check_convergence: bool = True
    """Also solve on a grid of half the resolution in each state dimension and with half as many action
    intervals, and report how much the answers move."""
    n_threads: int = 0
    """Threads for the batched transition simulation; 0 means ``os.cpu_count()``. Does not change results."""

    def __post_init__(self) -> None:
        for name in ("n_phi", "n_phi_dot", "n_actions", "lookahead_actions"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool):
                raise TypeError(f"OptimalConfig.{name} must be an int, got {value!r}")
        if self.n_phi < 4:
            raise ValueError(f"OptimalConfig.n_phi must be >= 4, got {self.n_phi}")
        if self.n_phi_dot < 3:
            raise ValueError(f"OptimalConfig.n_phi_dot must be >= 3, got {self.n_phi_dot}")
        if self.n_actions < 2:
            raise ValueError(
                f"OptimalConfig.n_actions must be >= 2 (the two extremes), got {self.n_actions}"
            )
        if self.lookahead_actions < 2:
            raise ValueError(
                f"OptimalConfig.lookahead_actions must be >= 2, got {self.lookahead_actions}"
            )
        if not (
            np.isscalar(self.max_phi_dot) and np.isfinite(self.max_phi_dot) and self.max_phi_dot > 0
        ):
            raise ValueError(
                f"OptimalConfig.max_phi_dot must be a positive finite number, "
                f"got {self.max_phi_dot!r}"
            )
        if not isinstance(self.n_threads, (int, np.integer)) or self.n_threads < 0:
            raise ValueError(f"OptimalConfig.n_threads must be an int >= 0, got {self.n_threads!r}")
        object.__setattr__(self, "max_phi_dot", float(self.max_phi_dot))

    def coarser(self) -> OptimalConfig:
        """The convergence check's problem: about half the nodes per state dimension, half the action
        intervals of the DP and of the look-ahead (the extremes and every other action stay in each
        set), no further check."""
        return dataclasses.replace(
            self,
            n_phi=max(4, self.n_phi // 2),
            n_phi_dot=max(3, (self.n_phi_dot + 1) // 2),
            n_actions=max(2, (self.n_actions + 1) // 2),
            lookahead_actions=max(2, (self.lookahead_actions + 1) // 2),
            check_convergence=False,
        )

"""What every learner shares: the spaces it sees, the exploration schedule, and the interface.

Agents know no particular task. They see a flat state vector ``x`` (described by a
:class:`StateSpace`) and a bounded action vector ``u`` (an :class:`ActionSpace`), and follow the
online protocol of the paper's Algorithms 1 and 2::

    u = agent.start(x0)            # lines 1-5: a new trial begins in x0, returns u_0
    for k in 1, 2, ...:
        u = agent.step(r_k, x_k)   # lines 6-14 (Alg. 1) / 8-29 (Alg. 2): learn, return u_k
    agent.stop(r_K, x_K)           # the last transition of a trial: learn, no action

``greedy_action`` and ``value`` evaluate the current policy and critic without exploring or learning;
a greedy trial begins with ``begin_greedy_trial()``.
``state_dict``/``load_state_dict`` exchange the learned state as a flat dict of numpy arrays, so that
snapshots are written with ``numpy.savez`` and read back with ``allow_pickle=False``.
"""

from __future__ import annotations

import abc
import dataclasses
from typing import Any

import numpy as np


@dataclasses.dataclass(frozen=True)
class StateSpace:
    """The box a flat state lives in.

    Attributes:
      low, high: ndarray of shape (n,), the nominal range of each state dimension (for a periodic
        dimension, one period: ``high - low`` is the period).
      periodic: ndarray of bool of shape (n,), True where a dimension wraps around (an angle).
    """

    low: np.ndarray
    high: np.ndarray
    periodic: np.ndarray

    def __post_init__(self) -> None:
        low = np.asarray(self.low, dtype=float).reshape(-1)
        high = np.asarray(self.high, dtype=float).reshape(-1)
        periodic = np.asarray(self.periodic, dtype=bool).reshape(-1)
        if not (low.shape == high.shape == periodic.shape):
            raise ValueError(
                f"StateSpace: low, high and periodic must have one shape, got {low.shape}, "
                f"{high.shape} and {periodic.shape}")
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high)) and np.all(high > low)):
            raise ValueError(f"StateSpace: need finite low < high, got low={low}, high={high}")
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)
        object.__setattr__(self, "periodic", periodic)

    @property
    def dim(self) -> int:
        return int(self.low.shape[0])

    @property
    def period(self) -> np.ndarray:
        """ndarray of shape (n,): the period of each periodic dimension, 0 for the others."""
        return np.where(self.periodic, self.high - self.low, 0.0)


@dataclasses.dataclass(frozen=True)
class ActionSpace:
    """A bounded continuous action: ndarrays ``low`` and ``high`` of shape (m,)."""

    low: np.ndarray
    high: np.ndarray

    def __post_init__(self) -> None:
        low = np.asarray(self.low, dtype=float).reshape(-1)
        high = np.asarray(self.high, dtype=float).reshape(-1)
        if low.shape != high.shape or not np.all(np.isfinite(low) & np.isfinite(high) & (high > low)):
            raise ValueError(f"ActionSpace: need finite low < high of one shape, got {low}, {high}")
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)

    @property
    def dim(self) -> int:
        return int(self.low.shape[0])

    def clip(self, u: np.ndarray) -> np.ndarray:
        return np.clip(u, self.low, self.high)


@dataclasses.dataclass(frozen=True)
class Exploration:
    """Exploration of section 6.1: every ``period``-th step, zero-mean Gaussian noise of std ``sigma``.

    The other steps are greedy (``Delta u = 0``). Step ``k`` of a trial explores when
    ``k % period == phase``; with the defaults, steps 0, 3, 6, ... explore.

    Attributes:
      sigma: standard deviation of the exploration noise, in action units (V). Paper: 1.
      period: explore once every ``period`` steps. Paper: 3.
      phase: which step of each period explores.
    """

    sigma: float = 1.0
    period: int = 3
    phase: int = 0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma) and self.sigma >= 0):
            raise ValueError(f"Exploration.sigma must be finite and >= 0, got {self.sigma!r}")
        if int(self.period) != self.period or self.period < 1:
            raise ValueError(f"Exploration.period must be a positive integer, got {self.period!r}")
        if int(self.phase) != self.phase or not 0 <= self.phase < self.period:
            raise ValueError(f"Exploration.phase must be in [0, period), got {self.phase!r}")

    def sample(self, k: int, dim: int, rng: np.random.Generator) -> np.ndarray:
        """Delta u_k, ndarray of shape (dim,): noise on exploring steps, zeros otherwise."""
        if self.sigma > 0 and k % self.period == self.phase:
            return rng.normal(0.0, self.sigma, size=dim)
        return np.zeros(dim)


class Agent(abc.ABC):
    """Interface of an online learner (see the module docstring for the protocol)."""

    #: Short name used in results and on the command line, e.g. ``"rmac"``.
    name: str = ""
    #: The frozen hyperparameter dataclass the agent takes.
    config_class: type = object

    def __init__(self, state_space: StateSpace, action_space: ActionSpace, config: Any,
                 seed: int | np.random.Generator | None = None) -> None:
        """Check and keep the spaces and the config; ``rng`` is the agent's only randomness."""
        cls = type(self).__name__
        if not isinstance(state_space, StateSpace):
            raise TypeError(f"{cls}: state_space must be a StateSpace, got {type(state_space).__name__}")
        if not isinstance(action_space, ActionSpace):
            raise TypeError(f"{cls}: action_space must be an ActionSpace, got "
                            f"{type(action_space).__name__}")
        if not isinstance(config, self.config_class):
            raise TypeError(f"{cls}: config must be a {self.config_class.__name__}, got "
                            f"{type(config).__name__}")
        self.state_space = state_space
        self.action_space = action_space
        self.config = config
        self.rng = np.random.default_rng(seed)

    @abc.abstractmethod
    def start(self, x0: np.ndarray) -> np.ndarray:
        """Begin a trial in state ``x0`` (shape (n,)); reset traces; return u_0 (shape (m,))."""

    @abc.abstractmethod
    def step(self, reward: float, x: np.ndarray) -> np.ndarray:
        """Observe r_k and x_k, learn from the transition, return u_k (shape (m,))."""

    @abc.abstractmethod
    def stop(self, reward: float, x: np.ndarray) -> None:
        """Observe the trial's last r_k and x_k and learn from it; no action follows."""

    @abc.abstractmethod
    def greedy_action(self, x: np.ndarray) -> np.ndarray:
        """The policy's action in ``x`` without exploration and without learning."""

    def begin_greedy_trial(self) -> None:
        """Forget what a previous greedy trial carried over (e.g. RMAC's last action); no learning."""

    @abc.abstractmethod
    def value(self, x: np.ndarray) -> float:
        """The critic's estimate V(x)."""

    @abc.abstractmethod
    def state_dict(self) -> dict[str, np.ndarray]:
        """Everything learned, as a flat dict of numeric numpy arrays."""

    @abc.abstractmethod
    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore what :meth:`state_dict` returned; the agent then acts exactly as it did."""

    def config_dict(self) -> dict[str, Any]:
        """The hyperparameters as JSON-ready data (a dataclass's fields)."""
        return dataclasses.asdict(self.config)  # type: ignore[attr-defined]

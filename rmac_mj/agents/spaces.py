"""What a learner sees of a task: a state box (:class:`StateSpace`), an :class:`ActionSpace`.

Both carry the task's default input weightings and its reward's costs; a learner knows nothing else
of the task.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rmac_mj.approximators.llr import wrap

#: How far from its box a learner accepts a state, in box widths. Far beyond any state a task
#: produces (the pendulum's box is +-8 pi rad/s wide; 1e6 widths are 5e7 rad/s), and near enough that
#: every learner's arithmetic stays finite and accurate: squared weighted distances, the normal
#: equations of a local fit, an angle wrapped into one period (to 1e-9 rad), tile indices. A state
#: beyond it is a fault (a corrupted measurement, a unit error) and is refused at the boundary.
STATE_LIMIT_WIDTHS = 1e6


def _weights(owner: str, weights, n: int, name: str = "weights") -> np.ndarray:
    """``weights`` as a float vector of shape (n,), ones for None; ValueError unless finite and >= 0."""
    if weights is None:
        return np.ones(n)
    w = np.asarray(weights, dtype=float).reshape(-1)
    if w.shape != (n,) or not np.all(np.isfinite(w) & (w >= 0)):
        raise ValueError(
            f"{owner}: {name} must be {n} finite numbers >= 0 (one per dimension), got {weights!r}"
        )
    return w


def _keep_box(
    space: StateSpace | ActionSpace, owner: str, low: np.ndarray, high: np.ndarray
) -> None:
    """Store the checked bounds of a frozen ``space``, and its input weights and cost as checked
    vectors of their dimension (:func:`_weights`)."""
    object.__setattr__(space, "low", low)
    object.__setattr__(space, "high", high)
    object.__setattr__(
        space, "input_weights", _weights(owner, space.input_weights, low.shape[0], "input_weights")
    )
    if space.cost is not None:
        object.__setattr__(space, "cost", _weights(owner, space.cost, low.shape[0], "cost"))


@dataclasses.dataclass(frozen=True)
class StateSpace:
    """The box a flat state lives in, and how its dimensions compare.

    Attributes:
      low, high: ndarray of shape (n,), the nominal range of each state dimension (for a periodic
        dimension, one period: ``high - low`` is the period).
      periodic: ndarray of bool of shape (n,), True where a dimension wraps around (an angle).
      input_weights: ndarray of shape (n,), the task's default weighting of each dimension in a
        learner's input distances (RMAC's LLR memories; dc_pendulum: Table 2's (1, 0.1)). None: ones.
      cost: ndarray of shape (n,), what the task's reward charges for the state, r containing
        -sum_i cost_i x_i^2 (x canonical; dc_pendulum: Q's diagonal (5, 0.1)): with
        ``ActionSpace.cost``, the task's reward given as prior knowledge (planning's
        ``reward='task'``). None: the task does not say.
      timestep: seconds between successive states x_k and x_{k+1}, the task's control step. None:
        not said (the learners then take the paper's 0.03 s).
      reward_scale: the magnitude of the task's reward per step far from the goal (dc_pendulum:
        5 pi^2, |r| hanging still), which scales the learners' rates on TD errors. None: not said
        (a learner that needs it estimates it).
    """

    low: np.ndarray
    high: np.ndarray
    periodic: np.ndarray
    input_weights: np.ndarray | None = None
    cost: np.ndarray | None = None
    timestep: float | None = None
    reward_scale: float | None = None

    def __post_init__(self) -> None:
        low = np.asarray(self.low, dtype=float).reshape(-1)
        high = np.asarray(self.high, dtype=float).reshape(-1)
        periodic = np.asarray(self.periodic, dtype=bool).reshape(-1)
        if not (low.shape == high.shape == periodic.shape):
            raise ValueError(
                f"StateSpace: low, high and periodic must have one shape, got {low.shape}, "
                f"{high.shape} and {periodic.shape}"
            )
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high)) and np.all(high > low)):
            raise ValueError(f"StateSpace: need finite low < high, got low={low}, high={high}")
        object.__setattr__(self, "periodic", periodic)
        _keep_box(self, "StateSpace", low, high)
        for name in ("timestep", "reward_scale"):
            value = getattr(self, name)
            if value is not None:
                if not (
                    isinstance(value, (int, float, np.floating, np.integer))
                    and not isinstance(value, bool)
                    and np.isfinite(value)
                    and value > 0
                ):
                    raise ValueError(
                        f"StateSpace: {name} must be a positive finite number or "
                        f"None, got {value!r}"
                    )
                object.__setattr__(self, name, float(value))
        # The accepted region (see ``limit``), as Python floats for the per-step check.
        object.__setattr__(self, "_centre", ((low + high) / 2).tolist())
        object.__setattr__(self, "_reach", (STATE_LIMIT_WIDTHS * (high - low)).tolist())

    @property
    def limit(self) -> tuple[np.ndarray, np.ndarray]:
        """(lowest, highest) states a learner accepts, each of shape (n,): ``STATE_LIMIT_WIDTHS`` box
        widths beyond the box on either side (module docstring)."""
        centre, reach = np.array(self._centre), np.array(self._reach)
        return centre - reach, centre + reach

    def accepts(self, values: list[float]) -> bool:
        """Whether the state ``values`` (n Python floats) is finite and within :attr:`limit`."""
        return all(abs(v - c) <= r for v, c, r in zip(values, self._centre, self._reach))

    @property
    def dim(self) -> int:
        return int(self.low.shape[0])

    @property
    def period(self) -> np.ndarray:
        """ndarray of shape (n,): the period of each periodic dimension, 0 for the others."""
        return np.where(self.periodic, self.high - self.low, 0.0)

    def canonical(self, x: np.ndarray) -> np.ndarray:
        """x (shape (..., n)) with each periodic entry wrapped to [-period/2, period/2): the form in
        which every learner stores and compares states (as ``LLRMemory`` wraps its inputs)."""
        if not self.periodic.any():
            return np.asarray(x, dtype=float)
        return wrap(x, self.period)


@dataclasses.dataclass(frozen=True)
class ActionSpace:
    """A bounded continuous action: ndarrays ``low`` and ``high`` of shape (m,).

    ``input_weights`` (shape (m,)) is the task's default weighting of each action dimension in a
    learner's input distances (RMAC's process model; dc_pendulum: Table 2's 1). None: ones.

    ``cost`` (shape (m,)) is what the task's reward charges for an action, r containing
    -sum_i cost_i u_i^2 (dc_pendulum: P = 1; two_link_arm: 0): the reward knowledge a learner may
    use. None: the task does not say.
    """

    low: np.ndarray
    high: np.ndarray
    input_weights: np.ndarray | None = None
    cost: np.ndarray | None = None

    def __post_init__(self) -> None:
        low = np.asarray(self.low, dtype=float).reshape(-1)
        high = np.asarray(self.high, dtype=float).reshape(-1)
        if low.shape != high.shape or not np.all(
            np.isfinite(low) & np.isfinite(high) & (high > low)
        ):
            raise ValueError(f"ActionSpace: need finite low < high of one shape, got {low}, {high}")
        _keep_box(self, "ActionSpace", low, high)

    @property
    def dim(self) -> int:
        return int(self.low.shape[0])

    def clip(self, u: np.ndarray) -> np.ndarray:
        return np.minimum(np.maximum(u, self.low), self.high)

"""What every task of the suite shares: the learner's view of a task, checks, environment assembly, and
what a task declares beyond its dynamics (its near-optimal return, demonstrators, plot hints:
:class:`TaskKnowledge`)."""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Callable, Mapping
from typing import Any, Protocol

import numpy as np
from dm_control.rl import control


@dataclasses.dataclass(frozen=True)
class LearnerStateSpec:
    """What a learner sees of a task, specified: its flat state x and per-dimension hints.

    x = concatenation of observation[key] for key in ``keys`` (in order).
    """

    keys: tuple[str, ...]
    """Observation entries making up x, in order."""
    low: tuple[float, ...]
    """Nominal box of x (periodic dims: one period)."""
    high: tuple[float, ...]
    periodic: tuple[bool, ...]
    labels: tuple[str, ...]
    """Axis label with unit per state dim, e.g. "angle phi [rad]"."""
    input_weights: tuple[float, ...]
    """Default input weighting of each state dim in LLR distances (dc_pendulum: Table 2's (1, 0.1))."""
    action_input_weights: tuple[float, ...]
    """Default input weighting of each action dim in the process model's LLR distances (dc_pendulum:
    Table 2's 1). Not the reward's weights (a task's ``action_weights`` kwarg); those give
    ``action_cost``."""
    action_labels: tuple[str, ...]
    """Per action dim, e.g. "u [V]" or "tau1 [N m]"."""
    action_cost: tuple[float, ...] | None = None
    """What the reward charges for the action, per action dim: r holds -sum_i action_cost[i] u_i^2
    and no other term in u (the diagonal of the reward's R; dc_pendulum: (P,) = (1,)). The one piece
    of reward knowledge a learner may use (RMAC's scored reachable rules, MLAC's dr/du). None: the
    task does not say (e.g. its R is not diagonal); a learner that needs it must then be told."""
    state_cost: tuple[float, ...] | None = None
    """What the reward charges for the state, per state dim: r holds -sum_i state_cost[i] x_i^2 (x as
    the learner sees it, angles wrapped) and no other term in x (the diagonal of the reward's Q;
    dc_pendulum: (5, 0.1)). With ``action_cost``, the whole reward: what a learner is given when
    the task's reward is prior knowledge (planning's ``reward='task'``). None: the task does not say."""
    reward_scale: float | None = None
    """The magnitude of the reward per step far from the goal (dc_pendulum: 5 pi^2, |r| hanging
    still), by which the learners scale their rates on TD errors. None: the task does not say (a
    learner that needs it estimates it from the rewards it receives)."""

    def __post_init__(self) -> None:
        if not self.keys or not all(isinstance(k, str) and k for k in self.keys):
            raise ValueError(f"LearnerStateSpec.keys must be non-empty strings, got {self.keys!r}")
        n = len(self.low)
        for name in ("high", "periodic", "labels", "input_weights"):
            if len(getattr(self, name)) != n:
                raise ValueError(
                    f"LearnerStateSpec.{name} must have one entry per state dim ({n}, as low), "
                    f"got {len(getattr(self, name))}"
                )
        if (
            len(self.action_input_weights) != len(self.action_labels)
            or not self.action_input_weights
        ):
            raise ValueError(
                f"LearnerStateSpec.action_input_weights and action_labels must have one entry "
                f"per action dim, got {len(self.action_input_weights)} and "
                f"{len(self.action_labels)}"
            )
        low, high = np.asarray(self.low, dtype=float), np.asarray(self.high, dtype=float)
        problem = box_problem(low, high, self.labels)
        if problem is not None:
            raise ValueError(
                f"LearnerStateSpec.low and high must be finite with low < high: {problem}"
            )
        if self.action_cost is not None and len(self.action_cost) != len(self.action_labels):
            raise ValueError(
                f"LearnerStateSpec.action_cost must be None or have one entry per action dim "
                f"({len(self.action_labels)}), got {self.action_cost!r}"
            )
        if self.state_cost is not None and len(self.state_cost) != n:
            raise ValueError(
                f"LearnerStateSpec.state_cost must be None or have one entry per state dim "
                f"({n}), got {self.state_cost!r}"
            )
        for name in ("input_weights", "action_input_weights", "action_cost", "state_cost"):
            w = np.asarray(
                getattr(self, name) if getattr(self, name) is not None else (), dtype=float
            )
            if not (np.all(np.isfinite(w)) and np.all(w >= 0)):
                raise ValueError(
                    f"LearnerStateSpec.{name} must be finite and >= 0, got {getattr(self, name)!r}"
                )
        # Canonical Python types, so that the hints compare, hash and serialise the same however given.
        object.__setattr__(self, "keys", tuple(str(k) for k in self.keys))
        object.__setattr__(self, "low", tuple(float(v) for v in low))
        object.__setattr__(self, "high", tuple(float(v) for v in high))
        object.__setattr__(self, "periodic", tuple(bool(v) for v in self.periodic))
        object.__setattr__(self, "labels", tuple(str(v) for v in self.labels))
        object.__setattr__(self, "input_weights", tuple(float(v) for v in self.input_weights))
        object.__setattr__(
            self, "action_input_weights", tuple(float(v) for v in self.action_input_weights)
        )
        object.__setattr__(self, "action_labels", tuple(str(v) for v in self.action_labels))
        if self.reward_scale is not None:
            if not (is_real(self.reward_scale) and self.reward_scale > 0):
                raise ValueError(
                    f"LearnerStateSpec.reward_scale must be None or a positive finite "
                    f"number, got {self.reward_scale!r}"
                )
            object.__setattr__(self, "reward_scale", float(self.reward_scale))
        for name in ("action_cost", "state_cost"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))


def box_problem(low, high, labels=None) -> str | None:
    """Why ``low`` and ``high`` (shape (n,)) are no box: the first dimension that is not finite
    with low < high, by its label when ``labels`` has one per dimension, with plain numbers
    (``"dimension 0, position [m]: low 3, high -3"``); None when they are a box."""
    low = np.asarray(low, dtype=float).reshape(-1)
    high = np.asarray(high, dtype=float).reshape(-1)
    bad = ~(np.isfinite(low) & np.isfinite(high) & (low < high))
    if not bad.any():
        return None
    i = int(np.argmax(bad))
    named = f", {labels[i]}" if labels is not None and len(labels) == low.size else ""
    return f"dimension {i}{named}: low {low[i]:g}, high {high[i]:g}"


def wrap_angle(angle):
    """Wrap an angle (rad, scalar or array) to [-pi, pi)."""
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


#: The largest magnitude of a start state entry: MuJoCo's mjMAXVAL, beyond which it declares the
#: simulation unstable and resets it (a start there would fail at the first reset, not at load).
MAX_STATE = 1e10


def is_real(value) -> bool:
    """Whether ``value`` is one finite real number (a bool, a string or a complex is not)."""
    return (
        isinstance(value, (numbers.Real, np.floating, np.integer))
        and not isinstance(value, (bool, np.bool_))
        and math.isfinite(value)
    )


def check_positive(name: str, value) -> None:
    """Raise ValueError naming ``name`` unless ``value`` is a positive finite number."""
    if not (is_real(value) and value > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")


def check_in(name: str, value, low: float, high: float, unit: str = "") -> float:
    """``value`` as a float; ValueError naming ``name`` unless it is a number in [low, high]."""
    if not (is_real(value) and low <= value <= high):
        raise ValueError(f"{name} must be a number in [{low:g}, {high:g}]{unit}, got {value!r}")
    return float(value)


def real_array(name: str, value, what: str) -> np.ndarray:
    """``value`` as a float ndarray; ValueError naming ``name`` (and ``what`` was expected) unless
    it holds finite real numbers only (no strings, no complex numbers, no NaN)."""
    array = np.asarray(value)
    if array.dtype.kind not in "iuf" or not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be {what}, got {value!r}")
    return array.astype(float)


def check_start_state(value, n: int, what: str) -> np.ndarray:
    """x_0 of ``n`` finite numbers within MuJoCo's range (:data:`MAX_STATE`); ValueError naming
    ``start_state`` and ``what`` it is otherwise."""
    x0 = real_array("start_state", value, f"finite {what}")
    if x0.shape != (n,):
        raise ValueError(f"start_state must be {what} ({n} numbers), got {value!r}")
    if np.any(np.abs(x0) > MAX_STATE):
        raise ValueError(
            f"start_state must lie within +-{MAX_STATE:g} (MuJoCo's range; beyond it a "
            f"reset fails), got {value!r}"
        )
    return x0


def check_random(random) -> None:
    """ValueError naming ``random`` unless it is what dm-control's tasks take: None, a seed (an
    integer in [0, 2**32)) or a ``numpy.random.RandomState``."""
    if random is None or isinstance(random, np.random.RandomState):
        return
    if (
        isinstance(random, (int, np.integer))
        and not isinstance(random, (bool, np.bool_))
        and 0 <= random < 2**32
    ):
        return
    raise ValueError(
        f"random must be None, a seed (an integer in [0, 2**32)) or a "
        f"numpy.random.RandomState, got {random!r}"
    )


def quadratic_weights(name: str, value, n: int) -> np.ndarray:
    """A weight matrix of shape (n, n) from its diagonal (n,) or itself (n, n), symmetric PSD.

    Raises ValueError naming ``name`` otherwise.
    """
    expected = (
        f"a diagonal of shape ({n},) or a symmetric positive semi-definite ({n}, {n}) "
        "matrix of finite numbers"
    )
    w = real_array(name, value, expected)
    if w.shape == (n,):
        w = np.diag(w)
    if (
        w.shape != (n, n)
        or not np.all(np.isfinite(w))
        or not np.allclose(w, w.T)
        or np.min(np.linalg.eigvalsh(w)) < 0
    ):
        raise ValueError(
            f"{name} must be a diagonal of shape ({n},) or a symmetric positive "
            f"semi-definite ({n}, {n}) matrix, got {value!r}"
        )
    return w


def make_environment(
    physics,
    task,
    time_limit: float,
    control_timestep: float,
    environment_kwargs: dict[str, Any] | None,
) -> control.Environment:
    """A ``control.Environment`` of exactly ``time_limit / control_timestep`` control steps.

    Both must be positive, ``control_timestep`` a whole number of physics timesteps and ``time_limit`` a
    whole number of control steps; ``environment_kwargs`` must not set what the task sets.
    """
    environment_kwargs = dict(environment_kwargs or {})
    for clash in ("control_timestep", "n_sub_steps", "time_limit"):
        if clash in environment_kwargs:
            raise ValueError(
                f"environment_kwargs[{clash!r}] is set by the task; pass it as a task_kwarg instead"
            )
    check_positive("time_limit", time_limit)
    check_positive("control_timestep", control_timestep)
    n_sub_steps = control_timestep / physics.timestep()
    if abs(n_sub_steps - round(n_sub_steps)) > 1e-8 or round(n_sub_steps) < 1:
        raise ValueError(
            f"control_timestep must be a positive multiple of the physics timestep "
            f"{physics.timestep()} s, got {control_timestep!r}"
        )
    n_steps = time_limit / control_timestep
    if abs(n_steps - round(n_steps)) > 1e-8:
        raise ValueError(
            f"time_limit must be a whole number of control steps of {control_timestep} s, "
            f"got {time_limit!r}"
        )
    # dm-control ends an episode once step_count >= time_limit / control_timestep; 3.0 / 0.03 is
    # 100.00000000000001 in floating point, which would give 101 steps. Half a step less is exact.
    return control.Environment(
        physics,
        task,
        time_limit=(round(n_steps) - 0.5) * control_timestep,
        control_timestep=control_timestep,
        **environment_kwargs,
    )


def check_action(action, n: int) -> np.ndarray:
    """The action as a float ndarray of shape (n,); ValueError on another shape, a non-finite value
    or anything but real numbers (a complex number is refused, not cut to its real part).

    A scalar is accepted when ``n == 1``.
    """
    action = np.asarray(action)
    if action.dtype.kind not in "iuf":
        raise ValueError(f"action must be real numbers, got {action!r}")
    action = action.astype(float, copy=False)
    if action.shape != (n,) and not (n == 1 and action.shape == ()):
        raise ValueError(f"action must have shape ({n},), got shape {action.shape}")
    if not np.all(np.isfinite(action)):
        raise ValueError(f"action must be finite, got {action!r}")
    return action.reshape(n)


# --------------------------------------------------------------------------------------------------
# What a task knows beyond its dynamics and reward: declared by the task, asked by the experiments.


class Demonstrator(Protocol):
    """A scripted controller of a task, whose closed loop can be recorded as prior knowledge."""

    action_noise: float
    """Standard deviation of the Gaussian noise added to every recorded action (so that a recording
    excites the input); in the action's unit."""

    def controller(self, env: control.Environment) -> Callable[[np.ndarray], np.ndarray]:
        """The control law x -> u for the environment ``env`` (built from its model)."""


@dataclasses.dataclass(frozen=True)
class Optimum:
    """How a task's near-optimal return is computed (the line the learners are measured against).

    Attributes:
      method: the name of a solver of ``rmac_mj.solvers.optimum`` ("dynamic programming",
        "trajectory optimisation").
      settings: the solver's settings this task needs (e.g. the DP's grid), by name.
    """

    method: str
    settings: Mapping[str, Any] = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class PlotHints:
    """How a task's results are drawn well.

    Attributes:
      return_margin: the least margin around the curves on a learning-curve axis, in the task's
        return units: about the smallest difference of returns per trial worth seeing.
    """

    return_margin: float = 10.0

    def __post_init__(self) -> None:
        check_positive("PlotHints.return_margin", self.return_margin)


@dataclasses.dataclass(frozen=True)
class TaskKnowledge:
    """What a task of the suite declares beyond its environment; an environment from elsewhere has
    none of it (:data:`NOTHING_KNOWN`).

    Attributes:
      optimum: how its near-optimal return is computed (:class:`Optimum`), or None (with its
        default settings: the optimum is for the task as declared).
      demonstrators: name -> a scripted :class:`Demonstrator` ('demo' is the one ``--prior demo``
        records).
      plot_hints: see :class:`PlotHints`.
    """

    optimum: Optimum | None = None
    demonstrators: Mapping[str, Demonstrator] = dataclasses.field(default_factory=dict)
    plot_hints: PlotHints = PlotHints()

    def demonstrator(self, name: str, where: str = "this task") -> Demonstrator:
        """Demonstrator ``name``; ValueError listing the available ones."""
        if name not in self.demonstrators:
            raise ValueError(
                f"no demonstrator {name!r} for {where}; available: "
                f"{', '.join(self.demonstrators) or 'none'} (or give recorded data, "
                "FILE.npz)"
            )
        return self.demonstrators[name]


#: The knowledge of an environment that declares none.
NOTHING_KNOWN = TaskKnowledge()

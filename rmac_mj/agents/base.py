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

``seed_from`` initialises a learner's memories from recorded transitions before it learns (prior
knowledge, section 7); learners that take none refuse it.
"""

from __future__ import annotations

import abc
import dataclasses
import math
from numbers import Integral, Real
from typing import Any, Callable, ClassVar

import numpy as np

from rmac_mj.approximators.llr import wrap
from rmac_mj.constraints import Field, Interval, Options, check_config, invalid


def _weights(owner: str, weights, n: int, name: str = "weights") -> np.ndarray:
    """``weights`` as a float vector of shape (n,), ones for None; ValueError unless finite and >= 0."""
    if weights is None:
        return np.ones(n)
    w = np.asarray(weights, dtype=float).reshape(-1)
    if w.shape != (n,) or not np.all(np.isfinite(w) & (w >= 0)):
        raise ValueError(f"{owner}: {name} must be {n} finite numbers >= 0 (one per dimension), "
                         f"got {weights!r}")
    return w


@dataclasses.dataclass(frozen=True)
class StateSpace:
    """The box a flat state lives in, and how its dimensions compare.

    Attributes:
      low, high: ndarray of shape (n,), the nominal range of each state dimension (for a periodic
        dimension, one period: ``high - low`` is the period).
      periodic: ndarray of bool of shape (n,), True where a dimension wraps around (an angle).
      input_weights: ndarray of shape (n,), the task's default weighting of each dimension in a
        learner's input distances (RMAC's LLR memories; dc_pendulum: Table 2's (1, 0.1)). None: ones.
    """

    low: np.ndarray
    high: np.ndarray
    periodic: np.ndarray
    input_weights: np.ndarray | None = None

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
        object.__setattr__(self, "input_weights",
                           _weights("StateSpace", self.input_weights, low.shape[0], "input_weights"))

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
        if low.shape != high.shape or not np.all(np.isfinite(low) & np.isfinite(high) & (high > low)):
            raise ValueError(f"ActionSpace: need finite low < high of one shape, got {low}, {high}")
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)
        object.__setattr__(self, "input_weights",
                           _weights("ActionSpace", self.input_weights, low.shape[0], "input_weights"))
        if self.cost is not None:
            object.__setattr__(self, "cost", _weights("ActionSpace", self.cost, low.shape[0], "cost"))

    @property
    def dim(self) -> int:
        return int(self.low.shape[0])

    def clip(self, u: np.ndarray) -> np.ndarray:
        return np.minimum(np.maximum(u, self.low), self.high)


@dataclasses.dataclass(frozen=True)
class Exploration:
    """Exploration of section 6.1: every ``period``-th step, zero-mean Gaussian noise of std ``sigma``.

    The other steps are greedy (``Delta u = 0``). Step ``k`` of a trial is *scheduled* to explore when
    ``k % period == phase``; with the defaults, steps 0, 3, 6, ... explore, each with N(0, 1), in
    every trial: the paper's setting. Two extensions (issue 14, study 4; the paper has neither):

    * **A decaying noise level** (``decay``): the std for learning trial t (t = 0, 1, ... counts the
      learning trials the agent has begun; greedy trials do not count) is

      - 'none': ``sigma`` in every trial (the paper);
      - 'exponential': ``max(sigma_min, sigma * decay_rate**t)``;
      - 'linear': from ``sigma`` at t = 0 down to ``sigma_min`` at t = ``decay_trials``, then
        ``sigma_min``.

    * **Exploring only where the process model is uncertain** (``where``, for the learners that learn
      one: RMAC and MLAC): with 'uncertain', a *scheduled* step explores only when the learner's
      model uncertainty at the step (:func:`model_uncertainty`: the mean weighted distance from the
      process model's query point to its K nearest samples, infinite while the memory holds fewer
      than K) is at least ``uncertainty_threshold``; the other scheduled steps are greedy. The
      schedule (``period``, ``phase``) still says *when* exploration may happen, the uncertainty
      *whether* it does. 'always' (the paper) explores on every scheduled step.

    Noise is drawn from the learner's generator only on steps that explore, so with the defaults the
    random stream is the one of the paper's schedule, draw for draw.

    Attributes:
      sigma: standard deviation of the exploration noise, in action units (V). Paper: 1. With a
        decay, the std of the first trial.
      period: explore once every ``period`` steps. Paper: 3.
      phase: which step of each period explores.
      decay: 'none' (paper), 'exponential' or 'linear': how the std falls from trial to trial.
      sigma_min: the std a decay ends at, in [0, sigma]. Unused with decay='none'.
      decay_rate: the factor per trial of decay='exponential', in (0, 1). E.g. 0.99 halves the std
        every 69 trials.
      decay_trials: the trials decay='linear' takes to reach sigma_min, a positive integer.
      where: 'always' (paper) or 'uncertain'.
      uncertainty_threshold: for where='uncertain', the model uncertainty (in the process memory's
        weighted input-distance units; dc_pendulum with Table 2's weighting: 1-norm over
        (phi [rad], 0.1 omega [rad/s], u [V])) at or above which a scheduled step explores. Required
        (a finite number >= 0) with where='uncertain', unused otherwise.
    """

    sigma: float = 1.0
    period: int = 3
    phase: int = 0
    decay: str = "none"
    sigma_min: float = 0.0
    decay_rate: float = 0.99
    decay_trials: int = 300
    where: str = "always"
    uncertainty_threshold: float | None = None

    parameter_constraints: ClassVar[dict[str, list]] = {
        "sigma": [Interval(Real, 0, None)],
        "period": [Interval(Integral, 1, None)],
        "phase": [Interval(Integral, 0, Field("period"), closed="left")],
        "decay": [Options("none", "exponential", "linear")],
        "sigma_min": [Interval(Real, 0, Field("sigma"))],
        "decay_rate": [Interval(Real, 0, 1, closed="right")],
        "decay_trials": [Interval(Integral, 1, None)],
        "where": [Options("always", "uncertain")],
        "uncertainty_threshold": [Interval(Real, 0, None), None],
    }

    def __post_init__(self) -> None:
        check_config(self)
        if self.decay == "exponential" and self.decay_rate == 1:
            raise invalid("Exploration", "decay_rate", self.decay_rate,
                          "below 1 with decay='exponential' (1 never decays; use decay='none')")
        if self.where == "uncertain" and self.uncertainty_threshold is None:
            raise invalid("Exploration", "uncertainty_threshold", None,
                          "a finite number >= 0 with where='uncertain'")

    @property
    def uses_trial(self) -> bool:
        """Whether the noise depends on the trial index (a decay)."""
        return self.decay != "none" and self.sigma_min != self.sigma

    def sigma_at(self, trial: int) -> float:
        """The noise std of learning trial ``trial`` (0 for the first), see ``decay``."""
        if self.decay == "none" or trial <= 0:
            return self.sigma
        if self.decay == "exponential":
            return max(self.sigma_min, self.sigma * self.decay_rate ** trial)
        return self.sigma + (self.sigma_min - self.sigma) * min(trial, self.decay_trials) / \
            self.decay_trials

    def scheduled(self, k: int) -> bool:
        """Whether step ``k`` of a trial is one on which exploration may happen (period, phase)."""
        return k % self.period == self.phase

    def sample(self, k: int, dim: int, rng: np.random.Generator, trial: int = 0,
               uncertainty: Callable[[], float] | None = None) -> np.ndarray:
        """Delta u_k, ndarray of shape (dim,): noise on exploring steps, zeros otherwise.

        Args:
          k: the step within the trial (0 for the action of ``start``).
          dim: m, the action dimension.
          rng: the learner's generator; drawn from only on a step that explores.
          trial: the learning trial's index (for a decay).
          uncertainty: for where='uncertain', a function returning the model uncertainty at this
            step; called only on scheduled steps.
        """
        if not self.scheduled(k):
            return np.zeros(dim)
        sigma = self.sigma_at(trial)
        if not sigma > 0:
            return np.zeros(dim)
        if self.where == "uncertain":
            if uncertainty is None:
                raise ValueError("Exploration.sample: where='uncertain' needs the learner's "
                                 "uncertainty")
            if not uncertainty() >= self.uncertainty_threshold:
                return np.zeros(dim)
        return rng.normal(0.0, sigma, size=dim)


def model_uncertainty(memory: Any, query: np.ndarray) -> float:
    """How uncertain an LLR process model is at ``query`` (shape (n + m,), [x, u]).

    The mean weighted input distance (the memory's own norm and weighting) from ``query`` to its K
    nearest samples; ``inf`` while the memory holds fewer than K samples (the fit there is
    under-determined or rests on far samples). Small where the model has dense data, large where it
    would extrapolate. Used by ``Exploration(where='uncertain')``.
    """
    distances = memory.neighbour_distances(query)
    if len(distances) < memory.n_neighbours:
        return math.inf
    return float(distances.mean())


class Agent(abc.ABC):
    """Interface of an online learner (see the module docstring for the protocol).

    The public methods are the boundary: they check their arguments once (a state of shape (n,) and
    finite, a finite reward, ``step``/``stop`` only inside a trial) and then call the learner's
    ``_start``/``_step``/``_stop``/``_greedy_action``/``_value`` with clean data, so every learner refuses
    bad input the same way. ``state_dict`` holds everything that decides what the agent does next: the
    learner's own arrays (``_state``), its random generator and whether a trial is running.
    """

    #: Short name used in results and on the command line, e.g. ``"rmac"``.
    name: str = ""
    #: Name shown in figures, tables and videos, e.g. ``"RMAC"``.
    display_name: str = ""
    #: The frozen hyperparameter dataclass the agent takes.
    config_class: type = object
    #: The kinds of prior knowledge :meth:`seed_from` puts into this learner, from
    #: :data:`PRIOR_PARTS`; empty for a learner that takes none.
    prior_parts: tuple[str, ...] = ()

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
        self._state_dim = state_space.dim
        self._in_trial = False
        #: Learning trials begun (``start`` calls); a decaying exploration reads the trial index.
        self.trials_ = 0

    def _config_with_task_weights(self, config: Any, state_memories: tuple[str, ...],
                                  process_memories: tuple[str, ...] = ("process",)) -> Any:
        """``config`` with every ``<memory>_weights`` left None taken from the task's hints: the
        StateSpace's ``weights`` for a memory over x, those then the ActionSpace's for one over
        [x, u]; every weighting checked against n or n + m. The learner keeps the result as
        ``self.config``, so results record the weightings actually used."""
        n, m = self.state_space.dim, self.action_space.dim
        hints = {name: self.state_space.input_weights for name in state_memories}
        hints.update({name: np.r_[self.state_space.input_weights, self.action_space.input_weights]
                      for name in process_memories})
        config = dataclasses.replace(config, **{
            f"{name}_weights": tuple(float(w) for w in weights)
            for name, weights in hints.items() if getattr(config, f"{name}_weights") is None})
        for name in hints:
            size = n + m if name in process_memories else n
            weights = getattr(config, f"{name}_weights")
            if len(weights) != size:
                raise ValueError(f"{self.name.upper()}: config.{name}_weights has {len(weights)} "
                                 f"entries, this task needs {size} "
                                 f"({'[x, u]' if name in process_memories else 'x'})")
        return config

    def _config_with_task_action_cost(self, config: Any, used_by: str | None) -> Any:
        """``config`` with its ``action_cost`` resolved against the task, as a tuple of m numbers: None
        takes the task's (``ActionSpace.cost``), a number P stands for P in every action dimension.
        ``used_by`` says what reads it; None when nothing does, and then a cost the task does not
        declare stays None. The learner keeps the result as ``self.config``."""
        m, cost = self.action_space.dim, config.action_cost
        if cost is None:
            cost = self.action_space.cost
            if cost is None and used_by is not None:
                raise ValueError(f"{self.name.upper()}: {used_by} uses the reward's action cost, "
                                 f"which this task does not declare (learner_state.action_cost); "
                                 f"set config.action_cost (0: the reward does not depend on u)")
        elif np.ndim(cost) == 0:
            cost = (cost,) * m
        if cost is not None and len(cost) != m:
            raise ValueError(f"{self.name.upper()}: config.action_cost has {len(cost)} entries, "
                             f"this task has {m} action dimensions")
        return dataclasses.replace(
            config, action_cost=None if cost is None else tuple(float(c) for c in cost))

    # -- the boundary -------------------------------------------------------------------------------
    def _checked_state(self, x: Any, name: str = "x") -> np.ndarray:
        """x as a new float64 vector of shape (n,); ValueError naming ``name`` if not finite or wrong."""
        v = np.array(x, dtype=float)
        if v.shape != (self._state_dim,):
            if v.size != self._state_dim:
                raise ValueError(f"{self.name}: {name} must have shape ({self._state_dim},), got "
                                 f"shape {np.shape(x)}")
            v = v.reshape(self._state_dim)
        # Called once per control step on a few numbers: Python's isfinite over a list is several
        # times cheaper than numpy's isfinite + all on a short vector.
        if not all(map(math.isfinite, v.tolist())):
            raise ValueError(f"{self.name}: {name} must be finite, got {x!r}")
        return v

    def _checked_reward(self, reward: Any) -> float:
        try:
            r = float(reward)
        except (TypeError, ValueError):
            raise ValueError(f"{self.name}: reward must be a finite number, got {reward!r}") from None
        if not math.isfinite(r):
            raise ValueError(f"{self.name}: reward must be finite, got {reward!r}")
        return r

    def _check_in_trial(self, method: str) -> None:
        if not self._in_trial:
            raise RuntimeError(f"{self.name}: {method}() called outside a trial; call start(x0) first")

    def start(self, x0: Any) -> np.ndarray:
        """Begin a trial in state ``x0`` (shape (n,)); reset traces; return u_0 (shape (m,))."""
        x0 = self._checked_state(x0, "x0")
        self.trials_ += 1
        u = self._start(x0)
        self._in_trial = True
        return u

    def step(self, reward: Any, x: Any) -> np.ndarray:
        """Observe r_k and x_k, learn from the transition, return u_k (shape (m,))."""
        self._check_in_trial("step")
        return self._step(self._checked_reward(reward), self._checked_state(x))

    def stop(self, reward: Any, x: Any) -> None:
        """Observe the trial's last r_k and x_k and learn from it; no action follows. Ends the trial."""
        self._check_in_trial("stop")
        self._stop(self._checked_reward(reward), self._checked_state(x))
        self._in_trial = False

    @property
    def _uses_trial_counter(self) -> bool:
        """Whether what the agent does depends on the trial index (a decaying exploration)."""
        exploration = getattr(self.config, "exploration", None)
        return exploration is not None and exploration.uses_trial

    @property
    def trial(self) -> int:
        """The index of the learning trial running (or last run): 0 for the first, -1 before any."""
        return self.trials_ - 1

    def greedy_action(self, x: Any) -> np.ndarray:
        """The policy's action in ``x`` (shape (m,)) without exploration and without learning."""
        return self._greedy_action(self._checked_state(x))

    def value(self, x: Any) -> float:
        """The critic's estimate V(x)."""
        return float(self._value(self._checked_state(x)))

    def begin_greedy_trial(self) -> None:
        """Forget what a previous greedy trial carried over (e.g. RMAC's last action); no learning."""

    def seed_from(self, states: Any, actions: Any, rewards: Any, next_states: Any, trial: Any,
                  parts: Any = None) -> None:
        """Initialise the learner from recorded transitions (prior knowledge, section 7).

        Transition t went from ``states[t]`` under ``actions[t]`` to ``next_states[t]`` and earned
        ``rewards[t]``; ``trial[t]`` says which recorded trial it belongs to, and the transitions of a
        trial are in time order. What each kind of knowledge becomes is the learner's choice (see its
        ``_seed_from``); ``parts`` (names from :attr:`prior_parts`, default all of them) selects some.
        Seeding replaces what the selected memories held; call it before the first trial.

        Args:
          states, next_states: arrays of shape (T, n); actions: (T, m); rewards: (T,); trial: (T,) of
            integers, non-decreasing. All finite; periodic state entries may be unwrapped.
          parts: iterable of names from :attr:`prior_parts`, or None for all.
        Raises:
          NotImplementedError: the learner takes no prior knowledge.
          ValueError: naming the argument that is malformed.
        """
        if not self.prior_parts:
            raise NotImplementedError(f"{self.name} does not take prior knowledge")
        if self._in_trial:
            raise RuntimeError(f"{self.name}: seed_from() called inside a trial; seed before start()")
        chosen = tuple(self.prior_parts) if parts is None else tuple(parts)
        unknown = sorted(set(chosen) - set(self.prior_parts))
        if not chosen or unknown:
            raise ValueError(f"{self.name}: parts must name some of {self.prior_parts}, got "
                             f"{parts!r}")
        arrays = check_transitions(states, actions, rewards, next_states, trial,
                                   self._state_dim, self.action_space.dim, owner=self.name)
        self._seed_from(*arrays, parts=tuple(p for p in self.prior_parts if p in chosen))

    def _seed_from(self, states: np.ndarray, actions: np.ndarray, rewards: np.ndarray,
                   next_states: np.ndarray, trial: np.ndarray, parts: tuple[str, ...]) -> None:
        """Put the checked transitions into the ``parts`` they seed (learners with prior_parts)."""
        raise NotImplementedError(f"{self.name} does not take prior knowledge")

    # -- what each learner implements (arguments already checked) ------------------------------------
    @abc.abstractmethod
    def _start(self, x0: np.ndarray) -> np.ndarray:
        """Lines that begin a trial in x0; return u_0."""

    @abc.abstractmethod
    def _step(self, reward: float, x: np.ndarray) -> np.ndarray:
        """One control step: learn from (x_{k-1}, u_{k-1}, r_k, x_k), return u_k."""

    @abc.abstractmethod
    def _stop(self, reward: float, x: np.ndarray) -> None:
        """The last transition of a trial."""

    @abc.abstractmethod
    def _greedy_action(self, x: np.ndarray) -> np.ndarray:
        """The greedy action in x."""

    @abc.abstractmethod
    def _value(self, x: np.ndarray) -> float:
        """V(x)."""

    @abc.abstractmethod
    def _state(self) -> dict[str, np.ndarray]:
        """The learner's own state (memories, weights, traces, trial bookkeeping) as numeric arrays."""

    @abc.abstractmethod
    def _load_state(self, state: dict[str, np.ndarray]) -> None:
        """Restore what :meth:`_state` returned."""

    # -- state ----------------------------------------------------------------------------------------
    def state_dict(self) -> dict[str, np.ndarray]:
        """Everything that decides what the agent does next, as a flat dict of numeric numpy arrays:
        the learner's state, its random generator (``rng``), whether a trial runs (``in_trial``) and
        how many learning trials have begun (``trials``; a decaying exploration depends on it)."""
        state = self._state()
        for key in ("rng", "in_trial", "trials"):
            if key in state:
                raise KeyError(f"{type(self).__name__}._state() must not use the reserved key {key!r}")
        state["rng"] = generator_state_array(self.rng)
        state["in_trial"] = np.array(self._in_trial)
        state["trials"] = np.array(self.trials_, dtype=np.int64)
        return state

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore what :meth:`state_dict` returned; the agent then acts exactly as the original."""
        missing = sorted({"rng", "in_trial"} - set(state))
        if missing:
            raise ValueError(f"{self.name}: state dict lacks {missing}; has {sorted(state)}")
        # Snapshots written before the trial counter existed lack ``trials``; they load unless the
        # agent's exploration decays, which would then start again from the first trial's noise.
        if "trials" not in state and self._uses_trial_counter:
            raise ValueError(f"{self.name}: state dict lacks 'trials', which a decaying "
                             f"exploration or learning rate needs; has {sorted(state)}")
        self._load_state({k: v for k, v in state.items()
                          if k not in ("rng", "in_trial", "trials")})
        set_generator_state(self.rng, state["rng"])
        self._in_trial = bool(state["in_trial"])
        if "trials" in state:
            self.trials_ = int(state["trials"])

    def config_dict(self) -> dict[str, Any]:
        """The hyperparameters as JSON-ready data (a dataclass's fields)."""
        return dataclasses.asdict(self.config)  # type: ignore[attr-defined]


_MASK64 = (1 << 64) - 1


def generator_state_array(rng: np.random.Generator) -> np.ndarray:
    """The state of a PCG64 generator as 6 uint64 words: state (hi, lo), inc (hi, lo), has_uint32,
    uinteger. Numeric, so snapshots need no pickle and no ``eval``."""
    st = rng.bit_generator.state
    if st.get("bit_generator") != "PCG64":
        raise ValueError(f"only PCG64 generators can be saved, got {st.get('bit_generator')!r}")
    s, inc = int(st["state"]["state"]), int(st["state"]["inc"])
    return np.array([s >> 64, s & _MASK64, inc >> 64, inc & _MASK64, int(st["has_uint32"]),
                     int(st["uinteger"])], dtype=np.uint64)


def set_generator_state(rng: np.random.Generator, words: Any) -> None:
    """Restore a PCG64 generator from :func:`generator_state_array`'s words."""
    w = np.asarray(words)
    if w.shape != (6,) or w.dtype != np.uint64:
        raise ValueError(f"rng state must be 6 uint64 words, got dtype {w.dtype} shape {w.shape}")
    if rng.bit_generator.state.get("bit_generator") != "PCG64":
        raise ValueError("only PCG64 generators can be restored")
    hi_lo = [int(v) for v in w]
    rng.bit_generator.state = {
        "bit_generator": "PCG64",
        "state": {"state": (hi_lo[0] << 64) | hi_lo[1], "inc": (hi_lo[2] << 64) | hi_lo[3]},
        "has_uint32": hi_lo[4], "uinteger": hi_lo[5]}


# ----------------------------------------------------------------------------------------------------
# Prior knowledge (section 7): what every learner that takes it shares.

#: The kinds of prior knowledge a learner may take from recorded transitions:
#: 'process' (x, u) -> x' samples of the dynamics; 'reference' x_k -> x_{k+1} along the demonstrated
#: closed loop (the desired behaviour); 'critic' the demonstration's discounted returns-to-go;
#: 'actor' the demonstrated (x, u) pairs.
PRIOR_PARTS = ("process", "reference", "critic", "actor")


def check_transitions(states: Any, actions: Any, rewards: Any, next_states: Any, trial: Any,
                      state_dim: int | None = None, action_dim: int | None = None,
                      owner: str = "transitions") -> tuple[np.ndarray, ...]:
    """Recorded transitions as float arrays (and int64 trial ids), checked once.

    Shapes: states and next_states (T, n), actions (T, m), rewards (T,), trial (T,) with T >= 1;
    everything finite; trial integer and non-decreasing (each trial's transitions contiguous and in
    time order). ``state_dim``/``action_dim``, when given, are the n and m required. ValueError names
    the field that is wrong.
    """
    def matrix(name, value, width):
        a = np.asarray(value)
        if a.dtype.kind not in "biuf":
            raise ValueError(f"{owner}: {name} must be numeric, got dtype {a.dtype}")
        a = a.astype(float)
        if a.ndim != 2 or a.shape[0] < 1 or (width is not None and a.shape[1] != width):
            want = f"(T, {width})" if width is not None else "(T, d)"
            raise ValueError(f"{owner}: {name} must have shape {want} with T >= 1, got {a.shape}")
        return a

    states = matrix("states", states, state_dim)
    n, T = states.shape[1], states.shape[0]
    actions = matrix("actions", actions, action_dim)
    next_states = matrix("next_states", next_states, n)
    rewards = np.asarray(rewards)
    if rewards.dtype.kind not in "biuf":
        raise ValueError(f"{owner}: rewards must be numeric, got dtype {rewards.dtype}")
    rewards = rewards.astype(float)
    trial_ids = np.asarray(trial)
    if trial_ids.dtype.kind not in "biu":
        raise ValueError(f"{owner}: trial must hold integers, got dtype {trial_ids.dtype}")
    trial_ids = trial_ids.astype(np.int64)
    for name, a, shape in (("actions", actions, (T, actions.shape[1])),
                           ("next_states", next_states, (T, n)), ("rewards", rewards, (T,)),
                           ("trial", trial_ids, (T,))):
        if a.shape != shape:
            raise ValueError(f"{owner}: {name} must have shape {shape} to match states "
                             f"{states.shape}, got {a.shape}")
    for name, a in (("states", states), ("actions", actions), ("rewards", rewards),
                    ("next_states", next_states)):
        bad_rows = ~np.isfinite(a.reshape(T, -1)).all(axis=1)
        if bad_rows.any():
            raise ValueError(f"{owner}: {name} must be finite; {int(bad_rows.sum())} of {T} rows are "
                             f"not (first: row {int(np.argmax(bad_rows))})")
    if T > 1 and np.any(np.diff(trial_ids) < 0):
        row = int(np.argmax(np.diff(trial_ids) < 0)) + 1
        raise ValueError(f"{owner}: trial must be non-decreasing (each trial's transitions together, "
                         f"in time order); row {row} goes back from {trial_ids[row - 1]} to "
                         f"{trial_ids[row]}")
    return states, actions, rewards, next_states, trial_ids


def discounted_returns(rewards: np.ndarray, trial: np.ndarray, gamma: float) -> np.ndarray:
    """Discounted returns-to-go G_t = r_t + gamma G_{t+1} within each trial; shape (T,).

    The return after a trial's last transition is taken as 0 (no bootstrapping past the recording):
    the demonstrator ends balanced upright, where every reward is about 0, and a value estimate of
    unknown states is what the learner is there to find. A state gamma^j steps before the end loses
    gamma^j V(x_end) of its value; with gamma = 0.97 that is under 5% after 100 steps.
    """
    rewards = np.asarray(rewards, dtype=float)
    trial = np.asarray(trial)
    out = np.empty_like(rewards)
    running = 0.0
    for t in range(len(rewards) - 1, -1, -1):
        if t == len(rewards) - 1 or trial[t + 1] != trial[t]:
            running = 0.0
        running = rewards[t] + gamma * running
        out[t] = running
    return out


def seed_memory(memory: Any, X: np.ndarray, Y: np.ndarray) -> None:
    """Fill an LLR memory with samples X (s, n) -> Y (s, m), replacing what it held.

    With s <= capacity the memory holds exactly these samples. With more, the first ``capacity``
    fill it and the rest are inserted in time order through the memory's replacement rule, as if
    they had arrived online (under 'nearest' each later sample replaces its most redundant
    predecessor, so the memory keeps samples spread over the recording; under 'oldest' it keeps the
    last ``capacity``).
    """
    s = min(len(X), int(memory.capacity))
    memory.fit(X[:s], Y[:s])
    for x, y in zip(X[s:], Y[s:]):
        memory.insert(x, y)


class PolicyAgent(Agent):
    """An agent that acts with a fixed policy ``u = policy(x)`` and learns nothing.

    For scripted controllers (a demonstrator, a constant action in a benchmark) wherever the
    experiments take an :class:`Agent`: every call still goes through the checked boundary. The value
    is 0 everywhere; the state is empty apart from the generator.
    """

    name = display_name = "policy"
    config_class = type(None)

    def __init__(self, state_space: StateSpace, action_space: ActionSpace,
                 policy: Any, seed: int | np.random.Generator | None = None) -> None:
        if not callable(policy):
            raise TypeError(f"policy must be a function x -> u, got {type(policy).__name__}")
        super().__init__(state_space, action_space, config=None, seed=seed)
        self.policy_function = policy

    def _act(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(self.policy_function(x), dtype=float).reshape(self.action_space.dim)

    def _start(self, x0: np.ndarray) -> np.ndarray:
        return self._act(x0)

    def _step(self, reward: float, x: np.ndarray) -> np.ndarray:
        return self._act(x)

    def _stop(self, reward: float, x: np.ndarray) -> None:
        pass

    def _greedy_action(self, x: np.ndarray) -> np.ndarray:
        return self._act(x)

    def _value(self, x: np.ndarray) -> float:
        return 0.0

    def _state(self) -> dict[str, np.ndarray]:
        return {}

    def _load_state(self, state: dict[str, np.ndarray]) -> None:
        pass

    def config_dict(self) -> dict[str, Any]:
        return {}

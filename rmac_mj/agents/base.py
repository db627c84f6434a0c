"""The contract every learner keeps: :class:`Agent` (Algorithms 1 and 2's online protocol).

A learner sees a flat state x (:class:`~rmac_mj.agents.spaces.StateSpace`) and a bounded action u
(:class:`~rmac_mj.agents.spaces.ActionSpace`), follows ``start``/``step``/``stop``, and exchanges
its learned state as a flat dict of numpy arrays (``state_dict``). Its public methods check their
arguments once (:func:`check_state`, :func:`check_action`, :func:`check_reward`) and undo a call
the learner refuses (:class:`RefusedTransition`); a subclass implements the protected hooks the
class docstring lists.
"""

from __future__ import annotations

import abc
import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from rmac_mj.agents.planning import Rehearsal
from rmac_mj.agents.seeding import Transitions, check_transitions
from rmac_mj.agents.spaces import STATE_LIMIT_WIDTHS, ActionSpace, StateSpace
from rmac_mj.agents.task_knowledge import with_task_units
from rmac_mj.constraints import finite_vector

#: State dict entries :class:`Agent` writes itself; a learner's ``_state`` must not use them.
_RESERVED = ("rng", "in_trial", "trials")


class RefusedTransition(ValueError):
    """A transition (or a trial's start) whose learning would overflow the learner's arithmetic:
    refused before anything changed (``Agent._overflow``)."""


# -- the checks at the boundary: a value, its space, its name ----------------------------------------
def check_state(x: Any, space: StateSpace, name: str = "x", owner: str = "") -> np.ndarray:
    """x as a new float64 vector of shape (n,) inside ``space.limit``; ValueError naming ``name``
    (after ``owner``, the learner's name) if it is not finite, of another size or that far out."""
    n = space.dim
    v = np.array(x, dtype=float)
    if v.shape != (n,):
        if v.size != n:
            raise ValueError(f"{owner}: {name} must have shape ({n},), got shape {np.shape(x)}")
        v = v.reshape(n)
    # Called once per control step on a few numbers: Python over a list is several times
    # cheaper than numpy on a short vector. A NaN fails every comparison, so this one check
    # refuses non-finite states too.
    values = v.tolist()
    if not space.accepts(values):
        if not all(map(math.isfinite, values)):
            raise ValueError(f"{owner}: {name} must be finite, got {x!r}")
        low, high = space.limit
        i = int(np.argmax((v < low) | (v > high)))
        raise ValueError(
            f"{owner}: {name}[{i}] = {values[i]:g} is beyond what a learner accepts, "
            f"[{low[i]:g}, {high[i]:g}] ({STATE_LIMIT_WIDTHS:g} widths of the state box around "
            f"it); a state that far out overflows the learner's arithmetic"
        )
    return v


def check_action(u: Any, space: ActionSpace, name: str = "u", owner: str = "") -> np.ndarray:
    """u as a new float64 vector of shape (m,); ValueError naming ``name`` if not finite or wrong."""
    return finite_vector(u, space.dim, name, owner)


def check_reward(reward: Any, name: str = "reward", owner: str = "") -> float:
    """A finite number as a float; ValueError naming ``name`` otherwise (a reward has no space)."""
    try:
        r = float(reward)
    except (TypeError, ValueError):
        raise ValueError(f"{owner}: {name} must be a finite number, got {reward!r}") from None
    if not math.isfinite(r):
        raise ValueError(f"{owner}: {name} must be finite, got {reward!r}")
    return r


# -- a random generator as numbers, so that a state dict needs no pickle -------------------------
_MASK64 = (1 << 64) - 1


def generator_state_array(rng: np.random.Generator) -> np.ndarray:
    """The state of a PCG64 generator as 6 uint64 words: state (hi, lo), inc (hi, lo), has_uint32,
    uinteger. Numeric, so snapshots need no pickle and no ``eval``."""
    st = rng.bit_generator.state
    if st.get("bit_generator") != "PCG64":
        raise ValueError(f"only PCG64 generators can be saved, got {st.get('bit_generator')!r}")
    s, inc = int(st["state"]["state"]), int(st["state"]["inc"])
    return np.array(
        [
            s >> 64,
            s & _MASK64,
            inc >> 64,
            inc & _MASK64,
            int(st["has_uint32"]),
            int(st["uinteger"]),
        ],
        dtype=np.uint64,
    )


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
        "has_uint32": hi_lo[4],
        "uinteger": hi_lo[5],
    }


class Agent(abc.ABC):
    """Interface of an online learner, following the paper's online protocol::

        u = agent.start(x0)            # lines 1-5: a new trial begins in x0, returns u_0
        for k in 1, 2, ...:
            u = agent.step(r_k, x_k)   # lines 6-14 (Alg. 1) / 8-29 (Alg. 2): learn, return u_k
        agent.stop(r_K, x_K)           # the last transition of a trial: learn, no action
                                       # (terminal=True: x_K is terminal, V(x_K) = 0)

    Contract. What a runner (or a user's own loop) calls, each checking its arguments once and
    undoing a call the learner refuses (:class:`RefusedTransition`), so every learner refuses bad
    input the same way:

    - ``start``, ``step``, ``stop``: a learning trial (above); planning and replay run after ``stop``.
    - ``begin_greedy_trial``, ``greedy_action``, ``value``: the current policy and critic, without
      exploring or learning (a greedy trial begins with ``begin_greedy_trial()``).
    - ``learn_from``, ``learn``, ``seed_from``: learning from recorded trials, single transitions
      and prior knowledge (section 7, :mod:`rmac_mj.agents.seeding`; refused by learners whose
      :attr:`prior_parts` is empty).
    - ``state_dict``, ``load_state_dict``, ``check_state_dict``: the learned state as a flat dict of
      numpy arrays (``numpy.savez``, read back with ``allow_pickle=False``): the learner's own
      arrays, its random generator, whether a trial runs and the trial counter.
    - ``memory_estimate`` (a classmethod), ``config_dict``, ``trial``, ``rehearsal``.

    What a learner implements, with checked arguments:

    - ``_start(x0, u=None)``, ``_step(reward, x, u=None)``, ``_stop(reward, x, terminal)``: its
      updates (abstract). ``u`` given: the action applied instead of the one it would choose
      (``learn_from``, replay); learners that take no applied action keep the two-argument form.
    - ``_greedy_action(x)``, ``_value(x)``: acting and valuing without learning (abstract).
    - ``_state()``, ``_load_state(state)``: its own arrays (abstract); ``_check_state``,
      ``_may_lack``, ``_shape_varies``: rules on a state dict to restore (optional).
    - ``_memory_parts`` (classmethod): its bytes, for ``memory_estimate``.
    - ``begin_greedy_trial``: forget what a previous greedy trial carried over (optional).
    - ``_set_rehearsing(rehearsing)``: the transitions that follow are planned or replayed, not
      real (optional; a learner with a model of the process keeps it unchanged then).
    - ``_learn_transition``, ``_seed_from``: single transitions and prior knowledge (optional).

    Planning and replay (:class:`~rmac_mj.agents.planning.Rehearsal`) call the learner's own
    updates, ``_start``/``_step``/``_stop``, ``_replay_transition`` and ``_learn_trial``, between
    ``_set_rehearsing(True)`` and ``_set_rehearsing(False)``; a learner's updates raise
    ``self._overflow(...)`` before changing anything when a transition would overflow.
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

    def __init__(
        self,
        state_space: StateSpace,
        action_space: ActionSpace,
        config: Any,
        seed: int | np.random.Generator | None = None,
    ) -> None:
        """Check and keep the spaces and the config; ``rng`` is the agent's only randomness."""
        cls = type(self).__name__
        if not isinstance(state_space, StateSpace):
            raise TypeError(
                f"{cls}: state_space must be a StateSpace, got {type(state_space).__name__}"
            )
        if not isinstance(action_space, ActionSpace):
            raise TypeError(
                f"{cls}: action_space must be an ActionSpace, got {type(action_space).__name__}"
            )
        if not isinstance(config, self.config_class):
            raise TypeError(
                f"{cls}: config must be a {self.config_class.__name__}, got {type(config).__name__}"
            )
        self.state_space = state_space
        self.action_space = action_space
        #: The config with the fields left None set from the task (``with_task_units``).
        self.config = config = with_task_units(config, state_space, action_space)
        self.rng = np.random.default_rng(seed)
        self._state_dim = state_space.dim
        self._in_trial = False
        #: Learning trials begun (``start`` calls); a decaying exploration reads the trial index.
        self.trials_ = 0
        #: Planning and replay between trials (``config.planning``, ``config.replay``); None without.
        self._rehearsal = Rehearsal.of(config, state_space, action_space)

    @classmethod
    def missing_requirement(cls) -> str | None:
        """What this learner needs that is not installed (an optional extra), as the message to
        show; None when it can be built."""
        return None

    @classmethod
    def memory_estimate(
        cls, config: Any, state_space: StateSpace, action_space: ActionSpace
    ) -> int:
        """Bytes of RAM a learner of this class needs with ``config`` (its config dataclass, a dict
        of overrides, or None for the defaults) on these spaces, computed without building it: its
        arrays (memories, weights, traces) and two copies of its state (``state_dict``, and the
        snapshot or restore made from it). The interpreter and compiled code a process needs
        besides are not counted. A runner checks a run against the machine's memory with it.
        """
        if config is None:
            config = cls.config_class()
        elif isinstance(config, dict):
            from rmac_mj.agents import config_from_dict

            config = config_from_dict(cls.config_class, config)
        config = with_task_units(config, state_space, action_space)
        arrays, state = cls._memory_parts(config, state_space, action_space)
        model_arrays, model_state = Rehearsal.memory_parts(config, state_space, action_space)
        return int(arrays + model_arrays + 2 * (state + model_state))

    @classmethod
    def _memory_parts(
        cls, config: Any, state_space: StateSpace, action_space: ActionSpace
    ) -> tuple[int, int]:
        """(bytes of the learner's arrays, bytes of one state dict) for :meth:`memory_estimate`."""
        raise NotImplementedError(f"{cls.name} gives no memory estimate")

    def start(self, x0: Any) -> np.ndarray:
        """Begin a trial in state ``x0`` (shape (n,)); reset traces; return u_0 (shape (m,))."""
        x0 = check_state(x0, self.state_space, "x0", self.name)
        return self._refusable(self._begin_trial, x0)

    def _begin_trial(self, x0: np.ndarray) -> np.ndarray:
        self.trials_ += 1
        u = self._start(x0)
        self._in_trial = True
        if self._rehearsal is not None:
            self._rehearsal.begin(x0, u)
        return u

    def step(self, reward: Any, x: Any) -> np.ndarray:
        """Observe r_k and x_k, learn from the transition, return u_k (shape (m,))."""
        self._check_in_trial("step")
        reward, x = (
            check_reward(reward, "reward", self.name),
            check_state(x, self.state_space, "x", self.name),
        )
        u = self._refusable(self._step, reward, x)
        if self._rehearsal is not None:
            self._rehearsal.record(reward, x, u)
        return u

    def stop(self, reward: Any, x: Any, terminal: bool = False) -> None:
        """Observe the trial's last r_k and x_k and learn from it; no action follows. Ends the trial
        (then plans and replays, with ``config.planning`` and ``config.replay``).

        ``terminal``: x_k is a terminal state (the environment ended the trial: a dm_env discount of
        0, Gymnasium's ``terminated``), whose value is 0, so the last TD error is r_k - V(x_{k-1})
        with no bootstrap. False (the default): the trial ends on a time limit or a truncation and
        the last TD error bootstraps from V(x_k) like every other. A refused update (in the last
        transition, or in planning or replay) leaves the agent as before the call, in its trial."""
        self._check_in_trial("stop")
        reward, x = (
            check_reward(reward, "reward", self.name),
            check_state(x, self.state_space, "x", self.name),
        )
        if self._rehearsal is None:
            self._refusable(self._stop, reward, x, bool(terminal))
            self._in_trial = False
        else:
            self._all_or_nothing(self._end_rehearsed_trial, reward, x, bool(terminal))

    def _end_rehearsed_trial(self, reward: float, x: np.ndarray, terminal: bool) -> None:
        self._stop(reward, x, terminal)
        self._in_trial = False
        self._rehearsal.record(reward, x, None)
        self._rehearsal.after_trial(self)

    def learn_from(self, states: Any, actions: Any, rewards: Any) -> None:
        """Learn from a recorded trial as if this learner had run it with the recorded actions.

        The learner's own updates run on every transition in time order, its traces included, with
        the applied action u_k in place of the one it would have chosen: the same updates as a real
        trial that applied those actions (and what ``Replay(order='forward')`` runs on stored
        trials). Nothing is drawn from the generator and the trial counter does not move.

        Args:
          states: shape (K + 1, n), x_0 ... x_K; actions: shape (K, m), u_0 ... u_{K-1} as applied
            (inside the action bounds); rewards: shape (K,), r_1 ... r_K. All finite, K >= 1.
        """
        if self._in_trial:
            raise RuntimeError(
                f"{self.name}: learn_from() called inside a trial; call it between trials"
            )
        n, m = self._state_dim, self.action_space.dim
        states, actions, rewards = (np.array(a, dtype=float) for a in (states, actions, rewards))
        K = rewards.shape[0] if rewards.ndim == 1 else -1
        for name, a, shape in (
            ("rewards", rewards, (K,)),
            ("states", states, (K + 1, n)),
            ("actions", actions, (K, m)),
        ):
            if K < 1 or a.shape != shape:
                raise ValueError(
                    f"{self.name}: learn_from() needs states (K + 1, {n}), actions "
                    f"(K, {m}) and rewards (K,) with K >= 1; {name} has shape "
                    f"{a.shape}"
                )
            if not np.all(np.isfinite(a)):
                raise ValueError(f"{self.name}: learn_from() {name} must be finite")
        if np.any((actions < self.action_space.low) | (actions > self.action_space.high)):
            raise ValueError(
                f"{self.name}: learn_from() actions must lie inside the action bounds "
                f"[{self.action_space.low}, {self.action_space.high}]"
            )
        self._all_or_nothing(self._learn_trial, states, actions, rewards)

    def _learn_trial(self, states: np.ndarray, actions: np.ndarray, rewards: np.ndarray) -> None:
        """The learner's updates along a recorded trial, with its applied actions (see learn_from)."""
        K = len(rewards)
        self._start(states[0], actions[0])
        for k in range(K - 1):
            self._step(float(rewards[k]), states[k + 1], actions[k + 1])
        self._stop(float(rewards[K - 1]), states[K], False)

    def _replay_transition(
        self, x: np.ndarray, u: np.ndarray, reward: float, x_next: np.ndarray
    ) -> None:
        """One recorded transition learned on its own, as a trial of one step (backward replay)."""
        self._start(x, u)
        self._stop(reward, x_next, False)

    # -- planning and replay -------------------------------------------------------------------------
    @property
    def rehearsal(self) -> Rehearsal | None:
        """What planning and replay keep (the learned model, the stored trials), or None without."""
        return self._rehearsal

    def _set_rehearsing(self, rehearsing: bool) -> None:  # noqa: B027 (an optional hook)
        """Whether the transitions that follow are rehearsed (planning, replay) rather than real: a
        learner that learns a model of the dynamics (RMAC's and MLAC's process model) must then
        leave it unchanged, so that only real transitions enter it (``agents.planning``)."""

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
        return self._greedy_action(check_state(x, self.state_space, "x", self.name))

    def value(self, x: Any) -> float:
        """The critic's estimate V(x)."""
        return float(self._value(check_state(x, self.state_space, "x", self.name)))

    def learn(
        self, x: Any, u: Any, reward: Any, x_next: Any, v: Any = None, model: bool = True
    ) -> float:
        """Learn one transition (x, u, r, x') as a control step does, with the running trial's traces
        and learning rates; returns V(x') (before the update). The learner's step bookkeeping
        (x_{k-1}, u_{k-1}, V_{k-1}) is left alone, so this also learns transitions the learner did
        not make (planning and replay).

        Args:
          x, x_next: states of shape (n,), finite; u: an action of shape (m,), finite; reward: a
            finite number.
          v: V(x), what the critic's sample inserted at x gets (a control step passes the V_{k-1}
            it computed one step before); None: the critic's estimate now.
          model: False leaves the process model out: for a simulated transition, which the process
            model predicted and must not learn from.
        Raises:
          NotImplementedError: the learner learns only from its own steps.
          ValueError: naming the argument that is malformed.
        """
        x, x_next = (
            check_state(x, self.state_space, "x", self.name),
            check_state(x_next, self.state_space, "x_next", self.name),
        )
        u, reward = (
            check_action(u, self.action_space, "u", self.name),
            check_reward(reward, "reward", self.name),
        )
        v = self._value(x) if v is None else check_reward(v, "v", self.name)
        return float(self._refusable(self._learn_transition, x, u, reward, x_next, v, bool(model)))

    def _learn_transition(
        self, x: np.ndarray, u: np.ndarray, reward: float, x_next: np.ndarray, v: float, model: bool
    ) -> float:
        """:meth:`learn` for checked arguments (learners that learn single transitions)."""
        raise NotImplementedError(f"{self.name} learns only from its own steps")

    def begin_greedy_trial(self) -> None:  # noqa: B027 (an optional hook)
        """Forget what a previous greedy trial carried over (e.g. RMAC's last action); no learning."""

    def seed_from(
        self,
        states: Any,
        actions: Any,
        rewards: Any,
        next_states: Any,
        trial: Any,
        parts: Any = None,
    ) -> None:
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
            raise RuntimeError(
                f"{self.name}: seed_from() called inside a trial; seed before start()"
            )
        chosen = tuple(self.prior_parts) if parts is None else tuple(parts)
        unknown = sorted(set(chosen) - set(self.prior_parts))
        if not chosen or unknown:
            raise ValueError(
                f"{self.name}: parts must name some of {self.prior_parts}, got {parts!r}"
            )
        transitions = check_transitions(
            states,
            actions,
            rewards,
            next_states,
            trial,
            self._state_dim,
            self.action_space.dim,
            owner=self.name,
        )
        self._seed_from(transitions, parts=tuple(p for p in self.prior_parts if p in chosen))

    def _seed_from(self, transitions: Transitions, parts: tuple[str, ...]) -> None:
        """Put the checked transitions into the ``parts`` they seed (learners with prior_parts)."""
        raise NotImplementedError(f"{self.name} does not take prior knowledge")

    # -- the learned state as flat arrays ------------------------------------------------------------
    def state_dict(self) -> dict[str, np.ndarray]:
        """Everything that decides what the agent does next, as a flat dict of numeric numpy arrays:
        the learner's state, its random generator (``rng``), whether a trial runs (``in_trial``) and
        how many learning trials have begun (``trials``; a decaying exploration depends on it)."""
        state = self._state()
        for key in _RESERVED:
            if key in state:
                raise KeyError(
                    f"{type(self).__name__}._state() must not use the reserved key {key!r}"
                )
        if self._rehearsal is not None:
            state.update(self._rehearsal.state_dict("rehearsal."))
        state["rng"] = generator_state_array(self.rng)
        state["in_trial"] = np.array(self._in_trial)
        state["trials"] = np.array(self.trials_, dtype=np.int64)
        return state

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore what :meth:`state_dict` returned; the agent then acts exactly as the original.

        Checked first (:meth:`check_state_dict`), so a refused state changes nothing.
        """
        arrays = self.check_state_dict(state)
        self._load_state(
            {
                k: v
                for k, v in arrays.items()
                if k not in _RESERVED and not k.startswith("rehearsal.")
            }
        )
        if self._rehearsal is not None:
            self._rehearsal.load_state_dict(arrays, "rehearsal.")
        set_generator_state(self.rng, arrays["rng"])
        self._in_trial = bool(arrays["in_trial"])
        if "trials" in arrays:
            self.trials_ = int(arrays["trials"])

    def check_state_dict(self, state: Mapping[str, Any]) -> dict[str, np.ndarray]:
        """The state dict as arrays if this learner can restore it, else ValueError (TypeError for
        no mapping) naming what is wrong; nothing changes. The one check of every learner, also
        of every file a resumed run keeps: the keys (none missing, none foreign: a state dict of
        another learner is called one), each array's dtype and shape against this learner's own
        state dict, every float finite, then the learner's own rules (``_check_state``: counts
        and indices in range)."""
        if not isinstance(state, Mapping):
            raise TypeError(
                f"{self.name}: a state dict must be a mapping of names to arrays, got "
                f"{type(state).__name__}"
            )
        own = self.state_dict()
        missing = sorted(k for k in own if k not in state and not self._may_lack(k))
        foreign = sorted(k for k in state if k not in own and not self._may_lack(k))
        if missing or foreign:
            parts = [f"lacks {_listed(missing)}"] * bool(missing) + [
                f"has {_listed(foreign)}, which {self.name} does not"
            ] * bool(foreign)
            hint = " (a state dict of another learner?)" if missing and foreign else ""
            raise ValueError(f"{self.name}: the state dict {' and '.join(parts)}{hint}")
        arrays = {
            key: self._checked_entry(key, value, own.get(key)) for key, value in state.items()
        }
        # Snapshots written before the trial counter existed lack ``trials``; they load unless the
        # agent's exploration decays, which would then start again from the first trial's noise.
        if "trials" not in arrays and self._uses_trial_counter:
            raise ValueError(
                f"{self.name}: the state dict lacks 'trials', which a decaying "
                f"exploration or learning rate needs"
            )
        if "trials" in arrays and int(arrays["trials"]) < 0:
            raise ValueError(
                f"{self.name}: state 'trials' must be >= 0, got {int(arrays['trials'])}"
            )
        self._check_state(arrays)
        return arrays

    def _checked_entry(self, key: str, value: Any, own: np.ndarray | None) -> np.ndarray:
        """One entry of a state dict to restore, checked against the learner's own (``own``; None
        for an entry the learner holds only at some moments: its dtype and values are checked).

        The dtype must be the learner's own (a float32 critic would not act as the original), the
        shape too (for an entry whose length varies, the dimensions after the first), every
        float finite. The one check of every learner: ValueError naming the key, what it got and
        what was expected."""
        array = np.asarray(value)
        if own is None:
            if array.dtype.kind not in "fiub":
                raise ValueError(
                    f"{self.name}: state {key!r} must hold numbers, got dtype {array.dtype}"
                )
        elif array.dtype != own.dtype:
            raise ValueError(
                f"{self.name}: state {key!r} must hold {own.dtype}, got dtype {array.dtype}"
            )
        if own is not None:
            varies = self._shape_varies(key)
            if (
                (array.ndim != own.ndim or array.shape[1:] != own.shape[1:])
                if varies
                else (array.shape != own.shape)
            ):
                expected = ("K",) + own.shape[1:] if varies else own.shape
                raise ValueError(
                    f"{self.name}: state {key!r} must have shape {expected}, got {array.shape}"
                )
        if array.dtype.kind == "f" and not np.all(np.isfinite(array)):
            raise ValueError(
                f"{self.name}: state {key!r} must be finite; "
                f"{int(np.size(array) - np.count_nonzero(np.isfinite(array)))} of "
                f"{np.size(array)} entries are not"
            )
        return array

    def _may_lack(self, key: str) -> bool:
        """Whether a state dict may lack ``key`` (or hold it though this agent does not now): an
        entry written only by some versions or at some moments."""
        return key == "trials"

    def _shape_varies(self, key: str) -> bool:
        """Whether the shape of state entry ``key`` depends on the moment (e.g. a filling buffer,
        planning's or replay's stored transitions)."""
        return key.startswith("rehearsal.")

    def _check_state(self, state: dict[str, np.ndarray]) -> None:  # noqa: B027 (an optional hook)
        """The learner's own rules on a state dict to restore (counts and indices in range), checked
        before anything changes; ValueError naming the entry."""

    # -- a refused call changes nothing ---------------------------------------------------------------
    def _overflow(self, what: Any) -> RefusedTransition:
        """The error of a transition whose learning overflows (``what``: the quantity, or the
        reward). A learner raises it before it changes its own arrays (check, then change); the
        boundary puts back the random generator and the trial counter (:meth:`_refusable`)."""
        if not isinstance(what, str):
            what = f"the transition with reward {what!r}"
        return RefusedTransition(
            f"{self.name}: {what} overflows the learner's arithmetic (not finite); "
            f"refused, nothing non-finite was stored"
        )

    def _check_in_trial(self, method: str) -> None:
        if not self._in_trial:
            raise RuntimeError(
                f"{self.name}: {method}() called outside a trial; call start(x0) first"
            )

    def _refusable(self, change: Any, *args: Any) -> Any:
        """``change(*args)``, and if the learner refuses it (:class:`RefusedTransition`) the random
        generator and the trial counter as they were: the learner refuses before it changes its own
        arrays, so a refused call leaves ``state_dict()`` exactly as it was."""
        rng_state, trials = self.rng.bit_generator.state, self.trials_
        try:
            return change(*args)
        except RefusedTransition:
            self.rng.bit_generator.state, self.trials_ = rng_state, trials
            raise

    def _all_or_nothing(self, change: Any, *args: Any) -> Any:
        """``change(*args)`` for a call that runs many updates (a stored trial, planning and replay
        after a trial): if the learner refuses one, the whole state as it was before the call."""
        before = self.state_dict()
        try:
            return change(*args)
        except RefusedTransition:
            self.load_state_dict(before)
            raise

    # -- what each learner implements (arguments already checked) ------------------------------------
    @abc.abstractmethod
    def _start(self, x0: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """Lines that begin a trial in x0; return u_0 (``u``: the action applied instead)."""

    @abc.abstractmethod
    def _step(self, reward: float, x: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """One control step: learn from (x_{k-1}, u_{k-1}, r_k, x_k), return u_k (``u``: the
        action applied instead)."""

    @abc.abstractmethod
    def _stop(self, reward: float, x: np.ndarray, terminal: bool) -> None:
        """The last transition of a trial (``terminal``: x is terminal, V(x) = 0; see ``stop``)."""

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

    def config_dict(self) -> dict[str, Any]:
        """The hyperparameters as JSON-ready data (a dataclass's fields)."""
        return dataclasses.asdict(self.config)  # type: ignore[attr-defined]


def _listed(keys: list[str], most: int = 4) -> str:
    """A few keys for a message: 'a', 'b' (+3 more)."""
    shown = ", ".join(repr(k) for k in keys[:most])
    return shown + (f" (+{len(keys) - most} more)" if len(keys) > most else "")

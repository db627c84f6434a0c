"""The interface every learner shares: :class:`Agent`, one checked boundary (Algorithms 1 and 2).

A learner sees a flat state x (:class:`~rmac_mj.agents.spaces.StateSpace`) and a bounded action u
(:class:`~rmac_mj.agents.spaces.ActionSpace`), follows ``start``/``step``/``stop`` (the protocol is
in :class:`Agent`), and exchanges its learned state as a flat dict of numpy arrays (``state_dict``).
The checks of its public methods are :mod:`~rmac_mj.agents.boundary`'s, the exchange of its state
:mod:`~rmac_mj.agents.state_exchange`'s.
"""

from __future__ import annotations

import abc
import dataclasses
from typing import Any

import numpy as np

from rmac_mj.agents.boundary import AgentBoundary
from rmac_mj.agents.planning import Rehearsal
from rmac_mj.agents.seeding import check_transitions
from rmac_mj.agents.spaces import ActionSpace, StateSpace
from rmac_mj.agents.state_exchange import StateExchange
from rmac_mj.agents.task_knowledge import with_task_units


class Agent(AgentBoundary, StateExchange, abc.ABC):
    """Interface of an online learner, following the paper's online protocol::

        u = agent.start(x0)            # lines 1-5: a new trial begins in x0, returns u_0
        for k in 1, 2, ...:
            u = agent.step(r_k, x_k)   # lines 6-14 (Alg. 1) / 8-29 (Alg. 2): learn, return u_k
        agent.stop(r_K, x_K)           # the last transition of a trial: learn, no action
                                       # (terminal=True: x_K is terminal, V(x_K) = 0)

    ``greedy_action`` and ``value`` evaluate the current policy and critic without exploring or
    learning; a greedy trial begins with ``begin_greedy_trial()``.
    ``state_dict``/``load_state_dict`` exchange the learned state as a flat dict of numpy arrays
    (``numpy.savez``, read back with ``allow_pickle=False``). ``seed_from`` initialises the memories
    from recorded transitions (prior knowledge, section 7, :mod:`rmac_mj.agents.seeding`); learners
    that take none refuse it.

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
        x0 = self._checked_state(x0, "x0")
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
        reward, x = self._checked_reward(reward), self._checked_state(x)
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
        reward, x = self._checked_reward(reward), self._checked_state(x)
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

    # -- what planning and replay use (``planning.RehearsedLearner``) ------------------------------
    def set_rehearsing(self, rehearsing: bool) -> None:
        """Tell the learner whether the transitions that follow are rehearsed (see
        ``_set_rehearsing``)."""
        self._set_rehearsing(bool(rehearsing))

    def rehearse_start(self, x0: np.ndarray) -> np.ndarray:
        return self._start(x0)

    def rehearse_step(self, reward: float, x: np.ndarray) -> np.ndarray:
        return self._step(reward, x)

    def rehearse_stop(self, reward: float, x: np.ndarray, terminal: bool) -> None:
        self._stop(reward, x, terminal)

    def replay_transition(
        self, x: np.ndarray, u: np.ndarray, reward: float, x_next: np.ndarray
    ) -> None:
        self._replay_transition(x, u, reward, x_next)

    def replay_trial(self, states: np.ndarray, actions: np.ndarray, rewards: np.ndarray) -> None:
        self._learn_trial(states, actions, rewards)

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
        return self._greedy_action(self._checked_state(x))

    def value(self, x: Any) -> float:
        """The critic's estimate V(x)."""
        return float(self._value(self._checked_state(x)))

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
        x, x_next = self._checked_state(x), self._checked_state(x_next, "x_next")
        u, reward = self._checked_action(u), self._checked_reward(reward)
        v = self._value(x) if v is None else self._checked_reward(v, "v")
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
        arrays = check_transitions(
            states,
            actions,
            rewards,
            next_states,
            trial,
            self._state_dim,
            self.action_space.dim,
            owner=self.name,
        )
        self._seed_from(*arrays, parts=tuple(p for p in self.prior_parts if p in chosen))

    def _seed_from(
        self,
        states: np.ndarray,
        actions: np.ndarray,
        rewards: np.ndarray,
        next_states: np.ndarray,
        trial: np.ndarray,
        parts: tuple[str, ...],
    ) -> None:
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

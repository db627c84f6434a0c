"""Planning (Dyna) and experience replay for every learner: rehearsal after each real trial.

:class:`Planning` runs rollouts in a learned :class:`TransitionModel`, :class:`Replay` replays
stored real trials, both through the learner's own updates (:class:`Rehearsal`); with ``steps = 0``
nothing here runs, bit for bit.
"""

from __future__ import annotations

import dataclasses
from numbers import Integral
from typing import Any, ClassVar, Protocol

import numpy as np
from numba import njit

from rmac_mj.agents.spaces import ActionSpace, StateSpace
from rmac_mj.approximators.llr import LLRMemory, llr_query, wrap, wrap_scalar
from rmac_mj.constraints import (
    REHEARSAL_STEPS,
    Boolean,
    InstanceOf,
    Interval,
    Options,
    check_config,
    invalid,
)


@dataclasses.dataclass(frozen=True)
class Planning:
    """Dyna-style planning in learned models (Sutton 1991; GRL's ``agent/dyna``). 0 steps: none (the
    paper).

    ``steps`` simulated transitions per real transition of the trial, in rollouts of ``horizon``
    steps. A rollout is a trial the learner runs in a learned model instead of the process: it
    starts in a state chosen by ``start``, acts with its own action rule and exploration, and learns
    from each simulated transition exactly as from a real one. The next state comes from the
    :class:`TransitionModel`, an LLR memory of the real transitions [x, u] -> x' kept for
    prediction; the reward from the same memory's real rewards (``reward='learned'``: the learner
    still knows no task) or from the task's declared costs (``reward='task'``: -sum_i q_i x_i^2 -
    sum_j p_j u_j^2 with ``StateSpace.cost`` and ``ActionSpace.cost``).
    """

    steps: int = 0
    """Simulated transitions per real transition, run after each real trial."""
    horizon: int | None = 0
    """Steps of one simulated rollout; 0: as many as the real trial just run had; None: 1 s of the
    task (33 steps of the paper's 0.03 s)."""
    start: str = "start"
    """Where a rollout starts: 'start' (the real trial's start state), 'trajectory' (a state of the
    real trial just run, drawn uniformly) or 'memory' (a state of the model's memory, uniformly)."""
    reward: str = "learned"
    """The simulated reward: 'learned' (an LLR model of the real rewards over [x, u]) or 'task' (the
    task's reward given as prior knowledge: its declared state and action costs)."""
    model_capacity: int | None = None
    """Samples of the model's memory (2000 for n + m = 3); None: 2000 (n + m) / 3."""
    model_neighbours: int | None = None
    """Nearest neighbours K of the model's local fits (9 for n + m = 3); None: 9 (n + m) / 3."""
    clip: bool = True
    """Keep predicted non-periodic state entries inside the task's nominal box."""
    interpolate: bool = False
    """Keep every prediction (next state and learned reward) within the range of its neighbours'
    outputs, so that a local fit never extrapolates a reward no real transition earned."""

    parameter_constraints: ClassVar[dict[str, list]] = {
        "steps": [Interval(Integral, 0, REHEARSAL_STEPS)],
        "horizon": [Interval(Integral, 0, None), None],
        "start": [Options("start", "trajectory", "memory")],
        "reward": [Options("learned", "task")],
        "model_capacity": [Interval(Integral, 1, None), None],
        "model_neighbours": [Interval(Integral, 1, None), None],
        "clip": [Boolean()],
        "interpolate": [Boolean()],
    }
    #: The fields set from the task when left None: field -> (rule, value at the paper's pendulum)
    #: (``task_knowledge.with_task_units``).
    task_units: ClassVar[dict[str, tuple[str, float]]] = {
        "model_capacity": ("transitions", 2000),
        "model_neighbours": ("transitions", 9),
        "horizon": ("steps", 33),
    }

    def __post_init__(self) -> None:
        check_config(self)
        if (
            self.model_neighbours is not None
            and self.model_capacity is not None
            and self.model_neighbours > self.model_capacity
        ):
            raise invalid(
                "Planning",
                "model_neighbours",
                self.model_neighbours,
                f"an integer in [1, model_capacity={self.model_capacity}]",
            )


@dataclasses.dataclass(frozen=True)
class Replay:
    """Experience replay of stored real trials (Adam, Busoniu and Babuska 2012). 0 steps: none (the
    paper).

    ``steps`` updates per real transition from the stored real trials, each with the action that was
    applied. ``order='backward'`` replays a stored trial from its last transition to its first, each
    on its own (traces reset: a TD(0)-like update that carries a reward back along the whole trial
    in one pass); ``'forward'`` replays it as the trial it was, traces and all.
    """

    steps: int = 0
    """Replayed transitions per real transition, run after each real trial."""
    order: str = "backward"
    """'backward' (each transition on its own, from a trial's last to its first, as Adam et al.) or
    'forward' (a stored trial replayed as it ran, with the learner's traces)."""
    capacity: int = 10000
    """Real transitions kept for replay (whole trials; the oldest trials are dropped first)."""

    parameter_constraints: ClassVar[dict[str, list]] = {
        "steps": [Interval(Integral, 0, REHEARSAL_STEPS)],
        "order": [Options("backward", "forward")],
        "capacity": [Interval(Integral, 1, None)],
    }

    def __post_init__(self) -> None:
        check_config(self)


#: The constraints of a learner config's ``planning`` and ``replay`` fields (every learner has both).
REHEARSAL = {"planning": [InstanceOf(Planning)], "replay": [InstanceOf(Replay)]}


# --------------------------------------------------------------------------------------------------
# The model planning simulates with.


@njit(cache=True)
def _predict(
    memory, z, period, low, high, clip, state_cost, action_cost, task_reward, idx, beta, out, x_next
):
    """x' (into ``x_next``) and r at z = [x, u] (x canonical, u applied): the compiled
    ``TransitionModel.predict``."""
    n = x_next.shape[0]
    llr_query(memory, z, idx, beta, out)
    for j in range(n):
        x_next[j] = wrap_scalar(out[j], period[j])
        if clip and period[j] == 0.0:
            x_next[j] = min(max(x_next[j], low[j]), high[j])
    if not task_reward:
        return out[n]
    r = 0.0
    for j in range(n):
        r -= state_cost[j] * z[j] * z[j]
    for i in range(z.shape[0] - n):
        r -= action_cost[i] * z[n + i] * z[n + i]
    return r


class TransitionModel:
    """x' = f(x, u) and r = rho(x, u) learned from real transitions, for planning.

    One LLR memory over [x, u] holds the real next states and, with ``reward='learned'``, the real
    rewards, [x, u | x', r]: one neighbour search and one local fit predict both. With
    ``reward='task'`` it holds [x, u | x'] and r is the task's declared reward.

    Args:
      planning: the settings (``model_capacity``, ``model_neighbours``, ``reward``, ``clip``).
      state_space, action_space: the learner's; the memory weighs [x, u] by the task's ``input_weights``
        (as RMAC's process model does), periodic state entries wrap, and ``reward='task'`` reads the
        spaces' ``cost``.
      backend: 'numba' or 'numpy'.

    Learned state: ``memory`` (:class:`LLRMemory`).
    """

    def __init__(
        self,
        planning: Planning,
        state_space: StateSpace,
        action_space: ActionSpace,
        backend: str = "numba",
    ) -> None:
        n, m = state_space.dim, action_space.dim
        self.n, self.m = n, m
        self.period = state_space.period
        self.low, self.high = state_space.low, state_space.high
        self.clip = bool(planning.clip)
        self.backend = backend
        self.task_reward = planning.reward == "task"
        if self.task_reward:
            state_cost = getattr(state_space, "cost", None)
            action_cost = getattr(action_space, "cost", None)
            if state_cost is None or action_cost is None:
                raise ValueError(
                    "Planning.reward='task' needs the task's reward as prior knowledge, "
                    "but this task does not declare its state and action costs "
                    "(learner_state.state_cost, action_cost); use reward='learned'"
                )
            self.state_cost = np.asarray(state_cost, dtype=float)
            self.action_cost = np.asarray(action_cost, dtype=float)
        else:
            self.state_cost, self.action_cost = np.zeros(n), np.zeros(m)
        outputs = n if self.task_reward else n + 1
        self.memory = LLRMemory(
            n + m,
            outputs,
            planning.model_capacity,
            planning.model_neighbours,
            input_weights=np.r_[state_space.input_weights, action_space.input_weights],
            input_period=np.r_[self.period, np.zeros(m)],
            output_period=np.r_[self.period, np.zeros(outputs - n)],
            conditioning="ridge",
            clip=bool(planning.interpolate),
            backend=backend,
        )
        # Scratch of the compiled prediction.
        self._z = np.empty(n + m)
        self._idx = np.empty(planning.model_neighbours, dtype=np.int64)
        self._beta = np.empty((outputs, n + m + 1))
        self._out = np.empty(outputs)

    def observe(self, x: np.ndarray, u: np.ndarray, r: float, x_next: np.ndarray) -> None:
        """Learn one real transition (x canonical, u as applied)."""
        self.memory.insert(np.concatenate([x, u]), x_next if self.task_reward else np.r_[x_next, r])

    def predict(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, float]:
        """(x', r) at the canonical state x (shape (n,)) under the applied action u (shape (m,))."""
        n = self.n
        if self.backend == "numba":
            z = self._z
            z[:n] = x
            z[n:] = u
            x_next = np.empty(n)
            r = _predict(
                self.memory.kernel_state,
                z,
                self.period,
                self.low,
                self.high,
                self.clip,
                self.state_cost,
                self.action_cost,
                self.task_reward,
                self._idx,
                self._beta,
                self._out,
                x_next,
            )
            return x_next, r
        out = self.memory.query(np.concatenate([x, u]))[0]
        x_next = wrap(out[:n], self.period)
        if self.clip:
            x_next = np.where(self.period > 0, x_next, np.clip(x_next, self.low, self.high))
        if self.task_reward:
            return x_next, -float(self.state_cost @ (x * x)) - float(self.action_cost @ (u * u))
        return x_next, float(out[n])

    def state_dict(self, prefix: str = "") -> dict[str, np.ndarray]:
        return self.memory.state_dict(prefix)

    def load_state_dict(self, state: dict[str, np.ndarray], prefix: str = "") -> None:
        self.memory.load_state_dict(state, prefix)


# --------------------------------------------------------------------------------------------------
# The rehearsal between real trials.


class RehearsedLearner(Protocol):
    """What a rehearsal calls on its learner: the generator and the protected hooks of
    :class:`~rmac_mj.agents.base.Agent`'s contract, with arguments already clean."""

    rng: np.random.Generator

    def _set_rehearsing(self, rehearsing: bool) -> None:
        """Rehearsed transitions follow (True) or real ones again (False)."""

    def _start(self, x0: np.ndarray) -> np.ndarray:
        """Begin a simulated trial in x0 (shape (n,)); return u_0 (shape (m,))."""

    def _step(self, reward: float, x: np.ndarray) -> np.ndarray:
        """Learn from a simulated step (r_k, x_k); return u_k."""

    def _stop(self, reward: float, x: np.ndarray, terminal: bool) -> None:
        """The last simulated transition of a rollout."""

    def _replay_transition(
        self, x: np.ndarray, u: np.ndarray, reward: float, x_next: np.ndarray
    ) -> None:
        """One stored transition learned on its own (backward replay)."""

    def _learn_trial(self, states: np.ndarray, actions: np.ndarray, rewards: np.ndarray) -> None:
        """A stored trial learned with its applied actions (forward replay)."""


class Rehearsal:
    """What a learner with planning or replay keeps, and the rehearsal it runs after each trial.

    The learner's boundary (``Agent.start/step/stop``) shows it every real transition
    (:meth:`begin`, :meth:`record`); after the trial, :meth:`after_trial` replays and plans through
    the learner's :class:`RehearsedLearner` interface.

    Simulated transitions never enter any model (the learner is told it is rehearsing, see
    ``Agent._set_rehearsing``), so the models hold only what the process did; a predicted
    state is kept inside the task's nominal box (``Planning.clip``). The rehearsal runs after the
    real trial's last transition is learned (``Agent.stop``), so the real trial's bookkeeping is
    never disturbed, and its budget is counted in real transitions of that trial. Simulated and
    replayed trials draw their exploration noise from the learner's generator and do not count as
    learning trials. The model's prediction runs compiled (``backend='numba'``) or in numpy.

    Learned state: the :class:`TransitionModel` (``model``, with planning), the stored trials
    (with replay) and the running trial's record.
    """

    def __init__(
        self,
        planning: Planning,
        replay: Replay,
        state_space: StateSpace,
        action_space: ActionSpace,
        backend: str = "numba",
    ) -> None:
        self.planning, self.replay = planning, replay
        self.n, self.m = state_space.dim, action_space.dim
        self.period = state_space.period
        self.model = (
            TransitionModel(planning, state_space, action_space, backend)
            if planning.steps
            else None
        )
        # The running trial: x_0..x_K (canonical), u_0..u_{K-1} as applied, r_1..r_K.
        self._states: list[np.ndarray] = []
        self._actions: list[np.ndarray] = []
        self._rewards: list[float] = []
        # Stored trials for replay: (states (K+1, n), actions (K, m), rewards (K,)).
        self.trials_: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._low, self._high = action_space.low, action_space.high

    @staticmethod
    def memory_parts(
        config: Any, state_space: StateSpace, action_space: ActionSpace
    ) -> tuple[int, int]:
        """(bytes of the arrays, bytes of one state dict) of the planning model a learner's config
        (its task units resolved) asks for, computed without building it; (0, 0) without planning.
        Replay's stored trials grow with the run and are not counted."""
        planning = getattr(config, "planning", None) or Planning()
        if not planning.steps:
            return 0, 0
        n, m = state_space.dim, action_space.dim
        outputs = n if planning.reward == "task" else n + 1
        capacity, neighbours = planning.model_capacity, planning.model_neighbours
        return (
            LLRMemory.memory_estimate(n + m, outputs, capacity, neighbours),
            LLRMemory.state_estimate(n + m, outputs, capacity),
        )

    @staticmethod
    def of(config: Any, state_space: StateSpace, action_space: ActionSpace) -> Rehearsal | None:
        """The rehearsal a learner's config asks for, or None (no planning and no replay)."""
        planning = getattr(config, "planning", None) or Planning()
        replay = getattr(config, "replay", None) or Replay()
        if not planning.steps and not replay.steps:
            return None
        return Rehearsal(
            planning, replay, state_space, action_space, getattr(config, "backend", "numba")
        )

    # -- the real trial --------------------------------------------------------------------------
    def begin(self, x0: np.ndarray, u0: np.ndarray) -> None:
        self._states = [wrap(x0, self.period)]
        self._actions = [np.minimum(np.maximum(u0, self._low), self._high)]
        self._rewards = []

    def record(self, reward: float, x: np.ndarray, u: np.ndarray | None) -> None:
        """r_k and x_k of a real step, and u_k (None after the trial's last step)."""
        x = wrap(x, self.period)
        if self.model is not None:
            self.model.observe(self._states[-1], self._actions[-1], reward, x)
        self._states.append(x)
        self._rewards.append(float(reward))
        if u is not None:
            self._actions.append(np.minimum(np.maximum(u, self._low), self._high))

    # -- between trials ----------------------------------------------------------------------------
    def after_trial(self, agent: RehearsedLearner) -> None:
        """Replay, then plan, with the real trial just ended."""
        steps = len(self._rewards)
        if steps == 0:
            return
        trial = (np.array(self._states), np.array(self._actions), np.array(self._rewards))
        agent._set_rehearsing(True)
        try:
            if self.replay.steps:
                self._store(trial)
                self._replay(agent, self.replay.steps * steps)
            if self.planning.steps:
                self._plan(agent, self.planning.steps * steps, trial, steps)
        finally:
            agent._set_rehearsing(False)

    def _store(self, trial) -> None:
        self.trials_.append(trial)
        total = sum(len(t[2]) for t in self.trials_)
        while len(self.trials_) > 1 and total > self.replay.capacity:
            total -= len(self.trials_.pop(0)[2])

    def _replay(self, agent: RehearsedLearner, budget: int) -> None:
        """``budget`` updates from stored trials drawn uniformly, each replayed whole (or cut)."""
        while budget > 0:
            states, actions, rewards = self.trials_[int(agent.rng.integers(len(self.trials_)))]
            K = min(len(rewards), budget)
            if self.replay.order == "backward":
                for k in range(len(rewards) - 1, len(rewards) - 1 - K, -1):
                    agent._replay_transition(
                        states[k], actions[k], float(rewards[k]), states[k + 1]
                    )
            else:
                agent._learn_trial(states[: K + 1], actions[:K], rewards[:K])
            budget -= K

    def _plan(self, agent: RehearsedLearner, budget: int, trial, steps: int) -> None:
        """``budget`` simulated transitions in rollouts of ``horizon`` steps (the last one cut)."""
        model, planning = self.model, self.planning
        horizon = planning.horizon or steps
        states = trial[0]
        while budget > 0:
            if planning.start == "start":
                x = states[0]
            elif planning.start == "trajectory":
                x = states[int(agent.rng.integers(steps))]
            else:
                x = model.memory.X_[
                    int(agent.rng.integers(model.memory.n_samples_)), : self.n
                ].copy()
            H = min(horizon, budget)
            u = agent._start(x)
            for k in range(H):
                x, r = model.predict(x, np.minimum(np.maximum(u, self._low), self._high))
                if k == H - 1:
                    agent._stop(r, x, False)
                else:
                    u = agent._step(r, x)
            budget -= H

    # -- state ----------------------------------------------------------------------------------------
    def state_dict(self, prefix: str = "") -> dict[str, np.ndarray]:
        """The model's memories, the running trial's record and the stored trials (concatenated,
        with each trial's length)."""
        state = self.model.state_dict(prefix + "model.") if self.model is not None else {}
        state[prefix + "trial.states"] = np.array(self._states).reshape(-1, self.n)
        state[prefix + "trial.actions"] = np.array(self._actions).reshape(-1, self.m)
        state[prefix + "trial.rewards"] = np.array(self._rewards, dtype=float)
        if self.replay.steps:
            lengths = np.array([len(t[2]) for t in self.trials_], dtype=np.int64)
            state[prefix + "trial_lengths"] = lengths
            state[prefix + "states"] = (
                np.concatenate([t[0] for t in self.trials_])
                if self.trials_
                else np.zeros((0, self.n))
            )
            state[prefix + "actions"] = (
                np.concatenate([t[1] for t in self.trials_])
                if self.trials_
                else np.zeros((0, self.m))
            )
            state[prefix + "rewards"] = (
                np.concatenate([t[2] for t in self.trials_]) if self.trials_ else np.zeros(0)
            )
        return state

    def load_state_dict(self, state: dict[str, np.ndarray], prefix: str = "") -> None:
        if self.model is not None:
            self.model.load_state_dict(state, prefix + "model.")
        self._states = [x.copy() for x in np.asarray(state[prefix + "trial.states"], dtype=float)]
        self._actions = [u.copy() for u in np.asarray(state[prefix + "trial.actions"], dtype=float)]
        self._rewards = [float(r) for r in np.asarray(state[prefix + "trial.rewards"])]
        if self.replay.steps:
            lengths = np.asarray(state[prefix + "trial_lengths"], dtype=np.int64)
            S, U, R = (
                np.asarray(state[prefix + key], dtype=float)
                for key in ("states", "actions", "rewards")
            )
            self.trials_ = []
            s = a = 0
            for K in lengths:
                self.trials_.append(
                    (S[s : s + K + 1].copy(), U[a : a + K].copy(), R[a : a + K].copy())
                )
                s += K + 1
                a += K

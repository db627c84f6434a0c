"""Model Learning Actor-Critic (MLAC; Grondman et al., IEEE SMC-B 42(3), 2012) and its config.

Memories (RMAC paper, section 4): actor M^A [x | u], critic M^C [x | V] (Algorithm 2 lines 22-28),
process M^P [x, u | x']; the actor follows the model's gradient of the one-step return (steps:
:class:`MLAC`; choices: :class:`MLACConfig`).
"""

from __future__ import annotations

import dataclasses
from numbers import Real
from typing import Any, ClassVar

import numpy as np

from rmac_mj.agents.base import Agent, RefusedTransition
from rmac_mj.agents.critic import LLRCritic, _check_traces
from rmac_mj.agents.exploration import Exploration, model_uncertainty
from rmac_mj.agents.planning import REHEARSAL, Planning, Replay
from rmac_mj.agents.seeding import Transitions, discounted_returns, seed_memory
from rmac_mj.agents.spaces import ActionSpace, StateSpace
from rmac_mj.agents.task_knowledge import (
    memory_units,
    with_task_action_cost,
    with_task_weights,
)
from rmac_mj.approximators.llr import (
    SHARED_CONSTRAINTS,
    LLRConfig,
    LLRMemory,
    shared_settings,
    with_memory_defaults,
    wrap,
)
from rmac_mj.constraints import (
    BACKEND,
    TD_LAMBDA,
    WEIGHTS,
    InstanceOf,
    Interval,
    Options,
    check_config,
)

_MEMORIES = ("actor", "critic", "process")


@dataclasses.dataclass(frozen=True)
class MLACConfig:
    """Hyperparameters of MLAC. Defaults: the RMAC paper's gamma and lambda (section 6.2), the
    authors' group's MLAC settings for this swing-up (memory sizes, K, learning rates, weightings),
    then the documented choices (docs/mlac.md)."""

    gamma: float | None = None
    """Discount factor per control step (RMAC paper, section 6.2: 0.97 per 0.03 s); None:
    0.97 ** (dt / 0.03), the same horizon in seconds at the task's step dt."""
    lam: float | None = None
    """Trace decay lambda of the critic per control step (0.65); None: 0.65 ** (dt / 0.03)."""
    alpha_a: float = 0.05
    """Actor learning rate: the actor's samples move by alpha_a dQ/du per step."""
    alpha_c: float = 0.3
    """Critic learning rate alpha_c of the TD(lambda) update on the critic's samples."""

    actor: LLRConfig = LLRConfig(clip=False, replacement="nearest", redundancy="distance")
    """The actor's memory M^A [x | u] (2000 samples and K = 25 for n = 2, K being the samples that
    define pi(x) and move in an update; None: grown to 2000 n / 2 and 25 n / 2; weighting over x,
    None: the task's, ``StateSpace.input_weights``: (1, 0.1) for dc_pendulum, as the authors' group's
    code uses). Predictions not clipped to the neighbours' range: pi(x) is always saturated to the
    action bounds, and the actor's samples always stay inside them."""
    critic: LLRConfig = LLRConfig(clip=True, replacement="nearest", redundancy="distance")
    """The critic's memory M^C [x | V] (2000 samples and K = 15 for n = 2; None: grown to 2000 n / 2
    and 15 n / 2; weighting as the actor's). Predictions clipped to the neighbours' values (as
    RMACConfig.critic)."""
    process: LLRConfig = LLRConfig(clip=False, replacement="nearest", redundancy="misfit")
    """The process model M^P [x, u | x'] (100 samples and K = 10 for n + m = 3; None: grown to
    100 (n + m) / 3 and 10 (n + m) / 3; weighting over [x, u], None: the task's,
    ``StateSpace.input_weights`` then ``ActionSpace.input_weights``: (1, 0.1, 1) for dc_pendulum,
    as the authors' group's code). Predictions not clipped; redundancy as RMACConfig.process."""

    exploration: Exploration = Exploration()
    """Exploration Delta u_k: N(0, 1) every third step, the S-AC schedule of the RMAC paper (6.1).
    With ``where='uncertain'`` the uncertainty is the process model's at (x_k, pi(x_k)), where the
    policy acts."""
    action_cost: float | tuple[float, ...] | None = None
    """P in dr/du = -2 P u (per action dimension), the reward's action gradient; the one piece of
    reward knowledge MLAC uses. None: the task's (``ActionSpace.cost``; dc_pendulum: r = -x^T Q x -
    P u^2 with P = 1; two_link_arm: 0); a number: P in every action dimension; 0 ignores the
    reward's dependence on u. ``agent.config.action_cost`` holds the resolved tuple."""
    saturation_threshold: float = 0.92
    """The saturation rule (see ``saturation_rule``) applies to an action dimension where the
    policy's action lies beyond this fraction of the half-range from the middle of the action box
    (the model's input gain means little in saturation; the authors' group's value). 1 disables it."""
    saturation_rule: str = "outward"
    """What the saturation rule drops: only the model term that would push a saturated action
    further out ('outward'; it may still pull the action back in), or df/du entirely ('zero', the
    authors' group's rule). With action_cost 0, 'zero' leaves a saturated action no gradient at all
    (docs/mlac.md)."""
    model_action: str = "policy"
    """Where the process model is linearised and x_hat predicted: at (x_{k-1}, pi(x_{k-1})), the
    policy's action ('policy', the gradient of the policy's own return), or at (x_{k-1}, u_{k-1}),
    the action applied, exploration included ('applied')."""
    initial_value: str = "critic"
    """V_0 of a trial: the critic's estimate V(x_0) ('critic'; 0 on an empty memory) or 0 ('zero'),
    as RMACConfig.initial_value."""

    norm: int = 1
    """1- or 2-norm of the weighted input difference in all memories."""
    conditioning: str = "ridge"
    """How the local least-squares fits are conditioned: 'ridge', 'svd' or 'none' (see LLRMemory)."""
    rcond: float = 0.01
    """Relative singular value cutoff for conditioning='svd'."""
    ridge: float = 1e-3
    """Ridge term for conditioning='ridge', in weighted input units squared."""
    redundancy_smoothing: float = 0.1
    """eta in (0, 1], the smoothing of every redundancy score (as RMACConfig)."""
    planning: Planning = Planning()
    """Simulated transitions in learned models between trials (``agents.planning``): the
    rollouts run this algorithm, step 1 excepted. None by default."""
    replay: Replay = Replay()
    """Replay of stored real trials between trials (``agents.planning``). None by default."""
    backend: str = "numba"
    """Back end of the LLR memories: 'numba' (compiled) or 'numpy' (reference); same results."""

    #: The fields set from the task when left None: field -> (rule, value at the paper's pendulum)
    #: (``task_knowledge.with_task_units``).
    task_units: ClassVar[dict[str, tuple[str, float]]] = {
        "gamma": ("horizon", 0.97),
        "lam": ("horizon", 0.65),
        **memory_units("actor", "states", 2000, 25),
        **memory_units("critic", "states", 2000, 15),
        **memory_units("process", "transitions", 100, 10),
    }
    parameter_constraints: ClassVar[dict[str, list]] = {
        **TD_LAMBDA,
        "alpha_a": [Interval(Real, 0, 1)],
        **{memory: [InstanceOf(LLRConfig)] for memory in _MEMORIES},
        "exploration": [InstanceOf(Exploration)],
        "action_cost": [Interval(Real, 0, None), WEIGHTS, None],
        "saturation_threshold": [Interval(Real, 0, 1, closed="right")],
        "saturation_rule": [Options("zero", "outward")],
        "model_action": [Options("policy", "applied")],
        "initial_value": [Options("critic", "zero")],
        **SHARED_CONSTRAINTS,
        **REHEARSAL,
        "backend": BACKEND,
    }

    def __post_init__(self) -> None:
        check_config(self)
        with_memory_defaults(self)


#: Values (of the critic, after an update) beyond which the actor's gradient may overflow: a
#: transition that reaches them is learned so that a refused actor step changes nothing. Below,
#: the critic's slopes times the process model's stay far inside the float range.
RISKY_VALUE = 1e100


class MLAC(Agent):
    """The MLAC learner over a flat state box and a bounded action.

    What sets MLAC apart from S-AC is the actor update: instead of moving the policy along the
    exploration Delta u weighted by the TD error (S-AC, eq. 4 of the RMAC paper), the actor's
    samples near x_{k-1} move along the gradient of the one-step return Q(x, u) = r(x, u) + gamma
    V(f(x, u))
    with respect to u, at the policy's action u_pi = pi(x_{k-1})::

        dQ/du = gamma (dV/dx at x_hat)^T (df/du at (x_{k-1}, u_pi)) + dr/du(u_pi),
        x_hat = f(x_{k-1}, u_pi)                       (the process model's prediction)

    df/du is beta^P's u block from the local fit that predicts x_hat; dV/dx the slope of the
    critic's local fit at x_hat. Where the policy's action is saturated (``saturation_threshold``),
    the model term is dropped when it would push the action further out (``saturation_rule``). Per
    control step k (model, critic, actor, then act):

    1. insert [x_{k-1}, u_{k-1} | x_k] in M^P;
    2. V_k = V(x_k); insert [x_{k-1} | V_{k-1}] in M^C; delta_k = r_k + gamma V_k - V_{k-1}; traces
       1 on K(x_{k-1}) and the inserted slot, lambda gamma e elsewhere; V_i += alpha_c delta_k e_i;
    3. u_pi = pi(x_{k-1}); insert [x_{k-1} | u_pi] in M^A; the samples K(x_{k-1}) and the inserted
       one move by alpha_a dQ/du (each kept inside the action bounds);
    4. u_k = pi(x_k) + Delta u_k, saturated.

    The reward's action gradient is the one piece of reward knowledge MLAC uses: ``action_cost`` P
    gives dr/du = -2 P u, right for a reward with the term -sum_i P_i u_i^2; it comes from the task
    (``ActionSpace.cost``), and 0 drops the term. Prior knowledge seeds the memories through
    :meth:`Agent.seed_from`.

    Args:
      state_space: the n-dimensional state (periodic dimensions are wrapped in every memory).
      action_space: the m-dimensional action box; the actor's samples stay inside it.
      config: hyperparameters; the weightings must have n (actor, critic) and n + m (process) entries.
      seed: seed or Generator of the exploration noise, the only randomness.

    Learned state: the memories ``actor`` and ``process`` (:class:`LLRMemory`) and the ``critic``
    (:class:`LLRCritic`, shared with RMAC: its memory and one eligibility trace per sample).
    """

    name = "mlac"
    display_name = "MLAC"
    config_class = MLACConfig

    def __init__(
        self,
        state_space: StateSpace,
        action_space: ActionSpace,
        config: MLACConfig = MLACConfig(),
        seed: int | np.random.Generator | None = None,
    ) -> None:
        super().__init__(state_space, action_space, config, seed)
        n, m = state_space.dim, action_space.dim
        self.n, self.m = n, m
        self.period = state_space.period  # (n,), 0 for non-periodic dimensions
        config = with_task_weights(
            "MLAC", self.config, state_space, action_space, ("actor", "critic")
        )
        self.config = config = with_task_action_cost(
            "MLAC", config, action_space, "the actor's gradient"
        )
        self._action_cost = np.array(config.action_cost)  # P, shape (m,)
        self.actor, critic_memory, self.process = self._new_memories(config)
        self.critic = LLRCritic(critic_memory, config.gamma, config.lam, config.alpha_c)
        #: The middle and half-width of the action box, for the saturation rule.
        self._u_mid = 0.5 * (action_space.low + action_space.high)
        self._u_half = 0.5 * (action_space.high - action_space.low)
        self._k = 0
        self._x_prev = np.zeros(n)
        self._u_prev = np.zeros(m)
        self._v_prev = 0.0
        #: (pi(x_{k-1}), K(x_{k-1})) found when acting in x_{k-1}: saves one actor query per step.
        #: Derived state (None: recompute), so it is not part of the state dict.
        self._pi_prev: tuple[np.ndarray, np.ndarray] | None = None
        #: Whether step 1 inserts a transition in M^P: False while rehearsing (planning, replay).
        self._learns_model = True

    def _new_memories(self, config: MLACConfig) -> tuple[LLRMemory, LLRMemory, LLRMemory]:
        """The actor [x | u], the critic's [x | V] and the process model [x, u | x'], empty."""
        n, m, period, shared = self.n, self.m, self.period, shared_settings(config)
        return (
            config.actor.memory(n, m, shared, input_period=period),
            config.critic.memory(n, 1, shared, input_period=period),
            config.process.memory(
                n + m, n, shared, input_period=np.r_[period, np.zeros(m)], output_period=period
            ),
        )

    def _set_rehearsing(self, rehearsing: bool) -> None:
        """While rehearsing (planning, replay), step 1 leaves M^P unchanged."""
        self._learns_model = not rehearsing

    @classmethod
    def _memory_parts(
        cls, config: MLACConfig, state_space: StateSpace, action_space: ActionSpace
    ) -> tuple[int, int]:
        """The three memories and the critic's traces (see :meth:`Agent.memory_estimate`)."""
        n, m = state_space.dim, action_space.dim
        parts = (
            config.actor.estimate(n, m),
            config.critic.estimate(n, 1),
            config.process.estimate(n + m, n),
        )
        traces = 8 * config.critic.capacity
        return tuple(sum(part) + traces for part in zip(*parts))

    # -- the policy -----------------------------------------------------------------------------------
    def _pi(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """pi(x), saturated to the action bounds, and the actor's neighbours K(x) (nearest first)."""
        u, _, near = self.actor.query(x)
        return self.action_space.clip(u), near

    def policy(self, states: Any) -> np.ndarray:
        """pi(x) for a batch of states (shape (q, n)) without exploration; returns shape (q, m)."""
        states = np.asarray(states, dtype=float).reshape(-1, self.n)
        if not np.all(np.isfinite(states)):
            raise ValueError("MLAC.policy: states must be finite")
        return self.action_space.clip(self.actor.predict(states))

    # -- the model-based actor gradient ---------------------------------------------------------------
    def saturated(self, u: np.ndarray) -> np.ndarray:
        """Bool (m,): where u lies beyond ``saturation_threshold`` of the half-range from the middle
        of the action box: the dimensions the saturation rule applies to."""
        return np.abs(u - self._u_mid) > self.config.saturation_threshold * self._u_half

    def action_gradient(
        self, x: np.ndarray, u_pi: np.ndarray, u_model: np.ndarray | None = None
    ) -> np.ndarray:
        """dQ/du = gamma (dV/dx at x_hat)^T df/du + dr/du at (x, u_pi); shape (m,).

        x: the state (shape (n,), canonical); u_pi: the policy's action there (shape (m,)); u_model:
        where the process model is linearised (default u_pi, see MLACConfig.model_action).
        """
        cfg, n = self.config, self.n
        u_model = u_pi if u_model is None else u_model
        # The process model's local fit at (x, u_model): x_hat and beta^P = [df/dx df/du df_b].
        x_hat, beta_p, _ = self.process.query(np.concatenate([x, u_model]))
        df_du = beta_p[:, n : n + self.m]  # (n, m)
        # The critic's local fit at the predicted next state: its slope is dV/dx (x_hat is wrapped
        # by the query; the slope holds for wrapped offsets).
        dv_dx = self.critic.memory.query(x_hat)[1][0, :n]  # (n,)
        model_term = cfg.gamma * dv_dx @ df_du  # (m,), column j is df/du_j's share
        # The saturation rule: df/du_j = 0 where the policy's action is saturated ('zero'), or only
        # where the model term would push it further out ('outward').
        ignored = self.saturated(u_pi)
        if cfg.saturation_rule == "outward":
            ignored &= model_term * (u_pi - self._u_mid) > 0
        model_term[ignored] = 0.0
        dr_du = -2.0 * self._action_cost * u_pi  # reward term -sum_i P_i u_i^2
        return model_term + dr_du

    def _improve_actor(
        self, x: np.ndarray, u: np.ndarray, policy: tuple[np.ndarray, np.ndarray] | None
    ) -> None:
        """Step 3: insert [x | pi(x)], move it and K(x) along alpha_a dQ/du. ``policy``: (pi(x),
        K(x)) when known (found when u was chosen in x: the actor has not changed since), else
        None."""
        u_pi, near = policy if policy is not None else self._pi(x)
        u_model = u_pi if self.config.model_action == "policy" else u
        step = self.config.alpha_a * self.action_gradient(x, u_pi, u_model)
        if not np.all(np.isfinite(step)):
            raise self._overflow("the actor's step along dQ/du")
        slot = self.actor.insert(x, u_pi, nearest=int(near[0]) if len(near) else None)
        # When the memory is full the new sample may take a neighbour's slot: move each sample once.
        moved = near if slot in near else np.append(near, slot)
        before = self.actor.outputs(moved)
        self.actor.adjust(moved, self.action_space.clip(before + step) - before)

    # -- Agent interface ------------------------------------------------------------------------------
    def _act(self, x: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """Step 4: u = pi(x) + Delta u_k, saturated; a given u (replay) is taken as it is."""
        self._pi_prev = self._pi(x)  # kept for the next actor update (x becomes x_{k-1})
        if u is not None:
            return u.copy()
        exploration = self.config.exploration
        uncertainty = None
        if exploration.where == "uncertain":  # the process model where the policy acts: (x, pi(x))
            query = np.concatenate([x, self._pi_prev[0]])
            uncertainty = lambda: model_uncertainty(self.process, query)  # noqa: E731
        du = exploration.sample(self._k, self.m, self.rng, self.trial, uncertainty)
        return self.action_space.clip(self._pi_prev[0] + du)

    def _start(self, x0: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """A trial begins: traces reset, V_0, u_0 = pi(x_0) + Delta u_0 (or the given u_0)."""
        x0 = self.state_space.canonical(x0)
        self.critic.begin_trial()
        self._k = 0
        self._v_prev = self.critic.value(x0) if self.config.initial_value == "critic" else 0.0
        u = self._act(x0, u)
        self._x_prev, self._u_prev = x0, u
        return u.copy()

    def _step(self, reward: float, x: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """Learn from (x_{k-1}, u_{k-1}, r_k, x_k) (steps 1-3), then act in x_k (step 4; a given u_k
        when replaying)."""
        x = self.state_space.canonical(x)
        self._v_prev = self._learn(
            self._x_prev, self._u_prev, reward, x, self._v_prev, self._learns_model, self._pi_prev
        )
        self._k += 1
        u = self._act(x, u)
        self._x_prev, self._u_prev = x, u
        return u.copy()

    def _stop(self, reward: float, x: np.ndarray, terminal: bool) -> None:
        """The trial's last transition is learned like any other (a time limit), or with V(x_K) = 0
        when x_K is terminal."""
        self._learn(
            self._x_prev,
            self._u_prev,
            reward,
            self.state_space.canonical(x),
            self._v_prev,
            self._learns_model,
            self._pi_prev,
            terminal,
        )

    def _learn_transition(
        self, x: np.ndarray, u: np.ndarray, reward: float, x_next: np.ndarray, v: float, model: bool
    ) -> float:
        """:meth:`Agent.learn`: steps 1-3 for one transition (``model=False``: without step 1)."""
        x, x_next = self.state_space.canonical(x), self.state_space.canonical(x_next)
        return self._learn(x, u, reward, x_next, v, model, None)

    def _learn(
        self,
        x: np.ndarray,
        u: np.ndarray,
        reward: float,
        x_next: np.ndarray,
        v: float,
        model: bool,
        policy: tuple[np.ndarray, np.ndarray] | None,
        terminal: bool = False,
    ) -> float:
        """Steps 1-3 of :class:`MLAC` for canonical states; returns V(x') (0 for a
        ``terminal`` x', whose value the TD error then does not bootstrap from)."""
        v_next = 0.0 if terminal else self.critic.next_value(x_next)
        bound = self.critic.update_bound(v, reward, v_next)
        if not np.isfinite(bound):  # refused before anything changes
            raise self._overflow(f"the TD error with reward {reward!r}")
        # The actor's step is known only once the process model and the critic have learned. Its
        # gradient can overflow only with values near the largest float (the process model's
        # samples are states within the learner's limits): then steps 1 and 2 are kept aside, and
        # put back if the step is refused.
        before = self._learned_models() if bound > RISKY_VALUE else None
        if model:  # 1. The process model learns the transition.
            self.process.insert(np.concatenate([x, u]), x_next)
        # 2. TD(lambda) on the critic's samples (RMAC paper, Algorithm 2 lines 22-28).
        self.critic.td_update(x, v, reward, v_next)
        # 3. The actor moves along the model-based gradient of the return.
        try:
            self._improve_actor(x, u, policy)
        except RefusedTransition:
            if before is None:  # a gradient that overflowed below RISKY_VALUE: nothing to put back
                raise
            self._restore_models(before)
            raise
        return v_next

    def _learned_models(self) -> dict[str, np.ndarray]:
        """What steps 1 and 2 change (the process model, the critic and its traces), to put back."""
        state = self.process.state_dict("process.")
        state.update(self.critic.memory.state_dict("critic."))
        state["traces"] = self.critic.traces.copy()
        return state

    def _restore_models(self, state: dict[str, np.ndarray]) -> None:
        self.process.load_state_dict(state, "process.")
        self.critic.memory.load_state_dict(state, "critic.")
        self.critic.traces[:] = state["traces"]

    def _greedy_action(self, x: np.ndarray) -> np.ndarray:
        """pi(x), saturated; no exploration, no learning, nothing carried between calls."""
        return self._pi(self.state_space.canonical(x))[0]

    def _value(self, x: np.ndarray) -> float:
        """V(x), the critic's LLR estimate."""
        return self.critic.value(self.state_space.canonical(x))

    # -- prior knowledge ------------------------------------------------------------------------------
    #: What :meth:`Agent.seed_from` can initialise from recorded transitions.
    prior_parts = ("process", "critic", "actor")

    def _seed_from(self, transitions: Transitions, parts: tuple[str, ...]) -> None:
        """Initialise the memories from a demonstration (section 7 of the RMAC paper): the actor with
        its (x_t, u_t), the critic with its discounted returns-to-go (this agent's gamma, 0 after a
        trial's last transition), the process model with its transitions [x_t, u_t] -> x_{t+1}.

        Up to each memory's capacity the memory holds exactly these samples; the rest are inserted
        in time order through its replacement rule (``seed_memory``).
        """
        actions = transitions.actions
        x = wrap(transitions.states, self.period)
        x_next = wrap(transitions.next_states, self.period)
        returns = discounted_returns(transitions.rewards, transitions.trial, self.config.gamma)
        data = {
            "actor": (x, actions),
            "critic": (x, returns[:, None]),
            "process": (np.hstack([x, actions]), x_next),
        }
        if "actor" in parts and np.any(
            (actions < self.action_space.low) | (actions > self.action_space.high)
        ):
            raise ValueError(
                "MLAC.seed_from: actions must lie inside the action bounds "
                f"[{self.action_space.low}, {self.action_space.high}]"
            )
        for name in parts:
            seed_memory(self._memories()[name], *data[name])
        self._pi_prev = None
        if "critic" in parts:
            self.critic.begin_trial()

    # -- state ----------------------------------------------------------------------------------------
    def _memories(self) -> dict[str, LLRMemory]:
        """The actor's, the critic's and the process model's memories, by their names in the
        learner's state and config (_MEMORIES)."""
        return {
            name: self.critic.memory if name == "critic" else getattr(self, name)
            for name in _MEMORIES
        }

    def _state(self) -> dict[str, np.ndarray]:
        """The three memories, the critic's traces and the running trial's bookkeeping."""
        state: dict[str, np.ndarray] = {}
        for name, memory in self._memories().items():
            state.update(memory.state_dict(prefix=f"{name}."))
        state["traces"] = self.critic.traces.copy()
        state["k"] = np.array(self._k)
        state["x_prev"] = self._x_prev.copy()
        state["u_prev"] = self._u_prev.copy()
        state["v_prev"] = np.array(self._v_prev)
        return state

    def _may_lack(self, key: str) -> bool:
        return super()._may_lack(key) or key.endswith(".redundancy")  # older snapshots

    def _check_state(self, state: dict[str, np.ndarray]) -> None:
        for name, memory in self._memories().items():
            memory.check_state_dict(state, prefix=f"{name}.")
        _check_traces(self.name, state)

    def _load_state(self, state: dict[str, np.ndarray]) -> None:
        for name, memory in self._memories().items():
            memory.load_state_dict(state, prefix=f"{name}.")
        self.critic.traces[:] = state["traces"]
        self._k = int(state["k"])
        self._x_prev = np.array(state["x_prev"], dtype=float)
        self._u_prev = np.array(state["u_prev"], dtype=float)
        self._v_prev = float(state["v_prev"])
        self._pi_prev = None

"""Reference Model Actor-Critic (RMAC): section 5 and Algorithm 2 of Grondman et al.

Three LLR memories (section 4): M^P [x, u | x'], M^R [x | x_hat], M^C [x | V]; u_k = f^-1(x_k,
R(x_k)) + exploration. The class reads in the paper's order: the memories, then Algorithm 2
(a trial's start, a control step, one transition's learning, lines 1-29), then acting greedily,
prior knowledge and the learned state; the options beyond the paper (``RMACConfig``'s reachable
rules other than the vertices) are :mod:`rmac_mj.agents.rmac_variants`. The numpy path follows
Algorithm 2 line by line, ``backend='numba'`` runs :mod:`rmac_mj.agents._rmac_kernels`.
"""

from __future__ import annotations

import itertools

import numpy as np

from rmac_mj.agents import _rmac_kernels, rmac_variants
from rmac_mj.agents.base import Agent, RefusedTransition
from rmac_mj.agents.critic import LLRCritic, _check_traces
from rmac_mj.agents.exploration import model_uncertainty
from rmac_mj.agents.rmac_config import REACHABLE_RULES, RMACConfig
from rmac_mj.agents.seeding import Transitions, discounted_returns, seed_memory
from rmac_mj.agents.spaces import ActionSpace, StateSpace
from rmac_mj.agents.task_knowledge import with_task_action_cost, with_task_weights
from rmac_mj.approximators.llr import LLRMemory, shared_settings, wrap

__all__ = ["RMAC", "RMACConfig"]

#: beta_u counts as zero (u = 0, section 5) below this fraction of the state gains: when every
#: neighbour of the process model holds the same action, the truncated fit removes the u direction
#: and rounding alone would otherwise decide a saturated action's sign.
BETA_U_ZERO = 1e-9
#: ``du`` of the compiled step's last transition of a trial, which takes no action.
_NO_ACTION = np.empty(0)


class RMAC(Agent):
    """The RMAC learner (Algorithm 2) over a flat state box and a bounded action.

    The action is the least-squares inverse of the local process model x' = beta^P [x; u; 1] for the
    desired state, u_k = f^-1(x_k, R(x_k)) (+ exploration). The reference model is moved towards the
    best reachable state x_r: the vertex of the reachable set (all 2^m combinations of action
    extremes applied to the local process model) with the highest value under the critic's local
    linear model. The critic (:class:`~rmac_mj.agents.critic.LLRCritic`, shared with MLAC) learns by
    TD(lambda). ``learn`` (:meth:`Agent.learn`) is one transition's update (lines 13-28), the same
    for a real and a simulated transition (which leaves the process model alone).

    Args:
      state_space: the n-dimensional state (periodic dimensions are wrapped in every memory).
      action_space: the m-dimensional action box; its 2^m vertices span the reachable set.
      config: hyperparameters; the weightings must have n (critic, reference) and n + m (process)
        entries, and those left None are taken from the spaces' ``input_weights``, the action cost
        from ``ActionSpace.cost`` (``self.config`` holds the resolved values).
      seed: seed or Generator of the exploration noise, the only randomness.

    Learned state: the memories ``process`` and ``reference`` (:class:`LLRMemory`) and the ``critic``
    (:class:`LLRCritic`: its memory and traces).
    """

    name = "rmac"
    display_name = "RMAC"
    config_class = RMACConfig
    prior_parts = ("process", "reference", "critic")

    def __init__(
        self,
        state_space: StateSpace,
        action_space: ActionSpace,
        config: RMACConfig = RMACConfig(),
        seed: int | np.random.Generator | None = None,
    ) -> None:
        super().__init__(state_space, action_space, config, seed)
        self.config = config = self._with_task_knowledge(self.config)
        self.n, self.m = n, m = state_space.dim, action_space.dim
        if config.reachable_rule == "exact" and m != 1:
            raise ValueError(
                f"RMAC: config.reachable_rule='exact' needs a one-dimensional action, "
                f"this task has {m}; use 'grid'"
            )
        self.period = state_space.period  # (n,), 0 for non-periodic dimensions
        # Section 4's memories: M^P [x, u | x'], M^R [x | x_hat], and M^C [x | V] in the critic.
        self.process, self.reference, critic_memory = self._new_memories(config)
        alpha_c, self._alpha_r = config.rates_at(self.trial)
        self.critic = LLRCritic(critic_memory, config.gamma, config.lam, alpha_c)
        self._rates_trial = self.trial
        #: U_R without the state rows: the 2^m combinations of action extremes, (2^m, m), max first.
        self.vertices = np.array(
            list(
                itertools.product(
                    *[(hi, lo) for lo, hi in zip(action_space.low, action_space.high)]
                )
            ),
            dtype=float,
        )
        #: The candidate actions of the reachable rule, (c, m), and the golden-section steps of
        #: 'exact' (:mod:`rmac_mj.agents.rmac_variants`).
        low, high, grid = action_space.low, action_space.high, config.reachable_grid
        rule = config.reachable_rule
        self.candidates = rmac_variants.candidate_actions(rule, grid, low, high, self.vertices)
        self._refine_steps = rmac_variants.refine_steps(rule, grid, low, high)
        # The step's bookkeeping: k, and x_{k-1}, u_{k-1} and V_{k-1} updated in place (the
        # compiled step shares these arrays); the last greedy action.
        self._k = 0
        self._x_prev, self._u_prev, self._v_prev = np.zeros(n), np.zeros(m), np.zeros(1)
        self._u_greedy = np.zeros(m)
        #: Whether line 14 inserts a transition in M^P: False while rehearsing (planning, replay).
        self._learns_model = True
        self._kernel_state = self._new_kernel_state()
        # the compiled step's type switch: np.linalg.pinv is compiled only for several actions
        self._several_actions = True if m > 1 else None

    def _with_task_knowledge(self, config: RMACConfig) -> RMACConfig:
        """The config with the weightings and the action cost left None taken from the task."""
        config = with_task_weights(
            "RMAC", config, self.state_space, self.action_space, ("critic", "reference")
        )
        config = with_task_action_cost(
            "RMAC",
            config,
            self.action_space,
            None
            if config.reachable_rule == "vertices"
            else f"reachable_rule={config.reachable_rule!r}",
        )
        #: P of the reachable rules' score (zeros when the rule does not use it), shape (m,).
        self._action_cost = np.array(
            config.action_cost or np.zeros(self.action_space.dim), dtype=float
        )
        return config

    def _new_memories(self, config: RMACConfig) -> tuple[LLRMemory, LLRMemory, LLRMemory]:
        """M^P [x, u | x'], M^R [x | x_hat] and M^C [x | V] (section 4), empty."""
        n, m, period, shared = self.n, self.m, self.period, shared_settings(config)
        return (
            config.process.memory(
                n + m, n, shared, input_period=np.r_[period, np.zeros(m)], output_period=period
            ),
            config.reference.memory(n, n, shared, input_period=period, output_period=period),
            config.critic.memory(n, 1, shared, input_period=period),
        )

    # -- Algorithm 2, lines 1-12: a trial's start and a control step -----------------------------
    def _start(self, x0: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """Lines 1-6: reset the traces, u_0 = f^-1(x_0, R(x_0)) + Delta u_0 (or the given u_0, when
        replaying)."""
        x0 = self.state_space.canonical(x0)
        self.critic.begin_trial()  # line 3
        self._k = 0
        self._u_greedy = np.zeros(self.m)
        self._v_prev[0] = self.critic.value(x0) if self.config.initial_value == "critic" else 0.0
        if u is None:
            u = self._explore(self._act(x0, np.zeros(self.m)), x0, np.zeros(self.m))  # line 5
        self._x_prev[:] = x0
        self._u_prev[:] = u
        return u.copy()

    def _step(self, reward: float, x: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """Lines 8-29 for one control step: act with the current models, then learn. A given u_k
        (replay) is taken as the action: lines 13-28 only. A refused transition leaves the step
        count as it was (the memories and x_prev, u_prev, v_prev are left by ``_learn``)."""
        self._k += 1
        try:
            return self._control_step(reward, x, u)
        except RefusedTransition:
            self._k -= 1
            raise

    def _control_step(self, reward: float, x: np.ndarray, u: np.ndarray | None) -> np.ndarray:
        self._sync_rates()
        if u is None and self._kernel_state is not None:
            du = self._noise(x, self._u_prev)  # line 8
            # Lines 10-28 in one compiled call (x wrapped there), which also advances x_prev,
            # u_prev and v_prev; it returns a new array.
            u, v = _rmac_kernels.step(
                self._kernel_state,
                reward,
                x,
                du,
                self._learns_model,
                False,
                False,
                self._several_actions,
            )
            if v != v:
                raise self._overflow(reward)
            return u
        x = self.state_space.canonical(x)
        if u is None:
            u = self._explore(self._act(x, self._u_prev), x, self._u_prev)  # lines 10-12
        self._v_prev[0] = self._learn(
            self._x_prev, self._u_prev, reward, x, float(self._v_prev[0]), self._learns_model
        )  # lines 13-28
        self._x_prev[:] = x
        self._u_prev[:] = u
        return u.copy()

    def _stop(self, reward: float, x: np.ndarray, terminal: bool) -> None:
        """The last transition of a trial: learn (lines 13-28; a ``terminal`` x has V(x) = 0 in
        the TD error), no action."""
        self._sync_rates()
        if self._kernel_state is not None:
            _, v = _rmac_kernels.step(
                self._kernel_state,
                reward,
                x,
                _NO_ACTION,
                self._learns_model,
                True,
                bool(terminal),
                self._several_actions,
            )
            if v != v:
                raise self._overflow(reward)
        else:
            self._learn(
                self._x_prev,
                self._u_prev,
                reward,
                self.state_space.canonical(x),
                float(self._v_prev[0]),
                self._learns_model,
                terminal,
            )
        self._u_greedy = np.zeros(self.m)  # a greedy trial that follows starts from u_{-1} = 0

    def _noise(self, x: np.ndarray, u_prev: np.ndarray) -> np.ndarray:
        """Delta u_k of line 8 for step k in x_k, after u_{k-1} (see ``RMACConfig.exploration``)."""
        exploration = self.config.exploration
        uncertainty = None
        if exploration.where == "uncertain":
            query = np.concatenate([x, self._u_query(u_prev)])
            uncertainty = lambda: model_uncertainty(self.process, query)  # noqa: E731
        return exploration.sample(self._k, self.m, self.rng, self.trial, uncertainty)

    def _explore(self, u_greedy: np.ndarray, x: np.ndarray, u_prev: np.ndarray) -> np.ndarray:
        du = self._noise(x, u_prev)  # line 8
        return np.minimum(np.maximum(u_greedy + du, self.action_space.low), self.action_space.high)

    # -- the policy: u = f^-1(x, R(x)) (lines 10-11) ---------------------------------------------
    def _act(self, x: np.ndarray, u_prev: np.ndarray) -> np.ndarray:
        """The greedy action in x: lines 10-11 without Delta u_k."""
        x_desired = self.reference.query(x)[0]  # line 10: x_hat_{k+1} = R(x_k)
        return self._inverse(x, x_desired, self._u_query(u_prev))

    def _inverse(self, x: np.ndarray, x_desired: np.ndarray, u_query: np.ndarray) -> np.ndarray:
        """f^-1(x, x_desired): least-squares inverse of the local process model (section 5).

        The model is linearised at (x, u_query): x' = f(x, u_query) + beta_u (u - u_query), so
        u = u_query + pinv(beta_u) wrap(x_desired - f(x, u_query)), which is the paper's
        u = pinv(beta_u) (x_desired - beta_x x - beta_b) written around the query point. Returns
        u = 0 when beta_u = 0 (numerically: see BETA_U_ZERO; section 5); saturated to the action bounds.
        """
        pred, beta, _ = self.process.query(np.concatenate([x, u_query]))
        beta_u = beta[:, self.n : self.n + self.m]
        if np.abs(beta_u).max() <= BETA_U_ZERO * max(1.0, np.abs(beta[:, : self.n]).max()):
            return np.zeros(self.m)
        u = u_query + np.linalg.pinv(beta_u) @ wrap(x_desired - pred, self.period)
        return self.action_space.clip(u)

    def _u_query(self, u_prev: np.ndarray) -> np.ndarray:
        return u_prev if self.config.inverse_query == "previous" else np.zeros(self.m)

    # -- one transition: lines 13-28 -------------------------------------------------------------
    def _learn_transition(
        self, x: np.ndarray, u: np.ndarray, reward: float, x_next: np.ndarray, v: float, model: bool
    ) -> float:
        """:meth:`Agent.learn`: lines 13-28 for one transition (``model=False``: without line 14)."""
        x, x_next = self.state_space.canonical(x), self.state_space.canonical(x_next)
        self._sync_rates()
        if self._kernel_state is not None:
            v_next = _rmac_kernels.learn(self._kernel_state, x, u, reward, x_next, v, model, False)
            if np.isnan(v_next):
                raise self._overflow(reward)
            return v_next
        return self._learn(x, u, reward, x_next, v, model)

    def _learn(
        self,
        x: np.ndarray,
        u: np.ndarray,
        reward: float,
        x_next: np.ndarray,
        v: float,
        model: bool,
        terminal: bool = False,
    ) -> float:
        """Lines 13-28 (reference implementation) for canonical states; returns V(x') (line 22).
        ``terminal``: x' is terminal, its value 0 in the TD error (no bootstrap)."""
        cfg, n = self.config, self.n
        # Line 22 first: V(x') and its local model do not depend on M^P, and a TD error that
        # overflows is refused before any memory changes.
        v_next, beta_c, _ = self.critic.memory.query(x_next)
        v_next = float(v_next[0])
        if self.critic.overflows(v, reward, 0.0 if terminal else v_next):
            raise self._overflow(reward)
        if model:  # line 14: insert [x, u | x'] in M^P
            self.process.insert(np.concatenate([x, u]), x_next)
        # Line 16: the best reachable state. X_R = beta^P U_R, linearised at (x, u).
        pred, beta, _ = self.process.query(np.concatenate([x, u]))
        beta_u = beta[:, n : n + self.m]
        if cfg.reachable_rule == "vertices":
            reachable = pred + (self.vertices - u) @ beta_u.T  # (2^m, n)
            # The critic's local linear model, V(y) = V(x_c) + beta^C_x wrap(y - x_c).
            if cfg.critic_gradient_at == "next":
                x_c, slope = x_next, beta_c[0, :n]
            else:
                x_c, slope = x, self.critic.memory.query(x)[1][0, :n]
            values = wrap(reachable - x_c, self.period) @ slope
            x_r = self.state_space.canonical(reachable[int(np.argmax(values))])
        else:  # the other rules: r + gamma V(x') with the full critic (RMACConfig.reachable_rule)
            x_r = self._best_scored(pred, beta_u, u)
        # x_r is a state the process model predicts from its finite samples: finite.
        # Lines 17-20: insert [x | x_r] in M^R and move K(x) towards x_r.
        near = self.reference.neighbours(x)
        inserted = x_r
        if cfg.reference_insert_rate < 1.0 and len(near):  # R(x) moved towards x_r
            r_x = self.reference.query(x)[0]
            inserted = self.state_space.canonical(
                r_x + cfg.reference_insert_rate * wrap(x_r - r_x, self.period)
            )
        self.reference.insert(x, inserted, int(near[0]) if len(near) else None)
        self.reference.move_outputs(near, x_r, self._alpha_r)
        # Lines 22-28: TD(lambda) on the critic's samples, V(x') from above (line 22).
        self.critic.td_update(x, v, reward, 0.0 if terminal else v_next)
        return v_next

    # -- acting without learning -----------------------------------------------------------------
    def begin_greedy_trial(self) -> None:
        """A greedy trial starts, like a learning one, from u_{-1} = 0."""
        self._u_greedy = np.zeros(self.m)

    def _greedy_action(self, x: np.ndarray) -> np.ndarray:
        """u = f^-1(x, R(x)) without exploration or learning, as in a greedy trial.

        With inverse_query='previous' the process model is linearised, as while learning, at the
        previous action: the one greedy_action returned last (0 after start() and stop()). For a
        stateless map over many states (policy plots) use :meth:`policy`.
        """
        x = self.state_space.canonical(x)
        u = self._act(x, self._u_greedy)
        self._u_greedy = u
        return u.copy()

    def _value(self, x: np.ndarray) -> float:
        """V(x), the critic's LLR estimate."""
        return self.critic.value(self.state_space.canonical(x))

    def policy(self, states: np.ndarray, u_query: np.ndarray | None = None) -> np.ndarray:
        """u = f^-1(x, R(x)) without exploration for a batch of states (policy plots, Fig. 4).

        states: shape (q, n); u_query: shape (m,) or (q, m), where the process model is linearised
        (default 0). Returns shape (q, m).
        """
        states = np.asarray(states, dtype=float).reshape(-1, self.n)
        if not np.all(np.isfinite(states)):
            raise ValueError("RMAC.policy: states must be finite")
        uq = np.broadcast_to(
            np.zeros(self.m) if u_query is None else np.asarray(u_query, dtype=float),
            (len(states), self.m),
        )
        out = np.empty((len(states), self.m))
        for i, x in enumerate(states):
            x = self.state_space.canonical(x)
            out[i] = self._inverse(x, self.reference.query(x)[0], uq[i])
        return out

    # -- the reachable rules beyond the paper (rmac_variants) ------------------------------------
    def _reachable_score(
        self, u: np.ndarray, pred: np.ndarray, beta_u: np.ndarray, u_model: np.ndarray
    ) -> tuple[float, np.ndarray]:
        """-sum_i P_i u_i^2 + gamma V(x'(u)) and x'(u) (canonical), x'(u) = pred + beta_u (u -
        u_model), the process model's local fit at (x, u_model) extended to u."""
        x_next = self.state_space.canonical(pred + beta_u @ (u - u_model))
        value = self.critic.value(x_next)
        return -float(np.sum(self._action_cost * (u * u))) + self.config.gamma * value, x_next

    def _best_scored(self, pred: np.ndarray, beta_u: np.ndarray, u_model: np.ndarray) -> np.ndarray:
        """x_r for the reachable rules other than 'vertices' (``rmac_variants.best_scored``): the
        candidate action with the highest -P |u|^2 + gamma V(x'(u)) under the full LLR critic;
        returns its predicted next state."""
        return rmac_variants.best_scored(
            lambda u: self._reachable_score(u, pred, beta_u, u_model),
            self.candidates,
            self._refine_steps,
            float(self.action_space.low[0]),
            float(self.action_space.high[0]),
            self.config.reachable_grid,
        )

    # -- prior knowledge (section 7) -------------------------------------------------------------
    def _seed_from(self, transitions: Transitions, parts: tuple[str, ...]) -> None:
        """Initialise the memories from recorded transitions instead of empty (section 7).

        * 'process': M^P <- [x_t, u_t | x_{t+1}], the recorded dynamics;
        * 'reference': M^R <- [x_t | x_{t+1}], the demonstrated closed loop as the desired behaviour
          (every desired state was reached, so it is reachable);
        * 'critic': M^C <- [x_t | G_t], the discounted returns-to-go within each recorded trial with
          this agent's gamma, 0 after a trial's last transition (see ``prior_knowledge.discounted_returns``).

        Each memory holds exactly the samples when they fit, otherwise they pass through its
        replacement rule in time order (``prior_knowledge.seed_memory``). Angles are wrapped as when learning.
        """
        x = wrap(transitions.states, self.state_space.period)
        x_next = wrap(transitions.next_states, self.state_space.period)
        if "process" in parts:
            seed_memory(self.process, np.hstack([x, transitions.actions]), x_next)
        if "reference" in parts:
            seed_memory(self.reference, x, x_next)
        if "critic" in parts:
            returns = discounted_returns(transitions.rewards, transitions.trial, self.config.gamma)
            seed_memory(self.critic.memory, x, returns[:, None])

    # -- state -----------------------------------------------------------------------------------
    def _memories(self) -> dict[str, LLRMemory]:
        """M^P, M^R and the critic's M^C, by their names in the learner's state and config."""
        return {"process": self.process, "reference": self.reference, "critic": self.critic.memory}

    def _state(self) -> dict[str, np.ndarray]:
        """The three memories, the critic's traces and the running trial's bookkeeping."""
        state: dict[str, np.ndarray] = {}
        for name, memory in self._memories().items():
            state.update(memory.state_dict(prefix=f"{name}."))
        state["traces"] = self.critic.traces.copy()
        state["k"] = np.array(self._k)
        state["x_prev"] = self._x_prev.copy()
        state["u_prev"] = self._u_prev.copy()
        state["v_prev"] = np.array(self._v_prev[0])
        state["u_greedy"] = self._u_greedy.copy()
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
        self._x_prev[:] = state["x_prev"]
        self._u_prev[:] = state["u_prev"]
        self._v_prev[0] = float(state["v_prev"])
        self._u_greedy = np.array(state["u_greedy"], dtype=float)

    # -- rehearsal, learning rates, memory and the compiled step ---------------------------------
    def _set_rehearsing(self, rehearsing: bool) -> None:
        """While rehearsing (planning, replay), line 14 leaves M^P unchanged."""
        self._learns_model = not rehearsing

    @property
    def _uses_trial_counter(self) -> bool:
        return super()._uses_trial_counter or self.config.rates_decay

    def _sync_rates(self) -> None:
        """The running trial's alpha_c and alpha_r (``RMACConfig.rates_at``), set once per trial:
        the trial counter may also change by ``load_state_dict``."""
        if self._rates_trial != self.trial:
            self.critic.alpha, self._alpha_r = self.config.rates_at(self.trial)
            if self._kernel_state is not None:
                _rmac_kernels.set_reference_rate(self._kernel_state, self._alpha_r)
            self._rates_trial = self.trial

    @classmethod
    def _memory_parts(
        cls, config: RMACConfig, state_space: StateSpace, action_space: ActionSpace
    ) -> tuple[int, int]:
        """The three memories and the critic's traces (see :meth:`Agent.memory_estimate`)."""
        n, m = state_space.dim, action_space.dim
        parts = (
            config.process.estimate(n + m, n),
            config.reference.estimate(n, n),
            config.critic.estimate(n, 1),
        )
        traces = 8 * config.critic.capacity
        return tuple(sum(part) + traces for part in zip(*parts))

    def _new_kernel_state(self) -> _rmac_kernels.RMACState | None:
        """The compiled step's view of this agent's arrays (numba back end), else None."""
        if self.config.backend != "numba":
            return None
        cfg = self.config
        settings = _rmac_kernels.RMACSettings(
            gamma=float(cfg.gamma),
            alpha_r=self._alpha_r,
            beta_u_zero=BETA_U_ZERO,
            inverse_previous=cfg.inverse_query == "previous",
            gradient_at_next=cfg.critic_gradient_at == "next",
            rule=REACHABLE_RULES.index(cfg.reachable_rule),
            action_cost=self._action_cost,
            vertices=np.ascontiguousarray(self.vertices),
            candidates=np.ascontiguousarray(self.candidates),
            refine_steps=self._refine_steps,
            insert_rate=float(cfg.reference_insert_rate),
            period=np.ascontiguousarray(self.period, dtype=float),
            low=self.action_space.low.copy(),
            high=self.action_space.high.copy(),
        )
        return _rmac_kernels.new_state(
            self.process.kernel_state,
            self.reference.kernel_state,
            self.critic.kernel_state,
            self._x_prev,
            self._u_prev,
            self._v_prev,
            settings,
        )

    def __getstate__(self) -> dict:
        # The structref is a view of arrays pickled here; it is made anew when unpickled.
        return {k: v for k, v in self.__dict__.items() if k != "_kernel_state"}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._kernel_state = self._new_kernel_state()

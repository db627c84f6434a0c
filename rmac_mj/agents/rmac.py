"""Reference Model Actor-Critic (RMAC): section 5 and Algorithm 2 of Grondman et al.

RMAC has no explicit actor. It learns three LLR memories (section 4):

* the process model M^P, samples [x, u | x'], giving the local model x' = beta^P [x; u; 1];
* the reference model M^R, samples [x | x_hat], mapping a state to the desired next state R(x);
* the critic M^C, samples [x | V].

The action is the least-squares inverse of the local process model for the desired state,
u_k = f^-1(x_k, R(x_k)) (+ exploration). The reference model is moved towards the best reachable state
x_r: the vertex of the reachable set (all 2^m combinations of action extremes applied to the local
process model) with the highest value under the critic's local linear model. The critic learns by
TD(lambda) with eligibility traces on its memory samples.

Every choice the paper leaves open is a field of :class:`RMACConfig`; docs/rmac.md lists them with
what was measured for each. Two back ends compute the same thing: ``backend='numpy'`` is the readable
reference below, written line by line after Algorithm 2; ``backend='numba'`` runs the same steps in
the compiled kernels of :mod:`rmac_mj.agents._rmac_kernels` (the learner must cost at most about two
``env.step`` calls). The memories are used only through their public interface: ``LLRMemory``'s
methods here, its compiled counterparts (``llr_query``, ...) on ``LLRMemory.kernel_state`` there.
"""

from __future__ import annotations

import dataclasses
import itertools
from numbers import Integral, Real
from typing import ClassVar

import numpy as np

from rmac_mj.agents import _rmac_kernels
from rmac_mj.agents.base import Agent
from rmac_mj.agents.exploration import Exploration, model_uncertainty
from rmac_mj.agents.prior_knowledge import discounted_returns, seed_memory
from rmac_mj.agents.spaces import ActionSpace, StateSpace
from rmac_mj.approximators.llr import SHARED_CONSTRAINTS, LLRMemory, memory_constraints, wrap
from rmac_mj.constraints import WEIGHTS, InstanceOf, Interval, Options, check_config

_BACKENDS = ("numba", "numpy")
#: beta_u counts as zero (u = 0, section 5) below this fraction of the state gains: when every
#: neighbour of the process model holds the same action, the truncated fit removes the u direction
#: and rounding alone would otherwise decide a saturated action's sign.
BETA_U_ZERO = 1e-9
_REACHABLE_RULES = ("vertices", "vertices_value", "grid", "exact")
#: Absolute tolerance, in action units, of the golden-section refinement of reachable_rule='exact'.
EXACT_TOLERANCE = 1e-6
#: 1 / golden ratio, the shrink factor of one golden-section step.
INV_PHI = (5.0 ** 0.5 - 1.0) / 2.0


@dataclasses.dataclass(frozen=True)
class RMACConfig:
    """Hyperparameters of RMAC. Defaults: section 6.2 and Table 2, then the documented choices."""

    gamma: float = 0.97
    """Discount factor (section 6.2)."""
    lam: float = 0.65
    """Trace decay lambda (section 6.2)."""
    alpha_c: float = 0.1
    """Critic learning rate (Table 2)."""
    alpha_r: float = 0.005
    """Reference model learning rate (Table 2)."""

    alpha_c_final: float | None = None
    """Where ``alpha_c`` decays to: linearly over the first ``rate_decay_trials`` learning trials
    (trial t uses alpha_c + min(t / rate_decay_trials, 1) (alpha_c_final - alpha_c)), then constant.
    None (the paper's): constant ``alpha_c``. Not in the paper: learning fast first and finely later
    (docs/studies/rmac-best.md)."""
    alpha_r_final: float | None = None
    """Where ``alpha_r`` decays to, as ``alpha_c_final``; None: constant (the paper's)."""
    rate_decay_trials: int = 200
    """Learning trials over which ``alpha_c`` and ``alpha_r`` reach their final values."""

    critic_capacity: int = 2000
    """Critic memory size (Table 2)."""
    critic_neighbours: int = 20
    """Critic nearest neighbours K (Table 2)."""
    critic_weights: tuple[float, ...] | None = None
    """Critic input weighting over x; None: the task's (``StateSpace.input_weights``; dc_pendulum: Table 2's
    (1, 0.1))."""
    process_capacity: int = 100
    """Process memory size (Table 2)."""
    process_neighbours: int = 9
    """Process nearest neighbours K (Table 2)."""
    process_weights: tuple[float, ...] | None = None
    """Process input weighting over [x, u]; None: the task's (``StateSpace.input_weights`` then
    ``ActionSpace.input_weights``; dc_pendulum: Table 2's (1, 0.1, 1))."""
    reference_capacity: int = 2000
    """Reference memory size (Table 2)."""
    reference_neighbours: int = 20
    """Reference nearest neighbours K (Table 2)."""
    reference_weights: tuple[float, ...] | None = None
    """Reference input weighting over x; None: the task's (``StateSpace.input_weights``; dc_pendulum: Table
    2's (1, 0.1))."""

    exploration: Exploration = Exploration()
    """Exploration Delta u_k. The paper says RMAC still needs it but not how; the default is the S-AC
    schedule of section 6.1 (N(0, 1) every third step). Without it beta_u stays 0 and u = 0 forever.
    With ``where='uncertain'`` the uncertainty is the process model's at the point the inverse of
    line 11 linearises it, (x_k, u_{k-1}) (or (x_k, 0): ``inverse_query``), before line 14 inserts
    the last transition (docs/studies/exploration-schedule.md)."""

    norm: int = 1
    """1- or 2-norm of the weighted input difference in all memories (section 4 allows both)."""
    conditioning: str = "ridge"
    """How the local least-squares fits are conditioned: 'ridge' (``ridge`` on the slopes, as GRL),
    'svd' (truncated SVD, ``rcond``) or 'none' (pseudo-inverse). Measured (docs/rmac.md): the three
    end within noise of each other; unclipped and unconditioned fits give outlier early trials."""
    rcond: float = 0.01
    """Relative singular value cutoff for conditioning='svd'."""
    ridge: float = 1e-3
    """Ridge term for conditioning='ridge', in weighted input units squared (1e-4 and 1e-2 were
    measured no better)."""
    critic_clip: bool = True
    """Clip critic predictions to the range of the neighbours' values (as GRL does); keeps the values
    sane when a fit extrapolates."""
    reference_clip: bool = True
    """Clip reference predictions to the range of the neighbours' desired states, so that no desired
    state lies beyond those once found reachable. Measured no different within noise; kept as a
    safeguard (docs/rmac.md)."""
    process_clip: bool = False
    """Clip process model predictions to the neighbours' next states."""
    critic_replacement: str = "nearest"
    """Critic memory management when full: 'nearest' (the sample most redundant with the new one),
    'oldest', or 'redundancy' (the sample of highest smoothed redundancy score, measured by
    ``critic_redundancy``; see :mod:`rmac_mj.approximators.llr` for the equations)."""
    process_replacement: str = "nearest"
    """Process memory management when full (same choices)."""
    reference_replacement: str = "nearest"
    """Reference memory management when full (same choices)."""
    critic_redundancy: str = "distance"
    """What the critic's redundancy score measures under critic_replacement='redundancy':
    'distance' (a sample close to new samples is redundant) or 'misfit' (a sample its local model
    predicts well is redundant). Issue 14's account of the authors' code: distance for the critic
    and reference memories, whose outputs move while learning (a misfit measured now says little
    about the sample later); the squared misfit for the process memory, whose samples are fixed
    observations of the dynamics."""
    process_redundancy: str = "misfit"
    """What the process memory's redundancy score measures under process_replacement='redundancy'
    (see critic_redundancy)."""
    reference_redundancy: str = "distance"
    """What the reference memory's redundancy score measures under
    reference_replacement='redundancy' (see critic_redundancy)."""
    redundancy_smoothing: float = 0.1
    """eta in (0, 1], the exponential smoothing of every redundancy score,
    rho_i <- (1 - eta) rho_i + eta c_i each time sample i is a neighbour of a new sample (our
    choice: about the last ten such events count)."""
    inverse_query: str = "previous"
    """Where the process model is linearised for the inverse (Alg. 2 lines 5, 11): at (x_k, u_{k-1}),
    the previously applied action ('previous'; u_{-1} = 0), or at (x_k, 0) ('zero')."""
    critic_gradient_at: str = "next"
    """Where the critic's local model that ranks the reachable states (line 16) is fitted: at x_k
    ('next', the reached state, which lies among the vertices) or at x_{k-1} ('previous')."""
    reachable_rule: str = "vertices"
    """How x_r, the best reachable state of line 16, is chosen. Every rule predicts the next state of
    a candidate action u with the process model's local linear fit at (x_{k-1}, u_{k-1}),
    x'(u) = f(x_{k-1}, u_{k-1}) + beta_u (u - u_{k-1}), and x_r is the chosen candidate's x'(u):

    * 'vertices' (the paper's): the 2^m combinations of action extremes, ranked by the critic's
      *local linear* model (see ``critic_gradient_at``); the action cost is ignored;
    * 'vertices_value': the same 2^m vertices ranked by r + gamma V(x'(u)) with the full LLR critic V;
    * 'grid': ``reachable_grid`` actions per action dimension (their product), same score;
    * 'exact' (m = 1 only): the maximum of r + gamma V(x'(u)) over u in the bounds, found on the
      grid and refined by golden-section search (to ``EXACT_TOLERANCE``) between the grid point's
      neighbours. "Exact" up to that tolerance and to the LLR critic itself, which is affine only
      within one neighbour set, so the maximised function is piecewise affine (plus -P u^2): the
      refinement finds the best point of the bracket when it is unimodal there.

    The reward r(x_{k-1}, u) = -x^T Q x - P |u|^2 has the same state part for every candidate, so the
    score is -sum_i P_i u_i^2 + gamma V(x'(u)) with P = ``action_cost``."""
    action_cost: float | tuple[float, ...] | None = None
    """P, the reward's action cost -sum_i P_i u_i^2, used only by the reachable rules other than
    'vertices': the one piece of reward knowledge those rules use (MLAC uses the same). None: the
    task's (``ActionSpace.cost``; dc_pendulum: its P = 1, two_link_arm: 0); a number: P in every
    action dimension. ``agent.config.action_cost`` holds the resolved tuple (None when the rule does
    not use it and the task does not say)."""
    reachable_grid: int = 21
    """Actions per action dimension for reachable_rule 'grid' and 'exact' (evenly spaced over the
    bounds, both bounds included)."""
    reference_insert_rate: float = 1.0
    """What line 18 inserts in M^R for x_{k-1}: R(x_{k-1}) + rate wrap(x_r - R(x_{k-1})), the
    reference's own estimate before the insertion (from K(x_{k-1}); x_r on an empty memory) moved
    this far towards x_r; line 20 then moves it on with K(x_{k-1}) when it replaced the nearest
    sample (a full memory). 1 (the paper's): x_r itself. With 1 every insertion near the goal writes a
    raw vertex state (about +-2.6 rad/s on the pendulum) over the few samples there, so R near
    upright is a fit to the last ~20 bang-bang targets and the greedy policy's resting angle is
    redrawn every trial (docs/studies/upright-offset.md); below 1 each sample averages its targets,
    as the critic inserts its estimate V_{k-1} (line 23) and lets TD move it. 0 inserts R(x_{k-1})
    unmoved: measured, the reference then never learns a swing-up."""
    initial_value: str = "critic"
    """V_0 of a trial (line 2): the critic's estimate V(x_0) ('critic'; 0 on the empty memory) or the
    literal 0 every trial ('zero')."""
    backend: str = "numba"
    """'numba' (compiled kernels) or 'numpy' (the readable reference); both give the same results."""

    @property
    def rates_decay(self) -> bool:
        """Whether the learning rates depend on the trial (``alpha_c_final``/``alpha_r_final``)."""
        return self.alpha_c_final is not None or self.alpha_r_final is not None

    def rates_at(self, trial: int) -> tuple[float, float]:
        """(alpha_c, alpha_r) of learning trial ``trial`` (0: the first); see ``alpha_c_final``."""
        fraction = min(max(trial, 0) / self.rate_decay_trials, 1.0)
        return tuple(float(start if final is None else start + fraction * (final - start))
                     for start, final in ((self.alpha_c, self.alpha_c_final),
                                          (self.alpha_r, self.alpha_r_final)))

    parameter_constraints: ClassVar[dict[str, list]] = {
        "gamma": [Interval(Real, 0, 1, closed="left")],
        "lam": [Interval(Real, 0, 1)],
        "alpha_c": [Interval(Real, 0, 1)],
        "alpha_r": [Interval(Real, 0, 1)],
        "alpha_c_final": [Interval(Real, 0, 1), None],
        "alpha_r_final": [Interval(Real, 0, 1), None],
        "rate_decay_trials": [Interval(Integral, 1, None)],
        **memory_constraints("critic"), **memory_constraints("process"),
        **memory_constraints("reference"),
        "exploration": [InstanceOf(Exploration)],
        **SHARED_CONSTRAINTS,
        "redundancy_smoothing": LLRMemory.parameter_constraints["redundancy_smoothing"],
        "inverse_query": [Options("previous", "zero")],
        "critic_gradient_at": [Options("next", "previous")],
        "reachable_rule": [Options(*_REACHABLE_RULES)],
        "action_cost": [Interval(Real, 0, None), WEIGHTS, None],
        "reachable_grid": [Interval(Integral, 2, None)],
        "reference_insert_rate": [Interval(Real, 0, 1)],
        "initial_value": [Options("critic", "zero")],
        "backend": [Options(*_BACKENDS)],
    }

    def __post_init__(self) -> None:
        check_config(self)


class RMAC(Agent):
    """The RMAC learner (Algorithm 2) over a flat state box and a bounded action.

    Args:
      state_space: the n-dimensional state (periodic dimensions are wrapped in every memory).
      action_space: the m-dimensional action box; its 2^m vertices span the reachable set.
      config: hyperparameters; the weightings must have n (critic, reference) and n + m (process)
        entries, and those left None are taken from the spaces' ``weights`` (``self.config`` holds
        the resolved values).
      seed: seed or Generator of the exploration noise, the only randomness.
    """

    name = "rmac"
    display_name = "RMAC"
    config_class = RMACConfig
    prior_parts = ("process", "reference", "critic")

    def __init__(self, state_space: StateSpace, action_space: ActionSpace,
                 config: RMACConfig = RMACConfig(),
                 seed: int | np.random.Generator | None = None) -> None:
        super().__init__(state_space, action_space, config, seed)
        n, m = state_space.dim, action_space.dim
        config = self._config_with_task_weights(config, ("critic", "reference"))
        self.config = config = self._config_with_task_action_cost(
            config, None if config.reachable_rule == "vertices" else
            f"reachable_rule={config.reachable_rule!r}")
        #: P of the reachable rules' score (zeros when the rule does not use it), shape (m,).
        self._action_cost = np.array(config.action_cost or np.zeros(action_space.dim), dtype=float)
        self.n, self.m = n, m
        if config.reachable_rule == "exact" and m != 1:
            raise ValueError(f"RMAC: config.reachable_rule='exact' needs a one-dimensional action, "
                             f"this task has {m}; use 'grid'")
        self.period = state_space.period  # (n,), 0 for non-periodic dimensions
        common = dict(norm=config.norm, conditioning=config.conditioning, rcond=config.rcond,
                      ridge=config.ridge, redundancy_smoothing=config.redundancy_smoothing,
                      backend=config.backend)
        self.process = LLRMemory(
            n + m, n, config.process_capacity, config.process_neighbours,
            input_weights=config.process_weights, input_period=np.r_[self.period, np.zeros(m)],
            output_period=self.period, clip=config.process_clip,
            replacement=config.process_replacement, redundancy=config.process_redundancy,
            **common)
        self.reference = LLRMemory(
            n, n, config.reference_capacity, config.reference_neighbours,
            input_weights=config.reference_weights, input_period=self.period,
            output_period=self.period, clip=config.reference_clip,
            replacement=config.reference_replacement, redundancy=config.reference_redundancy,
            **common)
        self.critic = LLRMemory(
            n, 1, config.critic_capacity, config.critic_neighbours,
            input_weights=config.critic_weights, input_period=self.period,
            clip=config.critic_clip, replacement=config.critic_replacement,
            redundancy=config.critic_redundancy, **common)
        #: e(s_i) of Algorithm 2 line 26, one per critic memory slot.
        self.traces = np.zeros(config.critic_capacity)
        #: U_R without the state rows: the 2^m combinations of action extremes, (2^m, m), max first.
        self.vertices = np.array(list(itertools.product(
            *[(hi, lo) for lo, hi in zip(action_space.low, action_space.high)])), dtype=float)
        #: The candidate actions of the reachable rule, (c, m): the vertices, or for 'grid' and
        #: 'exact' the product of ``reachable_grid`` evenly spaced values per action dimension.
        if config.reachable_rule in ("grid", "exact"):
            self.candidates = np.array(list(itertools.product(*[
                np.linspace(lo, hi, config.reachable_grid)
                for lo, hi in zip(action_space.low, action_space.high)])), dtype=float)
        else:
            self.candidates = self.vertices.copy()
        #: Golden-section steps of reachable_rule='exact': a bracket of two grid spacings shrinks
        #: to EXACT_TOLERANCE.
        span = 2.0 * float(np.max(action_space.high - action_space.low)) / (config.reachable_grid - 1)
        self._refine_steps = (int(np.ceil(np.log(EXACT_TOLERANCE / span) / np.log(INV_PHI)))
                              if config.reachable_rule == "exact" and span > EXACT_TOLERANCE else 0)
        self._k = 0
        # x_{k-1}, u_{k-1} and V_{k-1}, updated in place: the compiled step shares these arrays.
        self._x_prev = np.zeros(n)
        self._u_prev = np.zeros(m)
        self._v_prev = np.zeros(1)
        self._u_greedy = np.zeros(m)
        # The compiled step's neighbour lists (reference, critic) x (two buffers) x [length,
        # version]; a length of -1 drops a list (see _rmac_kernels).
        self._list_info = np.full((2, 2, 2), -1, dtype=np.int64)
        self._kernel_state = self._new_kernel_state()

    def _new_kernel_state(self) -> _rmac_kernels.RMACState | None:
        """The compiled step's view of this agent's arrays (numba back end), else None."""
        if self.config.backend != "numba":
            return None
        cfg = self.config
        self._kernel_rates_trial = self.trial
        return _rmac_kernels.new_state(
            self.process.kernel_state, self.reference.kernel_state, self.critic.kernel_state,
            self.traces, self._x_prev, self._u_prev, self._v_prev,
            np.ascontiguousarray(self.vertices), np.ascontiguousarray(self.period, dtype=float),
            self.action_space.low.copy(), self.action_space.high.copy(), float(cfg.gamma),
            float(cfg.lam), *cfg.rates_at(self.trial), BETA_U_ZERO,
            cfg.inverse_query == "previous", cfg.critic_gradient_at == "next",
            self._list_info[0], self._list_info[1], _REACHABLE_RULES.index(cfg.reachable_rule),
            self._action_cost, np.ascontiguousarray(self.candidates), self._refine_steps,
            float(cfg.reference_insert_rate))

    @property
    def _uses_trial_counter(self) -> bool:
        return super()._uses_trial_counter or self.config.rates_decay

    def _sync_kernel_rates(self) -> None:
        """Give the compiled step the running trial's alpha_c and alpha_r (when they decay), once
        per trial: the trial counter may also change by ``load_state_dict``."""
        if self._kernel_rates_trial != self.trial:
            _rmac_kernels.set_rates(self._kernel_state, *self.config.rates_at(self.trial))
            self._kernel_rates_trial = self.trial

    def __getstate__(self) -> dict:
        # The structref is a view of arrays pickled here; it is made anew when unpickled.
        return {k: v for k, v in self.__dict__.items() if k != "_kernel_state"}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._list_info[:, :, 0] = -1
        self._kernel_state = self._new_kernel_state()

    # -- the policy: u = f^-1(x, R(x)) ------------------------------------------------------------------
    def _inverse(self, x: np.ndarray, x_desired: np.ndarray, u_query: np.ndarray) -> np.ndarray:
        """f^-1(x, x_desired): least-squares inverse of the local process model (section 5).

        The model is linearised at (x, u_query): x' = f(x, u_query) + beta_u (u - u_query), so
        u = u_query + pinv(beta_u) wrap(x_desired - f(x, u_query)), which is the paper's
        u = pinv(beta_u) (x_desired - beta_x x - beta_b) written around the query point. Returns
        u = 0 when beta_u = 0 (numerically: see BETA_U_ZERO; section 5); saturated to the action bounds.
        """
        pred, beta, _ = self.process.query(np.concatenate([x, u_query]))
        beta_u = beta[:, self.n:self.n + self.m]
        if np.abs(beta_u).max() <= BETA_U_ZERO * max(1.0, np.abs(beta[:, :self.n]).max()):
            return np.zeros(self.m)
        u = u_query + np.linalg.pinv(beta_u) @ wrap(x_desired - pred, self.period)
        return self.action_space.clip(u)

    def _u_query(self, u_prev: np.ndarray) -> np.ndarray:
        return u_prev if self.config.inverse_query == "previous" else np.zeros(self.m)

    def _act(self, x: np.ndarray, u_prev: np.ndarray) -> np.ndarray:
        """The greedy action in x: lines 10-11 without Delta u_k."""
        x_desired = self.reference.query(x)[0]  # line 10: x_hat_{k+1} = R(x_k)
        return self._inverse(x, x_desired, self._u_query(u_prev))

    def policy(self, states: np.ndarray, u_query: np.ndarray | None = None) -> np.ndarray:
        """u = f^-1(x, R(x)) without exploration for a batch of states (policy plots, Fig. 4).

        states: shape (q, n); u_query: shape (m,) or (q, m), where the process model is linearised
        (default 0). Returns shape (q, m).
        """
        states = np.asarray(states, dtype=float).reshape(-1, self.n)
        if not np.all(np.isfinite(states)):
            raise ValueError("RMAC.policy: states must be finite")
        uq = np.broadcast_to(np.zeros(self.m) if u_query is None else
                             np.asarray(u_query, dtype=float), (len(states), self.m))
        out = np.empty((len(states), self.m))
        for i, x in enumerate(states):
            x = self.state_space.canonical(x)
            out[i] = self._inverse(x, self.reference.query(x)[0], uq[i])
        return out

    # -- Agent interface --------------------------------------------------------------------------------
    def _start(self, x0: np.ndarray) -> np.ndarray:
        """Lines 1-6: reset the traces, u_0 = f^-1(x_0, R(x_0)) + Delta u_0."""
        x0 = self.state_space.canonical(x0)
        self._list_info[:, :, 0] = -1
        self.traces[:] = 0.0  # line 3
        self._k = 0
        self._u_greedy = np.zeros(self.m)
        self._v_prev[0] = (self.critic.query(x0)[0][0] if self.config.initial_value == "critic"
                           else 0.0)  # line 2
        u = self._explore(self._act(x0, np.zeros(self.m)), x0, np.zeros(self.m))
        self._x_prev[:] = x0
        self._u_prev[:] = u
        return u.copy()

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

    def _step(self, reward: float, x: np.ndarray) -> np.ndarray:
        """Lines 8-29 for one control step: act with the current models, then learn."""
        self._k += 1
        if self._kernel_state is not None:
            if self.config.rates_decay:
                self._sync_kernel_rates()
            du = self._noise(x, self._u_prev)  # line 8
            # Lines 10-28 in one compiled call (x wrapped there), which also advances x_prev,
            # u_prev and v_prev; it returns a new array.
            return _rmac_kernels.step(self._kernel_state, reward, x, du)
        x = self.state_space.canonical(x)
        u = self._explore(self._act(x, self._u_prev), x, self._u_prev)  # lines 10-12
        self._v_prev[0] = self._update(float(reward), x)   # lines 13-28
        self._x_prev[:] = x
        self._u_prev[:] = u
        return u.copy()

    def _stop(self, reward: float, x: np.ndarray) -> None:
        """The last transition of a trial: learn (lines 13-28), no action."""
        if self._kernel_state is not None:
            if self.config.rates_decay:
                self._sync_kernel_rates()
            _rmac_kernels.stop(self._kernel_state, reward, x)
        else:
            self._update(reward, self.state_space.canonical(x))
        self._u_greedy = np.zeros(self.m)  # a greedy trial that follows starts from u_{-1} = 0

    def _update(self, reward: float, x: np.ndarray) -> float:
        """Lines 13-28 (reference implementation); returns V_k."""
        cfg, n = self.config, self.n
        x_prev, u_prev, v_prev = self._x_prev, self._u_prev, float(self._v_prev[0])
        # Line 14: insert [x_{k-1}, u_{k-1} | x_k] in M^P.
        self.process.insert(np.concatenate([x_prev, u_prev]), x)
        # Line 16: the best reachable state. X_R = beta^P U_R, linearised at (x_{k-1}, u_{k-1}).
        pred, beta, _ = self.process.query(np.concatenate([x_prev, u_prev]))
        beta_u = beta[:, n:n + self.m]
        v_k, beta_c, _ = self.critic.query(x)
        v_k = float(v_k[0])
        if cfg.reachable_rule == "vertices":
            reachable = pred + (self.vertices - u_prev) @ beta_u.T  # (2^m, n)
            # The critic's local linear model, V(x) = V(x_c) + beta^C_x wrap(x - x_c).
            if cfg.critic_gradient_at == "next":
                x_c, slope = x, beta_c[0, :n]
            else:
                x_c, slope = x_prev, self.critic.query(x_prev)[1][0, :n]
            values = wrap(reachable - x_c, self.period) @ slope
            x_r = self.state_space.canonical(reachable[int(np.argmax(values))])
        else:  # the other rules: r + gamma V(x') with the full critic (RMACConfig.reachable_rule)
            x_r = self._best_reachable(pred, beta_u, u_prev)
        # Lines 17-20: insert [x_{k-1} | x_r] in M^R and move K(x_{k-1}) towards x_r.
        near = self.reference.neighbours(x_prev)
        inserted = x_r
        if cfg.reference_insert_rate < 1.0 and len(near):  # R(x_{k-1}) moved towards x_r
            r_prev = self.reference.query(x_prev)[0]
            inserted = self.state_space.canonical(
                r_prev + cfg.reference_insert_rate * wrap(x_r - r_prev, self.period))
        self.reference.insert(x_prev, inserted, int(near[0]) if len(near) else None)
        alpha_c, alpha_r = cfg.rates_at(self.trial)
        self.reference.move_outputs(near, x_r, alpha_r)
        # Lines 22-28: TD(lambda) on the critic's samples. V_k was computed above (line 22).
        near = self.critic.neighbours(x_prev)
        slot = self.critic.insert(x_prev, [v_prev], int(near[0]) if len(near) else None)  # line 23
        delta = reward + cfg.gamma * v_k - v_prev  # line 24
        self.traces *= cfg.lam * cfg.gamma  # line 26
        self.traces[near] = 1.0
        self.traces[slot] = 1.0
        self.critic.add_weighted(self.traces, [alpha_c * delta])  # line 27
        return v_k

    def _reachable_score(self, u: np.ndarray, pred: np.ndarray, beta_u: np.ndarray,
                         u_prev: np.ndarray) -> tuple[float, np.ndarray]:
        """-sum_i P_i u_i^2 + gamma V(x'(u)) and x'(u) (canonical), x'(u) = pred + beta_u (u - u_{k-1})."""
        x_next = self.state_space.canonical(pred + beta_u @ (u - u_prev))
        value = float(self.critic.query(x_next)[0][0])
        return -float(np.sum(self._action_cost * (u * u))) + self.config.gamma * value, x_next

    def _best_reachable(self, pred: np.ndarray, beta_u: np.ndarray,
                        u_prev: np.ndarray) -> np.ndarray:
        """x_r for the reachable rules other than 'vertices' (see ``RMACConfig.reachable_rule``):
        the candidate action with the highest -P |u|^2 + gamma V(x'(u)) under the full LLR critic
        (first of equals), refined for 'exact' by golden-section search between the best grid
        point's neighbours; returns its predicted next state."""
        best_score, x_r, u_best = -np.inf, None, None
        for u in self.candidates:
            score, x_next = self._reachable_score(u, pred, beta_u, u_prev)
            if score > best_score:
                best_score, x_r, u_best = score, x_next, u
        if self._refine_steps:
            low, high = float(self.action_space.low[0]), float(self.action_space.high[0])
            h = (high - low) / (self.config.reachable_grid - 1)
            a, b = max(low, float(u_best[0]) - h), min(high, float(u_best[0]) + h)
            f = lambda v: self._reachable_score(np.array([v]), pred, beta_u, u_prev)  # noqa: E731
            c, d = b - INV_PHI * (b - a), a + INV_PHI * (b - a)
            (fc, xc), (fd, xd) = f(c), f(d)
            for _ in range(self._refine_steps):
                if fc >= fd:  # the maximum lies in [a, d]
                    b, d, fd, xd = d, c, fc, xc
                    c = b - INV_PHI * (b - a)
                    fc, xc = f(c)
                else:         # in [c, b]
                    a, c, fc, xc = c, d, fd, xd
                    d = a + INV_PHI * (b - a)
                    fd, xd = f(d)
            score, x_next = (fc, xc) if fc >= fd else (fd, xd)
            if score > best_score:
                x_r = x_next
        return x_r

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
        return float(self.critic.query(self.state_space.canonical(x))[0][0])

    # -- prior knowledge (section 7) --------------------------------------------------------------------
    def _seed_from(self, states: np.ndarray, actions: np.ndarray, rewards: np.ndarray,
                   next_states: np.ndarray, trial: np.ndarray, parts: tuple[str, ...]) -> None:
        """Initialise the memories from recorded transitions instead of empty (section 7).

        * 'process': M^P <- [x_t, u_t | x_{t+1}], the recorded dynamics;
        * 'reference': M^R <- [x_t | x_{t+1}], the demonstrated closed loop as the desired behaviour
          (every desired state was reached, so it is reachable);
        * 'critic': M^C <- [x_t | G_t], the discounted returns-to-go within each recorded trial with
          this agent's gamma, 0 after a trial's last transition (see ``base.discounted_returns``).

        Each memory holds exactly the samples when they fit, otherwise they pass through its
        replacement rule in time order (``base.seed_memory``). Angles are wrapped as when learning.
        """
        period = self.state_space.period
        x = wrap(states, period)
        x_next = wrap(next_states, period)
        if "process" in parts:
            seed_memory(self.process, np.hstack([x, actions]), x_next)
        if "reference" in parts:
            seed_memory(self.reference, x, x_next)
        if "critic" in parts:
            returns = discounted_returns(rewards, trial, self.config.gamma)
            seed_memory(self.critic, x, returns[:, None])

    # -- state ------------------------------------------------------------------------------------------
    def _state(self) -> dict[str, np.ndarray]:
        """The three memories, the critic's traces and the running trial's bookkeeping."""
        state: dict[str, np.ndarray] = {}
        for name in ("process", "reference", "critic"):
            state.update(getattr(self, name).state_dict(prefix=f"{name}."))
        state["traces"] = self.traces.copy()
        state["k"] = np.array(self._k)
        state["x_prev"] = self._x_prev.copy()
        state["u_prev"] = self._u_prev.copy()
        state["v_prev"] = np.array(self._v_prev[0])
        state["u_greedy"] = self._u_greedy.copy()
        return state

    def _load_state(self, state: dict[str, np.ndarray]) -> None:
        for name in ("process", "reference", "critic"):
            getattr(self, name).load_state_dict(state, prefix=f"{name}.")
        self.traces[:] = state["traces"]
        self._k = int(state["k"])
        self._x_prev[:] = state["x_prev"]
        self._u_prev[:] = state["u_prev"]
        self._v_prev[0] = float(state["v_prev"])
        self._list_info[:, :, 0] = -1
        self._u_greedy = np.array(state["u_greedy"], dtype=float)

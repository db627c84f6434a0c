"""RMAC's hyperparameters (:class:`RMACConfig`), the paper's (section 6.2, Table 2) as defaults.

Every choice the paper leaves open is a named field (docs/rmac.md), the constraints declared once
(:mod:`rmac_mj.constraints`).
"""

from __future__ import annotations

import dataclasses
from numbers import Integral, Real
from typing import ClassVar

from rmac_mj.agents.exploration import Exploration
from rmac_mj.agents.planning import REHEARSAL, Planning, Replay
from rmac_mj.agents.task_knowledge import memory_units
from rmac_mj.approximators.llr import SHARED_CONSTRAINTS, LLRConfig, with_memory_defaults
from rmac_mj.constraints import (
    BACKEND,
    TD_LAMBDA,
    WEIGHTS,
    InstanceOf,
    Interval,
    Options,
    check_config,
)

#: The rules that select line 16's best reachable state (``RMACConfig.reachable_rule``).
REACHABLE_RULES = ("vertices", "vertices_value", "grid", "exact")


@dataclasses.dataclass(frozen=True)
class RMACConfig:
    """Hyperparameters of RMAC. Defaults: section 6.2 and Table 2, then the documented choices."""

    gamma: float | None = None
    """Discount factor per control step (section 6.2: 0.97 per 0.03 s); None: 0.97 ** (dt / 0.03),
    the paper's horizon in seconds at the task's step dt."""
    lam: float | None = None
    """Trace decay lambda per control step (section 6.2: 0.65); None: 0.65 ** (dt / 0.03)."""
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

    critic: LLRConfig = LLRConfig(clip=True, replacement="nearest", redundancy="distance")
    """The critic's memory M^C [x | V] (Table 2: 2000 samples and K = 20 for n = 2; None: grown to
    2000 n / 2 and 20 n / 2; weighting over x, None: the task's, ``StateSpace.input_weights``;
    dc_pendulum: Table 2's (1, 0.1)). Predictions clipped to the neighbours' values (as GRL does):
    the values stay sane when a fit extrapolates. Redundancy measured by distance: as the authors'
    code is described, for the critic and reference memories, whose outputs move while learning (a
    misfit measured now says little about the sample later)."""
    process: LLRConfig = LLRConfig(clip=False, replacement="nearest", redundancy="misfit")
    """The process model M^P [x, u | x'] (Table 2: 100 samples and K = 9 for n + m = 3; None: grown
    to 100 (n + m) / 3 and 9 (n + m) / 3; weighting over [x, u], None: the task's,
    ``StateSpace.input_weights`` then ``ActionSpace.input_weights``; dc_pendulum: Table 2's (1, 0.1,
    1)). Predictions not clipped. Redundancy measured by the squared misfit: its samples are fixed
    observations of the dynamics."""
    reference: LLRConfig = LLRConfig(clip=True, replacement="nearest", redundancy="distance")
    """The reference model M^R [x | x_hat] (Table 2: 2000 samples and K = 20 for n = 2, as the
    critic). Predictions clipped to the neighbours' desired states, so that no desired state lies
    beyond those once found reachable; a safeguard (docs/rmac.md)."""

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
    'svd' (truncated SVD, ``rcond``) or 'none' (pseudo-inverse); docs/rmac.md compares them."""
    rcond: float = 0.01
    """Relative singular value cutoff for conditioning='svd'."""
    ridge: float = 1e-3
    """Ridge term for conditioning='ridge', in weighted input units squared."""
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
    unmoved (docs/studies/upright-offset.md)."""
    initial_value: str = "critic"
    """V_0 of a trial (line 2): the critic's estimate V(x_0) ('critic'; 0 on the empty memory) or the
    literal 0 every trial ('zero')."""
    planning: Planning = Planning()
    """Simulated transitions in learned models between trials (``agents.planning``): the
    rollouts run this algorithm, line 14 excepted. Paper: none."""
    replay: Replay = Replay()
    """Replay of stored real trials between trials (``agents.planning``). Paper: none."""
    backend: str = "numba"
    """'numba' (compiled kernels) or 'numpy' (the readable reference); both give the same results."""

    @property
    def rates_decay(self) -> bool:
        """Whether the learning rates depend on the trial (``alpha_c_final``/``alpha_r_final``)."""
        return self.alpha_c_final is not None or self.alpha_r_final is not None

    def rates_at(self, trial: int) -> tuple[float, float]:
        """(alpha_c, alpha_r) of learning trial ``trial`` (0: the first); see ``alpha_c_final``."""
        fraction = min(max(trial, 0) / self.rate_decay_trials, 1.0)
        return tuple(
            float(start if final is None else start + fraction * (final - start))
            for start, final in (
                (self.alpha_c, self.alpha_c_final),
                (self.alpha_r, self.alpha_r_final),
            )
        )

    #: The fields set from the task when left None: field -> (rule, value at the paper's pendulum)
    #: (``task_knowledge.with_task_units``). alpha_c and alpha_r need no rule: the critic's samples
    #: move by a fraction of the TD error and the reference's by a fraction of x_r - x_hat, both
    #: independent of the reward's and the state's scales.
    task_units: ClassVar[dict[str, tuple[str, float]]] = {
        "gamma": ("horizon", 0.97),
        "lam": ("horizon", 0.65),
        # Table 2: N and K of each memory
        **memory_units("critic", "states", 2000, 20),
        **memory_units("process", "transitions", 100, 9),
        **memory_units("reference", "states", 2000, 20),
    }

    parameter_constraints: ClassVar[dict[str, list]] = {
        **TD_LAMBDA,
        "alpha_r": [Interval(Real, 0, 1)],
        "alpha_c_final": [Interval(Real, 0, 1), None],
        "alpha_r_final": [Interval(Real, 0, 1), None],
        "rate_decay_trials": [Interval(Integral, 1, None)],
        **{memory: [InstanceOf(LLRConfig)] for memory in ("critic", "process", "reference")},
        "exploration": [InstanceOf(Exploration)],
        **SHARED_CONSTRAINTS,
        "inverse_query": [Options("previous", "zero")],
        "critic_gradient_at": [Options("next", "previous")],
        "reachable_rule": [Options(*REACHABLE_RULES)],
        "action_cost": [Interval(Real, 0, None), WEIGHTS, None],
        "reachable_grid": [Interval(Integral, 2, None)],
        "reference_insert_rate": [Interval(Real, 0, 1)],
        "initial_value": [Options("critic", "zero")],
        **REHEARSAL,
        "backend": BACKEND,
    }

    def __post_init__(self) -> None:
        check_config(self)
        with_memory_defaults(self)

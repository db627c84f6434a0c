"""MPC, the learner recommended for a new task (key ``recommended``): act by planning in the learned
models, with S-AC's critic as the terminal value.

Every real and greedy action comes from a sampling planner (:mod:`~rmac_mj.agents.sampling_planner`)
over a horizon in seconds, in the learned LLR model of the process and the reward
(:class:`~rmac_mj.agents.planning.TransitionModel`, queried through its cached local fits,
:mod:`~rmac_mj.approximators.local_fits`); a sequence scores its predicted rewards plus the
discounted critic value where it ends. The critic and the actor are S-AC's (Algorithm 1), learned
from the real transitions with the actions applied and from short rollouts in the model branched
from visited states (Dyna, :class:`~rmac_mj.agents.planning.Planning`); the actor's closed-loop
rollout is one of the planner's population, and S-AC's exploration is added to the planned action.
Where the reward is sparse (every real reward so far one constant, less the declared action cost),
the unknown is valued optimistically (R-MAX, ``MPCConfig.sparse_unknown_value``); a dense reward
leaves that off from its second step.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Iterator
from numbers import Real
from typing import ClassVar

import numpy as np

from rmac_mj.agents.base import RefusedTransition
from rmac_mj.agents.planning import Planning
from rmac_mj.agents.sampling_planner import Planner, SamplingPlanner
from rmac_mj.agents.standard_ac import StandardACConfig, StandardActorCritic
from rmac_mj.agents.task_knowledge import PAPER_TIMESTEP
from rmac_mj.approximators.local_fits import LocalFits
from rmac_mj.approximators.tile_coding import feature_count
from rmac_mj.constraints import InstanceOf, Interval


@dataclasses.dataclass(frozen=True)
class MPCConfig(StandardACConfig):
    """S-AC's settings (:class:`StandardACConfig`: critic, actor, exploration) with a planner.

    Attributes:
      planner: the sampling planner that chooses every real and greedy action.
      planning: the critic's rollouts in the learned model: ``steps`` simulated transitions per real
        one, in rollouts of ``horizon`` control steps (None: 1 s of the task) branched from states of
        the model's memory (visited states).
      unknown_value: optimism in the face of uncertainty that reaches the critic (R-MAX's value of
        the unknown, as an optimistic initial value that fades with visits), on from the first step
        whatever the rewards: the planner values a state by V(x) + Phi(x), with Phi(x) =
        ``unknown_value`` x the reward's scale (its largest |r| so far) / (1 - gamma) x the state's
        novelty, the mean over the critic's tilings of 1 / sqrt(1 + n), n the real learning steps
        that visited the tile (1 where none did). The critic learns V from rewards shaped by that
        potential, r + gamma Phi(x') - Phi(x) (Ng, Harada and Russell 1999), so that V + Phi is the
        learned value where data is and Phi where none is: the horizon's terminal value pulls
        towards where the learner has not been, and the pull vanishes as data arrives. Greedy
        trials plan with the same V + Phi (V alone undervalues the states that are rarely
        visited). 0: none unless the reward is sparse (``sparse_unknown_value``).
      sparse_unknown_value: the same optimism, decided by the learner's own data: on while the
        reward is sparse so far, that is while every real reward less the task's declared action
        cost (``ActionSpace.cost`` P: r + sum_i P_i u_i^2) has been one constant, from the second
        such reward on. The rewards then tell nothing of their scale, so the unknown is worth, per
        step, the most an action can cost (sum_i P_i max(low_i^2, high_i^2): the push that reaching
        it may take) plus ``sparse_unknown_value`` x the task's declared ``reward_scale``, else one
        reward unit: Phi of a never-visited state is that / (1 - gamma). Once a reward differs from
        the constant, Phi stays with that scale, fading with visits; if the second real reward
        already differs (a dense reward), the optimism is never on and the learner is bit for bit
        MPC without it. 0: off. Unused with ``unknown_value``.
    """

    planner: SamplingPlanner = SamplingPlanner()
    planning: Planning = Planning(steps=30, start="memory", horizon=None)
    unknown_value: float = 0.0
    sparse_unknown_value: float = 0.1

    task_units: ClassVar[dict[str, tuple[str, float]]] = {
        **StandardACConfig.task_units,
        "alpha_a": ("reward", 0.002),
    }
    parameter_constraints: ClassVar[dict[str, list]] = {
        **StandardACConfig.parameter_constraints,
        "planner": [InstanceOf(SamplingPlanner)],
        "unknown_value": [Interval(Real, 0, None)],
        "sparse_unknown_value": [Interval(Real, 0, None)],
    }

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.planning.steps:
            raise ValueError("MPCConfig.planning.steps must be > 0: the planner needs the model")


class MPC(StandardActorCritic):
    """Model-predictive control on the learned LLR models (:class:`MPCConfig`); S-AC's interface
    and state, plus the planner's warm start and the greedy trials' seed."""

    name = "recommended"
    display_name = "MPC (LLR models)"
    config_class = MPCConfig

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        c, model = self.config, self.rehearsal.model
        timestep = self.state_space.timestep or PAPER_TIMESTEP
        self.planner = Planner(c.planner, self.action_space, timestep)
        #: Greedy trials plan apart, so that evaluating never changes a learning trial's state.
        self._greedy_planner = Planner(c.planner, self.action_space, timestep)
        self.fits = LocalFits(model.memory, c.backend)
        self._box = (model.low, model.high, model.period)
        coder = self.coder
        self._coder = (
            coder.low,
            coder.high,
            coder.periodic,
            coder.scale,
            coder.offsets,
            coder.sizes,
            coder.strides,
            coder.tiling_size,
        )
        #: Greedy trials plan with draws of their own (seeded by this and the trial count), so that
        #: evaluating a learner never changes what it learns.
        self.greedy_seed_ = int(self.rng.integers(2**62))
        self._plan_rng = self.rng
        self._rehearsing = False
        self._greedy = False
        watches = not c.unknown_value and c.sparse_unknown_value > 0
        #: Real learning steps per tile of the critic's coder, while the optimism is on or may come
        #: on (``unknown_value``, ``sparse_unknown_value``); else None.
        self.visits_ = np.zeros(self.coder.num_features) if c.unknown_value or watches else None
        #: The constant every real reward so far has had, less its declared action cost, while the
        #: reward is sparse so far (``sparse_unknown_value``); None once one differed (or without
        #: that option).
        self.sparse_reward_: float | None = 0.0 if watches else None
        #: How many real rewards have had that constant (none yet: 0; the optimism is on from 2).
        self.sparse_rewards_ = 0
        #: The largest |r| + sum_i P_i u_i^2 of those rewards: the size the constant is compared at.
        self._sparse_size = 0.0
        #: The action applied last in a real step (whose cost a reward's residual takes off).
        self._prev_u = np.zeros(self.action_space.dim)
        self._action_cost = (
            np.zeros(self.action_space.dim)
            if self.action_space.cost is None
            else np.asarray(self.action_space.cost, dtype=float)
        )
        #: The most a step's action can cost, sum_i P_i max(low_i^2, high_i^2).
        self._largest_action_cost = float(
            self._action_cost @ np.maximum(self.action_space.low**2, self.action_space.high**2)
        )

    @classmethod
    def _memory_parts(cls, config, state_space, action_space) -> tuple[int, int]:
        """S-AC's arrays, the model's cached fits (derived data: not in the state) and, with the
        optimism, the visits of each tile (in the state too)."""
        arrays, state = super()._memory_parts(config, state_space, action_space)
        n, m, planning = state_space.dim, action_space.dim, config.planning
        outputs = n if planning.reward == "task" else n + 1
        fits = LocalFits.memory_estimate(
            n + m, outputs, planning.model_capacity, planning.model_neighbours
        )
        visits = 0
        if config.unknown_value or config.sparse_unknown_value:
            visits = 8 * feature_count(state_space.periodic, config.tile_coding)
        return arrays + fits + visits, state + visits

    # -- optimism in the critic -------------------------------------------------------------------
    def optimistic(self) -> bool:
        """Whether the planner's terminal value and the critic's rewards carry the potential Phi:
        with ``unknown_value`` always; with ``sparse_unknown_value`` from the second real reward
        with the same residual on, and, once that was so, for good."""
        if self.visits_ is None:
            return False
        return self.sparse_reward_ is None or self.sparse_rewards_ >= 2

    def novelty_of(self, tiles: np.ndarray) -> float:
        """The novelty of the state whose active tiles are ``tiles``: the mean over the tilings of
        1 / sqrt(1 + n), n the real learning steps that visited each tile (1 where none did)."""
        return float(np.mean(1.0 / np.sqrt(1.0 + self.visits_[tiles])))

    def potential_scale(self, reward_scale: float | None = None) -> float:
        """Phi of a never-visited state (0 while not :meth:`optimistic`): with ``unknown_value``,
        ``unknown_value`` x the reward's scale (``reward_scale``, default the running one) /
        (1 - gamma); with ``sparse_unknown_value``, (the largest action's declared cost + that value
        x the task's declared reward scale, else one reward unit) / (1 - gamma)."""
        if not self.optimistic():
            return 0.0
        c, declared = self.config, self.state_space.reward_scale
        if c.unknown_value:
            scale = self.reward_scale_ if reward_scale is None else reward_scale
            return c.unknown_value * (scale or declared or 1.0) / (1.0 - c.gamma)
        return (self._largest_action_cost + c.sparse_unknown_value * (declared or 1.0)) / (
            1.0 - c.gamma
        )

    def potential(self, x: np.ndarray) -> float:
        """Phi(x), the optimism of the canonical state x (0 while not :meth:`optimistic`)."""
        if not self.optimistic():
            return 0.0
        return self.potential_scale() * self.novelty_of(self.coder.active_tiles(x))

    def _sparse_after(self, reward: float) -> tuple:
        """(sparse_reward_, sparse_rewards_, the size of the rewards watched, visits_) once the real
        reward ``reward`` of the transition from the last applied action is seen: a residual
        r + sum_i P_i u_i^2 (P the declared action cost) equal to the constant so far counts (equal
        within 1e-6 of the largest |r| + sum_i P_i u_i^2 watched: an action or a reward rounded to
        float32 by the environment); one that differs ends the watch, and the optimism with it
        unless it was on (two equal residuals before)."""
        cost = float(self._action_cost @ (self._prev_u * self._prev_u))
        residual, constant, count = reward + cost, self.sparse_reward_, self.sparse_rewards_
        size = max(self._sparse_size, abs(reward) + cost)
        if count == 0:
            return residual, 1, size, self.visits_
        if abs(residual - constant) <= 1e-6 * size:
            return constant, count + 1, size, self.visits_
        return None, count, 0.0, self.visits_ if count >= 2 else None

    def _learn(self, reward: float, gamma: float, tiles: np.ndarray) -> None:
        """S-AC's update; while :meth:`optimistic`, from the reward shaped by the potential Phi (the
        reward's scale follows the unshaped reward). A real transition counts its visit and, while
        the reward is sparse so far, its residual (:meth:`_sparse_after`), both committed after
        the update is accepted."""
        if self.visits_ is None:
            return super()._learn(reward, gamma, tiles)
        before = self.sparse_reward_, self.sparse_rewards_, self._sparse_size, self.visits_
        if self.sparse_reward_ is not None and not self._rehearsing:
            watch = self._sparse_after(reward)
            self.sparse_reward_, self.sparse_rewards_, self._sparse_size, self.visits_ = watch
        try:
            self._learn_optimistic(reward, gamma, tiles)
        except RefusedTransition:
            self.sparse_reward_, self.sparse_rewards_, self._sparse_size, self.visits_ = before
            raise
        if self.visits_ is not None and not self._rehearsing:
            self.visits_[tiles] += 1.0

    def _learn_optimistic(self, reward: float, gamma: float, tiles: np.ndarray) -> None:
        if not self.optimistic():
            return super()._learn(reward, gamma, tiles)
        scale = self.reward_scale_
        if scale is not None and self._learns_scale and abs(reward) > scale:
            scale = abs(reward)
        phi = self.potential_scale(scale)
        shaped = reward + phi * (gamma * self.novelty_of(tiles) - self.novelty_of(self._prev_tiles))
        learns, self._learns_scale = self._learns_scale, False
        try:
            super()._learn(shaped, gamma, tiles)
        finally:
            self._learns_scale = learns
        if scale != self.reward_scale_:
            self.reward_scale_ = scale
            self._set_rate_a()

    # -- the action -----------------------------------------------------------------------------
    def _set_rehearsing(self, rehearsing: bool) -> None:
        super()._set_rehearsing(rehearsing)
        self._rehearsing = rehearsing

    def _plans(self) -> bool:
        """Whether this action is planned: in real and greedy trials, once the model can fit."""
        memory = self.rehearsal.model.memory
        return not self._rehearsing and memory.n_samples_ >= memory.n_neighbours

    def _planned(self, x: np.ndarray) -> np.ndarray:
        x = self.state_space.canonical(x)
        c = self.config
        bonus = 0.0
        if c.planner.optimism and not self._greedy:
            bonus = c.planner.optimism * (
                self.reward_scale_ or self.state_space.reward_scale or 1.0
            )
        planner = self._greedy_planner if self._greedy else self.planner
        return planner.plan(
            x,
            self.fits,
            self._box,
            self.critic_,
            self.actor_,
            self._coder,
            c.gamma,
            self._plan_rng,
            bonus,
            initial=self._policy(self.coder.active_tiles(x)),
            potential=self.potential_scale(),
            visits=self.visits_ if self.optimistic() else None,
        )

    def _start(self, x0: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        with self._plan_put_back_if_refused():
            if not self._rehearsing:
                self.planner.reset()
                self._greedy, self._plan_rng = False, self.rng
            u = super()._start(x0, self._explored_plan(x0, 0) if u is None else u)
            if not self._rehearsing:
                self._prev_u = u.copy()
            return u

    def _step(self, reward: float, x: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        with self._plan_put_back_if_refused():
            u = self._explored_plan(x, self._k + 1) if u is None else u
            u = super()._step(reward, x, u)
            if not self._rehearsing:
                self._prev_u = u.copy()
            return u

    def _explored_plan(self, x: np.ndarray, k: int) -> np.ndarray | None:
        """u_k planned in x plus S-AC's exploration; None (S-AC's actor chooses) while the model
        cannot fit yet or in a rollout. Refused if the plan's scores overflow."""
        if not self._plans():
            return None
        noise = self.config.exploration.sample(k, self.action_space.dim, self.rng, self.trial)
        planned = self._planned(x)
        if not np.isfinite(planned).all():
            raise self._overflow("the planned action's score")
        return self.action_space.clip(planned + noise)

    @contextlib.contextmanager
    def _plan_put_back_if_refused(self) -> Iterator[None]:
        """A refused call (:class:`RefusedTransition`: the plan's scores or S-AC's update overflow)
        leaves the warm start as it was; the boundary puts back the random generator."""
        warm_start = None if self.planner.mean_ is None else self.planner.mean_.copy()
        try:
            yield
        except RefusedTransition:
            self.planner.mean_ = warm_start
            raise

    def begin_greedy_trial(self) -> None:
        """A greedy trial plans afresh, with draws seeded by the learner and its trial count."""
        self._greedy_planner.reset()
        self._greedy = True
        self._plan_rng = np.random.default_rng([self.greedy_seed_, self.trials_])

    def _greedy_action(self, x: np.ndarray) -> np.ndarray:
        return self._planned(x) if self._plans() else super()._greedy_action(x)

    # -- state ------------------------------------------------------------------------------------
    def _state(self) -> dict[str, np.ndarray]:
        state = super()._state()
        state["greedy_seed"] = np.array(self.greedy_seed_, dtype=np.int64)
        if self.visits_ is not None:
            state["visits"] = self.visits_.copy()
        if self.sparse_reward_ is not None:
            state["sparse_reward"] = np.array([self.sparse_reward_, self._sparse_size])
            state["sparse_rewards"] = np.array(self.sparse_rewards_, dtype=np.int64)
            state["prev_u"] = self._prev_u.copy()
        if self.planner.mean_ is not None:
            state["plan"] = self.planner.mean_.copy()
        return state

    #: What the optimism keeps only at some moments: the visits while it is on or may come on, the
    #: watch of a sparse reward while it lasts (absent: never optimistic but by ``unknown_value``).
    _OPTIMISM_KEYS = ("visits", "sparse_reward", "sparse_rewards", "prev_u")

    def _may_lack(self, key: str) -> bool:
        return super()._may_lack(key) or key == "plan" or key in self._OPTIMISM_KEYS

    def _check_state(self, state: dict[str, np.ndarray]) -> None:
        super()._check_state(state)
        features, m = self.coder.num_features, self.action_space.dim
        if "visits" in state and (
            np.shape(state["visits"]) != (features,) or np.any(state["visits"] < 0)
        ):
            raise ValueError(f"{self.name}: state 'visits' must be {features} counts >= 0")
        if self.config.unknown_value and "visits" not in state:
            raise ValueError(f"{self.name}: state lacks 'visits', which unknown_value needs")
        watch = [key for key in ("sparse_reward", "sparse_rewards", "prev_u") if key in state]
        if watch and (
            len(watch) != 3
            or "visits" not in state
            or np.shape(state["sparse_reward"]) != (2,)
            or state["sparse_reward"][1] < 0
            or np.shape(state["sparse_rewards"]) != ()
            or int(state["sparse_rewards"]) < 0
            or np.shape(state["prev_u"]) != (m,)
        ):
            raise ValueError(
                f"{self.name}: state 'sparse_reward' (the constant and its size >= 0), "
                f"'sparse_rewards' (a count >= 0) and "
                f"'prev_u' ({m} values) come together, with 'visits'"
            )

    def _load_state(self, state: dict[str, np.ndarray]) -> None:
        super()._load_state(state)
        self.greedy_seed_ = int(state["greedy_seed"])
        self.planner.mean_ = np.array(state["plan"], dtype=float) if "plan" in state else None
        self.visits_ = np.array(state["visits"], dtype=float) if "visits" in state else None
        if "sparse_reward" in state:
            self.sparse_reward_, self._sparse_size = (float(v) for v in state["sparse_reward"])
            self.sparse_rewards_ = int(state["sparse_rewards"])
            self._prev_u = np.array(state["prev_u"], dtype=float)
        else:
            self.sparse_reward_, self.sparse_rewards_, self._sparse_size = None, 0, 0.0

"""A near-optimal return for a one-joint swing-up: the best sum of rewards per trial, by dynamic programming.

The learners are scored by the undiscounted sum of the H rewards of a trial from a fixed start x_0
(section 6). For a deterministic, time-invariant system and a fixed horizon the best such sum is the
value V_0(x_0) of the finite-horizon Bellman recursion

    V_H(x) = 0,    V_t(x) = max_u [ rho(x, u) + V_{t+1}(f(x, u)) ],   t = H-1, ..., 0,

with rho the task's own reward (``task.reward_of``) and f one control step of the task's *own* MuJoCo
model. Everything about the problem is read from the environment (:class:`Problem`): the horizon, the
control step, the action range, the start state, the reward and the state map ``physics.state_of``;
nothing of a task is repeated here. What this solver needs of a task: one joint (x = [angle, speed],
the angle periodic over the learner state's box), one actuator, a deterministic start. A task declares
it as its reference (``tasks.common.Reference("dynamic programming", {grid settings})``).

It is solved on a grid (periodic in the angle, a box in the speed) with a finite action set that
contains the extremes of the action range, and V_{t+1} is read between grid nodes by bilinear
interpolation. Why this choice:

- *Finite horizon, undiscounted*: it is exactly the learners' metric, not a discounted surrogate; a
  stationary policy of a discounted problem would answer a different question.
- *Transition table once*: the dynamics do not depend on time, so f(x_i, u_a) is simulated once for every
  grid node and action (batched with ``mujoco.rollout``) and stored as a sparse interpolation matrix;
  each of the H backups is then one sparse mat-vec and a max.
- *Bilinear interpolation* is an averager (non-negative weights summing to one), so the approximate
  Bellman operator stays monotone and the recursion cannot blow up (Gordon 1995; Munos & Moore 2002).
- *No time discretisation error*: the DP steps with the true control period, so the only errors are the
  state interpolation and the finite action set, which the convergence check measures.

The same greedy policy run with the learners' exploration noise gives the *exploration floor*
(:mod:`rmac_mj.solvers.exploration_floor`).

The DP value is an approximation; the number to report is the return of its greedy policy simulated on the
MuJoCo model from x_0 (one-step look-ahead on V_{t+1} from the exact, off-grid state). Being the return of
an actual admissible policy on the actual model, it is a lower bound on the true optimum; the DP value
next to it is its check. Results are cached as JSON keyed by the problem (the compiled model, the task's
source and settings), the grid and the solver version, so ``rmac-mj optimal`` and Fig. 2 reuse them.

    from rmac_mj.solvers import dynamic_programming as optimal
    from rmac_mj.solvers.problem import problem_identity
    env = protocol.make_environment()
    result = optimal.optimal_return(env, problem_identity(protocol.domain, protocol.task))
    print(result.simulated_return, result.dp_value)

The module is one algorithm read top to bottom (config, problem, result, grid, backups, greedy rollout,
cache), which is why it runs past 400 lines; its one separable use, the exploration floor, is its own.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np
import scipy.sparse
from dm_control.rl import control
from mujoco import rollout

from rmac_mj.results.files import cached_json
from rmac_mj.rollout import learner_state_of, steps_per_trial
from rmac_mj.solvers.problem import Ticker, TrialProblem, cache_directory, versions
from rmac_mj.solvers.problem import cache_key as problem_cache_key

#: Bumped whenever a change to this module changes the numbers it computes: old cache entries are ignored.
#: 2: the problem is read from the environment (the task's own reward_of instead of a copy of it).
SOLVER_VERSION = 2


@dataclasses.dataclass(frozen=True)
class OptimalConfig:
    """How finely the problem is solved (the problem itself comes from the environment: :class:`Problem`).

    A task's reference declares the settings it needs (``Reference.settings``); the defaults are the
    DC-motor pendulum's converged grid (docs/optimal.md).
    """

    n_phi: int = 361
    """Grid nodes in the angle over one period (periodic; spacing period / n_phi)."""
    n_phi_dot: int = 241
    """Grid nodes in the speed over [-max_phi_dot, max_phi_dot], ends included."""
    max_phi_dot: float = 20.0
    """Half-width of the speed grid (rad/s). Next states beyond it are clipped to its edge; the solver
    raises if the greedy trajectory comes within 10% of the edge."""
    n_actions: int = 25
    """Actions evenly spaced over the action range, extremes included."""
    lookahead_actions: int = 121
    """Actions (same range) the greedy policy chooses from when simulated: its one-step look-ahead is
    cheap, so it may search finer than the DP's backups."""
    check_convergence: bool = True
    """Also solve on a grid of half the resolution in each state dimension and with half as many action
    intervals, and report how much the answers move."""
    n_threads: int = 0
    """Threads for the batched transition simulation; 0 means ``os.cpu_count()``. Does not change results."""

    def __post_init__(self) -> None:
        for name in ("n_phi", "n_phi_dot", "n_actions", "lookahead_actions"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool):
                raise TypeError(f"OptimalConfig.{name} must be an int, got {value!r}")
        if self.n_phi < 4:
            raise ValueError(f"OptimalConfig.n_phi must be >= 4, got {self.n_phi}")
        if self.n_phi_dot < 3:
            raise ValueError(f"OptimalConfig.n_phi_dot must be >= 3, got {self.n_phi_dot}")
        if self.n_actions < 2:
            raise ValueError(
                f"OptimalConfig.n_actions must be >= 2 (the two extremes), got {self.n_actions}"
            )
        if self.lookahead_actions < 2:
            raise ValueError(
                f"OptimalConfig.lookahead_actions must be >= 2, got {self.lookahead_actions}"
            )
        if not (
            np.isscalar(self.max_phi_dot) and np.isfinite(self.max_phi_dot) and self.max_phi_dot > 0
        ):
            raise ValueError(
                f"OptimalConfig.max_phi_dot must be a positive finite number, "
                f"got {self.max_phi_dot!r}"
            )
        if not isinstance(self.n_threads, (int, np.integer)) or self.n_threads < 0:
            raise ValueError(f"OptimalConfig.n_threads must be an int >= 0, got {self.n_threads!r}")
        object.__setattr__(self, "max_phi_dot", float(self.max_phi_dot))

    def coarser(self) -> OptimalConfig:
        """The convergence check's problem: about half the nodes per state dimension, half the action
        intervals of the DP and of the look-ahead (the extremes and every other action stay in each
        set), no further check."""
        return dataclasses.replace(
            self,
            n_phi=max(4, self.n_phi // 2),
            n_phi_dot=max(3, (self.n_phi_dot + 1) // 2),
            n_actions=max(2, (self.n_actions + 1) // 2),
            lookahead_actions=max(2, (self.lookahead_actions + 1) // 2),
            check_convergence=False,
        )


class Problem(TrialProblem):
    """The trial of a one-joint task as the DP sees it, read from its environment.

    Attributes:
      model: the task's compiled MuJoCo model (one joint, one actuator, no activation state).
      n_substeps: physics steps per control step; horizon: control steps per trial.
      low, high: the action range (the action spec's bounds).
      start: the full physics state at the start of a trial (``mj_getState``, FULLPHYSICS).
      angle_low, period: the angle's grid range [angle_low, angle_low + period) (the learner state's box).
      describe: a few words on the problem, for people.
    """

    owner = "optimal"

    def __init__(self, env: control.Environment):
        super().__init__(env)
        model, physics = self.model, env.physics
        if model.nq != 1 or model.nv != 1 or model.na != 0 or model.nu != 1:
            raise ValueError(
                f"optimal: the DP needs a one-joint model with one actuator and no "
                f"activation state (x = [angle, speed]), got nq={model.nq}, nv={model.nv}, "
                f"na={model.na}, nu={model.nu}"
            )
        learner_state = learner_state_of(env)
        if tuple(learner_state.periodic) != (True, False):
            raise ValueError(
                f"optimal: the DP needs x = [angle (periodic), speed], got periodic "
                f"{learner_state.periodic}"
            )
        self.angle_low = float(learner_state.low[0])
        self.period = float(learner_state.high[0]) - self.angle_low
        spec = env.action_spec()
        self.low, self.high = float(np.min(spec.minimum)), float(np.max(spec.maximum))
        self.horizon = steps_per_trial(env)
        env.reset()
        self.start = self._full_state(physics.data.ptr)
        self._check_deterministic_start(self.start)
        self.describe = (
            f"horizon {self.horizon} of {self.control_timestep:g} s, actions in "
            f"[{self.low:g}, {self.high:g}]"
        )

    @property
    def start_z(self) -> np.ndarray:
        """z_0 = [qpos, qvel] at the start; shape (2,)."""
        return self.start[1:3].copy()

    def state_of(self, z: np.ndarray) -> np.ndarray:
        """The task's x (angle wrapped) of physics states z = [qpos, qvel], shape (..., 2)."""
        return np.asarray(self.env.physics.state_of(z[..., :1], z[..., 1:]), dtype=float)

    def reward(self, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        """rho(x(z), u), the task's own reward, for states z (..., 2) and actions u (...,)."""
        return np.asarray(self.env.task.reward_of(self.state_of(z), np.asarray(u)[..., None]))

    def identity(self) -> dict[str, Any]:
        """What :func:`cache_key` hashes besides the grid: the problem as numbers."""
        return {
            "horizon": self.horizon,
            "control_timestep": self.control_timestep,
            "n_substeps": self.n_substeps,
            "action_range": [self.low, self.high],
            "start": self.start.tolist(),
            "angle_range": [self.angle_low, self.period],
        }


@dataclasses.dataclass(frozen=True)
class SolveSummary:
    """The answer of one DP solve (one grid and action set)."""

    n_phi: int
    n_phi_dot: int
    n_actions: int
    dp_value: float
    """V_0(x_0) of the grid DP (interpolated)."""
    simulated_return: float
    """Sum of the H rewards of the greedy policy simulated on the MuJoCo model from x_0."""
    runtime_s: float


@dataclasses.dataclass(frozen=True)
class OptimalResult:
    """The near-optimal return.

    Attributes:
      simulated_return: the number to report: return of the DP's greedy policy, simulated on the model.
      dp_value: the DP's own estimate V_0(x_0), its check.
      config: the ``OptimalConfig`` solved.
      fine: the ``SolveSummary`` of the configured grid.
      coarse: the ``SolveSummary`` of ``config.coarser()``, or None without the convergence check.
      states: ndarray of shape (horizon + 1, 2): greedy trajectory x_0..x_H, angle wrapped.
      actions: ndarray of shape (horizon,): actions u_0..u_{H-1}.
      rewards: ndarray of shape (horizon,): r_1..r_H.
      problem: what was solved (:meth:`Problem.identity`), as numbers.
      runtime_s: wall time of the whole computation (s); that of the run that filled the cache if cached.
      versions: package versions that computed it.
      from_cache: True when read from the cache rather than computed now.
    """

    simulated_return: float
    dp_value: float
    config: OptimalConfig
    fine: SolveSummary
    coarse: SolveSummary | None
    states: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    problem: dict[str, Any]
    runtime_s: float
    versions: dict[str, str]
    from_cache: bool = False

    @property
    def convergence_gap(self) -> float | None:
        """|simulated return (fine) - simulated return (coarse)|, or None without the check."""
        if self.coarse is None:
            return None
        return abs(self.fine.simulated_return - self.coarse.simulated_return)

    def describe(self) -> str:
        """A few lines for people: the return, its check, the convergence and the cost."""
        c = self.config
        lines = [
            f"near-optimal return per trial (greedy DP policy simulated on the model): "
            f"{self.simulated_return:.2f}",
            f"DP value V_0(x_0): {self.dp_value:.2f}  "
            f"(grid {c.n_phi} x {c.n_phi_dot} over the angle's period x speeds in "
            f"[-{c.max_phi_dot:g}, {c.max_phi_dot:g}], {c.n_actions} actions in the DP, "
            f"{c.lookahead_actions} in the look-ahead, horizon {self.problem['horizon']})",
        ]
        if self.coarse is not None:
            lines.append(
                f"coarser grid {self.coarse.n_phi} x {self.coarse.n_phi_dot}, "
                f"{self.coarse.n_actions} actions: {self.coarse.simulated_return:.2f} "
                f"(DP {self.coarse.dp_value:.2f}); "
                f"convergence gap {self.convergence_gap:.2f}"
            )
        cached = " (read from the cache)" if self.from_cache else ""
        lines.append(f"computed in {self.runtime_s:.1f} s{cached}")
        return "\n".join(lines)

    def to_json_dict(self) -> dict[str, Any]:
        """A plain dict (lists and numbers) that ``json.dump`` writes and ``from_json_dict`` reads."""
        return {
            "simulated_return": self.simulated_return,
            "dp_value": self.dp_value,
            "convergence_gap": self.convergence_gap,
            "config": dataclasses.asdict(self.config),
            "fine": dataclasses.asdict(self.fine),
            "coarse": None if self.coarse is None else dataclasses.asdict(self.coarse),
            "states": self.states.tolist(),
            "actions": self.actions.tolist(),
            "rewards": self.rewards.tolist(),
            "problem": self.problem,
            "runtime_s": self.runtime_s,
            "versions": dict(self.versions),
            "solver_version": SOLVER_VERSION,
        }

    @classmethod
    def from_json_dict(cls, d: dict[str, Any], from_cache: bool = True) -> OptimalResult:
        return cls(
            simulated_return=float(d["simulated_return"]),
            dp_value=float(d["dp_value"]),
            config=OptimalConfig(**d["config"]),
            fine=SolveSummary(**d["fine"]),
            coarse=None if d["coarse"] is None else SolveSummary(**d["coarse"]),
            states=np.asarray(d["states"], dtype=float).reshape(-1, 2),
            actions=np.asarray(d["actions"], dtype=float),
            rewards=np.asarray(d["rewards"], dtype=float),
            problem=dict(d["problem"]),
            runtime_s=float(d["runtime_s"]),
            versions=dict(d["versions"]),
            from_cache=from_cache,
        )


# --------------------------------------------------------------------------------------------------
# The grid, actions, transitions


def action_set(problem: Problem, n_actions: int) -> np.ndarray:
    """ndarray of shape (n_actions,): actions evenly spaced over the problem's action range."""
    return np.linspace(problem.low, problem.high, n_actions)


def state_grid(config: OptimalConfig, problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """The grid axes: angles of shape (n_phi,) over one period from ``problem.angle_low``, speeds of
    shape (n_phi_dot,)."""
    phi = problem.angle_low + problem.period * np.arange(config.n_phi) / config.n_phi
    phi_dot = np.linspace(-config.max_phi_dot, config.max_phi_dot, config.n_phi_dot)
    return phi, phi_dot


def simulate_transitions(
    model: mujoco.MjModel,
    phi: np.ndarray,
    phi_dot: np.ndarray,
    u: np.ndarray,
    n_substeps: int,
    n_threads: int = 1,
    chunk: int = 1 << 17,
    progress: Callable[[str], None] | None = None,
) -> np.ndarray:
    """One control step of a one-joint MuJoCo model from many states, batched with ``mujoco.rollout``.

    Args:
      phi, phi_dot, u: ndarrays of shape (n,): start qpos, qvel and the action held.
      n_substeps: physics steps per control step.
    Returns:
      ndarray of shape (n, 2): [qpos, qvel] after the step (the angle *not* wrapped).
    """
    n = phi.shape[0]
    datas = [mujoco.MjData(model) for _ in range(max(1, n_threads))]
    size = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    if size != 3:  # [time, qpos, qvel]: one joint, no activation state
        raise ValueError(f"optimal: a one-joint model has a physics state of 3 numbers, got {size}")
    out = np.empty((n, 2))
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        state0 = np.zeros((stop - start, size))
        state0[:, 1] = phi[start:stop]
        state0[:, 2] = phi_dot[start:stop]
        control = u[start:stop].reshape(-1, 1, 1)
        states, _ = rollout.rollout(
            model, datas if len(datas) > 1 else datas[0], state0, control, nstep=n_substeps
        )
        out[start:stop] = states[:, -1, 1:3]
        if progress is not None:
            progress(f"simulated {stop:,} of {n:,} transitions")
    return out


def interpolation_matrix(
    config: OptimalConfig, problem: Problem, next_states: np.ndarray
) -> scipy.sparse.csr_matrix:
    """Bilinear interpolation on the grid as a sparse matrix.

    Args:
      next_states: ndarray of shape (m, 2), [angle, speed] (angle any real; speed clipped to the grid).
    Returns:
      csr_matrix of shape (m, n_phi * n_phi_dot) with 4 non-negative weights summing to 1 per row, so that
      ``W @ V.ravel()`` interpolates a grid function V of shape (n_phi, n_phi_dot) at ``next_states``.
    """
    n_phi, n_dot = config.n_phi, config.n_phi_dot
    d_phi = problem.period / n_phi
    d_dot = 2.0 * config.max_phi_dot / (n_dot - 1)
    s = (next_states[:, 0] - problem.angle_low) / d_phi
    i0 = np.floor(s)
    a = s - i0  # weight of the upper angle node, in [0, 1)
    i0 = i0.astype(np.int64) % n_phi
    i1 = (i0 + 1) % n_phi  # periodic in the angle
    w = (
        np.clip(next_states[:, 1], -config.max_phi_dot, config.max_phi_dot) + config.max_phi_dot
    ) / d_dot
    j0 = np.clip(np.floor(w).astype(np.int64), 0, n_dot - 2)
    b = np.clip(w - j0, 0.0, 1.0)  # weight of the upper speed node
    m = next_states.shape[0]
    # 32-bit indices where they fit: the default table has 2.2 M rows, and this halves its index memory.
    index = np.int32 if max(4 * m, n_phi * n_dot) < np.iinfo(np.int32).max else np.int64
    cols = np.stack(
        [i0 * n_dot + j0, i0 * n_dot + j0 + 1, i1 * n_dot + j0, i1 * n_dot + j0 + 1], axis=1
    ).astype(index)
    vals = np.stack([(1 - a) * (1 - b), (1 - a) * b, a * (1 - b), a * b], axis=1)
    return scipy.sparse.csr_matrix(
        (vals.ravel(), cols.ravel(), np.arange(0, 4 * m + 1, 4, dtype=index)),
        shape=(m, n_phi * n_dot),
    )


# --------------------------------------------------------------------------------------------------
# The solver


def solve_values(
    config: OptimalConfig, problem: Problem, announce: Callable[[str], None] | None = None
) -> np.ndarray:
    """Backward finite-horizon DP on the grid; ``announce`` hears its progress (about every 10 s).

    Returns:
      ndarray of shape (horizon + 1, n_phi, n_phi_dot), float32: V_t on the grid for t = 0..H (V_H = 0).
    """
    phi, phi_dot = state_grid(config, problem)
    actions = action_set(problem, config.n_actions)
    n_states, n_act = config.n_phi * config.n_phi_dot, config.n_actions
    # Row s * n_act + a is the transition from grid node s (angle-major) under action a.
    pp, dd, uu = np.meshgrid(phi, phi_dot, actions, indexing="ij")
    threads = config.n_threads or os.cpu_count() or 1
    ticker = Ticker(announce)
    next_states = simulate_transitions(
        problem.model,
        pp.ravel(),
        dd.ravel(),
        uu.ravel(),
        problem.n_substeps,
        threads,
        progress=ticker,
    )
    transition = interpolation_matrix(config, problem, next_states)
    rewards = problem.reward(np.stack([pp, dd], axis=-1), uu).reshape(n_states, n_act)
    values = np.zeros((problem.horizon + 1, n_states), dtype=np.float32)
    v = np.zeros(n_states)
    for t in range(problem.horizon - 1, -1, -1):
        v = (rewards + (transition @ v).reshape(n_states, n_act)).max(axis=1)
        values[t] = v
        ticker(f"backup {problem.horizon - t}/{problem.horizon}")
    return values.reshape(problem.horizon + 1, config.n_phi, config.n_phi_dot)


def interpolate_value(
    config: OptimalConfig, problem: Problem, value: np.ndarray, states: np.ndarray
) -> np.ndarray:
    """Bilinear interpolation of one grid function ``value`` (n_phi, n_phi_dot) at ``states`` (m, 2);
    shape (m,)."""
    return (
        interpolation_matrix(config, problem, np.asarray(states, dtype=float).reshape(-1, 2))
        @ value.astype(float).ravel()
    )


def greedy_rollout(
    config: OptimalConfig, problem: Problem, values: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Simulate the DP's greedy policy on the model from the task's start.

    At step k, from the exact (off-grid) state z_k, each of ``config.lookahead_actions`` actions is
    simulated for one control step and scored rho(x_k, u) + V_{k+1}(x_{k+1}); the best is applied
    (ties: the lowest action).

    Returns:
      states (horizon + 1, 2) (the task's x, angle wrapped), actions (horizon,), rewards (horizon,).
    """
    model = problem.model
    actions = action_set(problem, config.lookahead_actions)
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, problem.start, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    states = np.empty((problem.horizon + 1, 2))
    applied = np.empty(problem.horizon)
    rewards = np.empty(problem.horizon)
    for k in range(problem.horizon):
        z = np.concatenate([data.qpos, data.qvel])
        states[k] = problem.state_of(z)
        candidates = simulate_transitions(
            model,
            np.full(len(actions), z[0]),
            np.full(len(actions), z[1]),
            actions,
            problem.n_substeps,
        )
        scores = problem.reward(np.broadcast_to(z, (len(actions), 2)), actions) + interpolate_value(
            config, problem, values[k + 1], candidates
        )
        u = actions[int(np.argmax(scores))]
        rewards[k] = problem.reward(z, u)
        applied[k] = u
        data.ctrl[:] = u
        for _ in range(problem.n_substeps):
            mujoco.mj_step(model, data)
    states[-1] = problem.state_of(np.concatenate([data.qpos, data.qvel]))
    return states, applied, rewards


def _solve_once(
    config: OptimalConfig,
    problem: Problem,
    values: np.ndarray | None = None,
    announce: Callable[[str], None] | None = None,
) -> tuple[SolveSummary, np.ndarray, np.ndarray, np.ndarray]:
    """Solve (or take the given ``values``), then simulate the greedy policy."""
    start = time.perf_counter()
    if values is None:
        values = solve_values(config, problem, announce)
    dp_value = float(interpolate_value(config, problem, values[0], problem.start_z)[0])
    states, actions, rewards = greedy_rollout(config, problem, values)
    peak = float(np.max(np.abs(states[:, 1])))
    if peak > 0.9 * config.max_phi_dot:
        raise ValueError(
            f"optimal: the greedy trajectory reaches a speed of {peak:.1f}, within 10% "
            f"of the grid edge max_phi_dot={config.max_phi_dot}; widen the grid"
        )
    summary = SolveSummary(
        n_phi=config.n_phi,
        n_phi_dot=config.n_phi_dot,
        n_actions=config.n_actions,
        dp_value=dp_value,
        simulated_return=float(np.sum(rewards)),
        runtime_s=time.perf_counter() - start,
    )
    return summary, states, actions, rewards


def solve(
    env: control.Environment,
    config: OptimalConfig = OptimalConfig(),
    announce: Callable[[str], None] | None = None,
    key: str | None = None,
) -> OptimalResult:
    """Solve the trial of ``env`` without the cache (see :func:`optimal_return`); with ``key`` (its
    :func:`cache_key`), the values are kept for :func:`solved_values`."""
    start = time.perf_counter()
    problem = Problem(env)
    values = solve_values(config, problem, announce)
    if key is not None:
        _remember(key, problem, values)
    fine, states, actions, rewards = _solve_once(config, problem, values)
    coarse = (
        _solve_once(config.coarser(), problem, announce=announce)[0]
        if config.check_convergence
        else None
    )
    return OptimalResult(
        simulated_return=fine.simulated_return,
        dp_value=fine.dp_value,
        config=config,
        fine=fine,
        coarse=coarse,
        states=states,
        actions=actions,
        rewards=rewards,
        problem=problem.identity(),
        runtime_s=time.perf_counter() - start,
        versions=versions(),
    )


#: The last solved DP (its values are 35 MB at the default grid and not cached on disk, only its
#: answer), by cache key: the exploration floor explores with the greedy policy of the DP that the
#: near-optimal return just solved, and a sweep asks for several floors of one DP.
_SOLVED: dict[str, tuple[Problem, np.ndarray]] = {}


def _remember(key: str, problem: Problem, values: np.ndarray) -> None:
    _SOLVED.clear()
    _SOLVED[key] = problem, values


def solved_values(
    env: control.Environment,
    identity: dict[str, Any],
    config: OptimalConfig,
    announce: Callable[[str], None] | None = None,
) -> tuple[Problem, np.ndarray]:
    """The problem of ``env`` and its DP values V_t (:func:`solve_values`): those this process
    last solved for the same :func:`cache_key` if any, else solved now (and kept)."""
    key = cache_key(env, identity, config)
    if key not in _SOLVED:
        problem = Problem(env)
        _remember(key, problem, solve_values(config, problem, announce))
    return _SOLVED[key]


# --------------------------------------------------------------------------------------------------
# The cache


def cache_key(env: control.Environment, identity: dict[str, Any], config: OptimalConfig) -> str:
    """Hex digest identifying a result (:func:`rmac_mj.solvers.problem.cache_key` of this solver)."""
    return problem_cache_key(env, identity, config, SOLVER_VERSION)


def optimal_return(
    env: control.Environment,
    identity: dict[str, Any],
    config: OptimalConfig = OptimalConfig(),
    cache_dir: str | os.PathLike | None = None,
    refresh: bool = False,
    announce: Callable[[str], None] | None = None,
) -> OptimalResult:
    """The near-optimal return per trial of ``env``, from the cache if there, else solved and cached.

    Args:
      env: the task's environment (reset and stepped only on copies of its physics).
      identity: what names the problem for the cache (``problem.problem_identity``): the task
        and its settings.
      config: grid and actions.
      cache_dir: directory of ``optimal-<key>.json`` files; default ``problem.default_cache_dir()``.
      refresh: solve again even if cached (and overwrite the entry).
      announce: called with a one-line message before a solve and with its progress, e.g. ``print``.
    """
    if not isinstance(config, OptimalConfig):
        raise TypeError(
            f"optimal_return: config must be an OptimalConfig, got {type(config).__name__}"
        )
    directory = cache_directory(cache_dir)
    key = cache_key(env, identity, config)
    return cached_json(
        directory / f"optimal-{key}.json",
        lambda document: OptimalResult.from_json_dict(document, from_cache=True),
        lambda: solve(env, config, announce, key=key),
        refresh=refresh,
        announce=announce,
        message=(
            f"computing the near-optimal return by dynamic programming (about a minute on 2 "
            f"idle cores; cached after, in {directory})"
        ),
    )

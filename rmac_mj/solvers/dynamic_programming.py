"""A near-optimal return for a one-joint swing-up: the best sum of rewards per trial, by dynamic programming.

The learners are scored by the undiscounted sum of the H rewards of a trial from a fixed start x_0
(section 6). For a deterministic, time-invariant system and a fixed horizon the best such sum is the
value V_0(x_0) of the finite-horizon Bellman recursion

    V_H(x) = 0,    V_t(x) = max_u [ rho(x, u) + V_{t+1}(f(x, u)) ],   t = H-1, ..., 0,

with rho the task's own reward (``task.reward_of``) and f one control step of the task's own MuJoCo
model, both read from the environment (:class:`~rmac_mj.solvers.dynamic_programming_grid.Problem`).
What it needs of a task: one joint (x = [angle, speed], the angle periodic over the learner state's
box), one actuator, a deterministic start; a task declares it as its optimum
(``tasks.Optimum("dynamic programming", {grid settings})``).

It is solved on a grid with a finite action set that contains the extremes of the action range
(:mod:`rmac_mj.solvers.dynamic_programming_grid`); the transitions f(x_i, u_a) of every node and
action are simulated once (the dynamics do not depend on time), so each of the H backups is one sparse
mat-vec and a max. Finite horizon and undiscounted, it is exactly the learners' metric, and it steps
with the true control period, so the only errors are the state interpolation and the finite action
set, which the convergence check (a coarser grid) measures.

The number to report is the return of the DP's greedy policy simulated on the MuJoCo model from x_0
(one-step look-ahead on V_{t+1} from the exact, off-grid state): the return of an admissible policy on
the actual model, hence a lower bound on the true optimum; the DP value next to it is its check. The
same greedy policy run with the learners' exploration noise gives the exploration floor
(:mod:`rmac_mj.solvers.exploration_floor`). Results are cached as JSON keyed by the problem, the grid
and ``SOLVER_VERSION`` (:func:`rmac_mj.solvers.problem.cache_key`).

    from rmac_mj.solvers import dynamic_programming as optimal
    from rmac_mj.solvers.problem import problem_identity
    env = protocol.make_environment()
    result = optimal.optimal_return(env, problem_identity(protocol.domain, protocol.task))
    print(result.simulated_return, result.dp_value)
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np
from dm_control.rl import control

from rmac_mj._physics_timers import untimed
from rmac_mj.results.files import cached_json
from rmac_mj.solvers.dynamic_programming_config import OptimalConfig
from rmac_mj.solvers.dynamic_programming_grid import (
    Problem,
    action_set,
    interpolate_value,
    interpolation_matrix,
    simulate_transitions,
    state_grid,
)
from rmac_mj.solvers.problem import Ticker, cache_directory, versions
from rmac_mj.solvers.problem import cache_key as problem_cache_key

__all__ = [
    "SOLVER_VERSION",
    "OptimalConfig",
    "OptimalResult",
    "Problem",
    "SolveSummary",
    "action_set",
    "cache_key",
    "greedy_rollout",
    "interpolate_value",
    "interpolation_matrix",
    "optimal_return",
    "simulate_transitions",
    "solve",
    "solve_values",
    "solved_values",
    "state_grid",
]

#: Bumped whenever a change to the solver (this module, ``dynamic_programming_grid``) changes the
#: numbers it computes: old cache entries are ignored.
#: 2: the problem is read from the environment (the task's own reward_of instead of a copy of it).
SOLVER_VERSION = 2


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
        problem.dynamics,
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
    model = problem.dynamics
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
        with untimed():
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
            f"computing the near-optimal return by dynamic programming (about 20 s of CPU, "
            f"shared by the cores; cached after, in {directory})"
        ),
    )

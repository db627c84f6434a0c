"""A near-optimal return by trajectory optimisation: the best return of a trial from a fixed x_0.

For a deterministic task (a fixed start state, no noise) the best sum of rewards per trial is the maximum
over the action sequence u_0..u_{H-1} (inside the action box) of

    J(u) = sum_{k=1..H} r_k,   r_k = rho(x_{k-1}, u_{k-1}),   z_k = f(z_{k-1}, u_{k-1}),   x_k = s(z_k),

on the task's own model and reward (:mod:`rmac_mj.solvers.trajopt_problem`), maximised by iLQR with
control limits (:mod:`rmac_mj.solvers.ilqr`) from several starts. This module owns how hard it
searches (:class:`TrajoptConfig`), the starts, the result and its cache.

Each start runs in two phases: phase 1 optimises the reward of the angles *continued* from x_0 (not
wrapped, ``Problem.state_of(wrap=False)``), which charges every full turn, so that no start settles
into looping around; phase 2 optimises the task's own reward from there. The starts are zero, each
corner of the action box held throughout, each corner switched to its opposite half way, and random
sequences; the best is kept, and how many starts agree on it is the check that it is not a poor local
optimum (docs/optimal.md).

The reported number is the return of the found action sequence replayed open-loop on the model: the
return of an admissible sequence on the actual model, hence a lower bound on the true optimum.
Results are cached as JSON keyed by the problem, the config and ``SOLVER_VERSION``
(:func:`rmac_mj.solvers.problem.cache_key`).

    from rmac_mj import tasks
    from rmac_mj.solvers import trajopt
    result = trajopt.optimise(tasks.load(domain, task))
    print(result.describe())
"""

from __future__ import annotations

import dataclasses
import os
import time
from typing import Any

import numpy as np
from dm_control.rl import control

from rmac_mj.results.files import cached_json
from rmac_mj.solvers.ilqr import box_qp, ilqr
from rmac_mj.solvers.problem import cache_directory, versions
from rmac_mj.solvers.problem import cache_key as problem_cache_key
from rmac_mj.solvers.trajopt_problem import MAX_ACTION_DIM, Problem

__all__ = [
    "MAX_ACTION_DIM",
    "SOLVER_VERSION",
    "Problem",
    "StartSummary",
    "TrajoptConfig",
    "TrajoptResult",
    "box_qp",
    "cache_key",
    "cached_optimise",
    "ilqr",
    "optimise",
]

#: Bumped whenever a change to the solver (this module, ``ilqr``, ``trajopt_problem``) changes the
#: numbers it computes: old cache entries are ignored.
SOLVER_VERSION = 1


@dataclasses.dataclass(frozen=True)
class TrajoptConfig:
    """How hard to search. The problem itself (model, horizon, reward, x_0) comes from the environment."""

    max_iterations: int = 300
    """iLQR iterations per start and phase (each: derivatives, a backward pass, a line search)."""
    tolerance: float = 1e-9
    """A phase stops when the gain its quadratic model predicts for a full step is below this fraction
    of (1 + |return|)."""
    random_starts: int = 2
    """Random starts (uniform in the action box) in addition to the zero, corner and switched starts."""
    corner_starts: bool = True
    """Also start from every corner of the action box held throughout, and from every corner switched
    to its opposite half way through the trial (2 * 2^m starts)."""
    fd_step: float = 1e-6
    """Finite-difference step of the dynamics: in each of qpos and qvel (rad, rad/s) and as a fraction of
    each action's range."""
    reward_fd_step: float = 1e-4
    """Finite-difference step of the reward's gradient and Hessian in x and u (exact for a quadratic
    reward up to rounding)."""
    seed: int = 0
    """Seed of the random starts."""
    n_threads: int = 0
    """Threads for the batched rollouts; 0 means ``os.cpu_count()``. Does not change results."""

    def __post_init__(self) -> None:
        for name in ("max_iterations", "random_starts", "seed", "n_threads"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool):
                raise TypeError(f"TrajoptConfig.{name} must be an int, got {value!r}")
            if value < 0:
                raise ValueError(f"TrajoptConfig.{name} must be >= 0, got {value}")
        if self.max_iterations < 1:
            raise ValueError(
                f"TrajoptConfig.max_iterations must be >= 1, got {self.max_iterations}"
            )
        if not isinstance(self.corner_starts, (bool, np.bool_)):
            raise TypeError(
                f"TrajoptConfig.corner_starts must be a bool, got {self.corner_starts!r}"
            )
        for name in ("tolerance", "fd_step", "reward_fd_step"):
            value = getattr(self, name)
            if not (np.isscalar(value) and np.isfinite(value) and 0 < value < 1):
                raise ValueError(f"TrajoptConfig.{name} must be a number in (0, 1), got {value!r}")
            object.__setattr__(self, name, float(value))
        object.__setattr__(self, "corner_starts", bool(self.corner_starts))


@dataclasses.dataclass(frozen=True)
class StartSummary:
    """One iLQR run from one initial sequence."""

    start: str
    """Which start: "zero", "corner (...)", "switch (...) half way", "random i"."""
    initial_return: float
    simulated_return: float
    iterations: int
    """iLQR iterations of both phases (unwrapped, then wrapped angles)."""
    stopped: str
    """Why the last phase stopped: "converged", "max_iterations" or "regularisation" (no step improved
    any more)."""


@dataclasses.dataclass(frozen=True)
class TrajoptResult:
    """The best return found.

    Attributes:
      simulated_return: the number to report, sum of the H rewards of ``actions`` replayed on the model.
      actions: ndarray of shape (H, m): the best sequence.
      states: ndarray of shape (H + 1, n): x_0..x_H of the task's state (``physics.state_of``).
      rewards: ndarray of shape (H,): r_1..r_H.
      starts: one ``StartSummary`` per start, in the order run.
      config: the ``TrajoptConfig``.
      problem: what was solved: domain and task when known, horizon, control timestep, x_0, bounds.
      runtime_s: wall time (s) of the run that computed it.
      versions: package versions that computed it.
      from_cache: True when read from the cache rather than computed now.
    """

    simulated_return: float
    actions: np.ndarray
    states: np.ndarray
    rewards: np.ndarray
    starts: tuple[StartSummary, ...]
    config: TrajoptConfig
    problem: dict[str, Any]
    runtime_s: float
    versions: dict[str, str]
    from_cache: bool = False

    def starts_within(self, fraction: float) -> int:
        """How many starts ended within ``fraction`` of |best return| of the best return."""
        margin = fraction * abs(self.simulated_return)
        return sum(s.simulated_return >= self.simulated_return - margin for s in self.starts)

    def describe(self) -> str:
        """A few lines for people: the return, its check (agreement of the starts), the cost."""
        p = self.problem
        name = f"{p['domain']}/{p['task']}: " if p.get("domain") else ""
        returns = sorted((s.simulated_return for s in self.starts), reverse=True)
        lines = [
            f"{name}near-optimal return per trial (iLQR, best of {len(self.starts)} starts, "
            f"replayed on the model): {self.simulated_return:.2f}",
            f"{p['horizon']} steps of {p['control_timestep']:g} s, {p['n_actions']} action(s); "
            f"{self.starts_within(1e-3)} of {len(self.starts)} starts within 0.1% of the best",
            "returns of the starts: " + ", ".join(f"{r:.2f}" for r in returns),
        ]
        cached = " (read from the cache)" if self.from_cache else ""
        lines.append(f"computed in {self.runtime_s:.1f} s{cached}")
        return "\n".join(lines)

    def to_json_dict(self) -> dict[str, Any]:
        """A plain dict (lists and numbers) that ``json.dump`` writes and ``from_json_dict`` reads."""
        return {
            "simulated_return": self.simulated_return,
            "actions": self.actions.tolist(),
            "states": self.states.tolist(),
            "rewards": self.rewards.tolist(),
            "starts": [dataclasses.asdict(s) for s in self.starts],
            "config": dataclasses.asdict(self.config),
            "problem": self.problem,
            "runtime_s": self.runtime_s,
            "versions": dict(self.versions),
            "solver_version": SOLVER_VERSION,
        }

    @classmethod
    def from_json_dict(cls, d: dict[str, Any], from_cache: bool = True) -> TrajoptResult:
        problem = dict(d["problem"])
        return cls(
            simulated_return=float(d["simulated_return"]),
            actions=np.asarray(d["actions"], dtype=float).reshape(problem["horizon"], -1),
            states=np.asarray(d["states"], dtype=float).reshape(problem["horizon"] + 1, -1),
            rewards=np.asarray(d["rewards"], dtype=float),
            starts=tuple(StartSummary(**s) for s in d["starts"]),
            config=TrajoptConfig(**d["config"]),
            problem=problem,
            runtime_s=float(d["runtime_s"]),
            versions=dict(d["versions"]),
            from_cache=from_cache,
        )


def _starts(problem: Problem, config: TrajoptConfig) -> list[tuple[str, np.ndarray]]:
    """Initial sequences (name, ndarray of shape (H, m))."""
    m, horizon = problem.low.size, problem.horizon
    starts = [("zero", np.clip(np.zeros((horizon, m)), problem.low, problem.high))]
    if config.corner_starts:
        corners = [
            np.where([(c >> i) & 1 for i in range(m)], problem.high, problem.low)
            for c in range(2**m)
        ]
        for corner in corners:
            label = ", ".join(f"{v:+g}" for v in corner)
            starts.append((f"corner ({label})", np.tile(corner, (horizon, 1))))
        half = horizon // 2
        for corner in corners:
            label = ", ".join(f"{v:+g}" for v in corner)
            opposite = problem.low + problem.high - corner
            starts.append(
                (
                    f"switch ({label}) half way",
                    np.vstack([np.tile(corner, (half, 1)), np.tile(opposite, (horizon - half, 1))]),
                )
            )
    rng = np.random.default_rng(config.seed)
    for i in range(config.random_starts):
        starts.append((f"random {i}", rng.uniform(problem.low, problem.high, size=(horizon, m))))
    return starts


def optimise(env: control.Environment, config: TrajoptConfig = TrajoptConfig()) -> TrajoptResult:
    """The best return of a deterministic environment's trial by iLQR from several starts, uncached.

    Args:
      env: a dm-control environment of this suite whose task has a fixed start (e.g.
        ``tasks.load(domain, task)``); it is reset and stepped.
      config: the search's settings.
    """
    if not isinstance(config, TrajoptConfig):
        raise TypeError(f"optimise: config must be a TrajoptConfig, got {type(config).__name__}")
    start_time = time.perf_counter()
    problem = Problem(env, config.n_threads)
    summaries, best_u, best_value = [], None, -np.inf
    for name, guess in _starts(problem, config):
        initial = float(problem.trajectories(guess[None])[1].sum())
        # Phase 1 charges whole turns (angles unwrapped), so that no start settles into looping
        # around; phase 2 optimises the task's own reward from there.
        u, _, unwrapped_iterations, _ = ilqr(problem, guess, config, wrap=False)
        u, value, iterations, why = ilqr(problem, u, config, wrap=True)
        summaries.append(
            StartSummary(
                start=name,
                initial_return=initial,
                simulated_return=value,
                iterations=unwrapped_iterations + iterations,
                stopped=why,
            )
        )
        if value > best_value:
            best_u, best_value = u, value
    states, rewards = problem.trajectories(best_u[None])  # the open-loop replay is what is reported
    problem_info = {
        "horizon": problem.horizon,
        "n_actions": int(problem.low.size),
        "control_timestep": float(env.control_timestep()),
        "n_substeps": problem.n_substeps,
        "start_state": states[0, 0].tolist(),
        "action_low": problem.low.tolist(),
        "action_high": problem.high.tolist(),
    }
    return TrajoptResult(
        simulated_return=float(rewards[0].sum()),
        actions=best_u,
        states=states[0],
        rewards=rewards[0],
        starts=tuple(summaries),
        config=config,
        problem=problem_info,
        runtime_s=time.perf_counter() - start_time,
        versions=versions(),
    )


# --------------------------------------------------------------------------------------------------
# The cache


def cache_key(env: control.Environment, identity: dict[str, Any], config: TrajoptConfig) -> str:
    """Hex digest identifying a result (:func:`rmac_mj.solvers.problem.cache_key` of this solver)."""
    return problem_cache_key(env, identity, config, SOLVER_VERSION)


def cached_optimise(
    env: control.Environment,
    identity: dict[str, Any],
    config: TrajoptConfig = TrajoptConfig(),
    cache_dir: str | os.PathLike | None = None,
    refresh: bool = False,
    announce=None,
) -> TrajoptResult:
    """``optimise`` of ``env``, from the cache if there.

    Args:
      env: the task's environment (it is reset and stepped).
      identity: what names the problem (``problem.problem_identity``: domain, task, task_kwargs).
      config: the search's settings.
      cache_dir: directory of ``trajopt-<key>.json`` files; default ``problem.default_cache_dir()``.
      refresh: solve again even if cached (and overwrite the entry).
      announce: called with a one-line message before a solve (not for a cache hit), e.g. ``print``.
    """
    if not isinstance(config, TrajoptConfig):
        raise TypeError(
            f"cached_optimise: config must be a TrajoptConfig, got {type(config).__name__}"
        )
    directory = cache_directory(cache_dir)
    path = directory / f"trajopt-{cache_key(env, identity, config)}.json"
    name = f"{identity.get('domain')}/{identity.get('task')}"

    def compute() -> TrajoptResult:
        result = optimise(env, config)
        return dataclasses.replace(
            result,
            problem={
                "domain": identity.get("domain"),
                "task": identity.get("task"),
                **result.problem,
            },
        )

    return cached_json(
        path,
        lambda document: TrajoptResult.from_json_dict(document, from_cache=True),
        compute,
        refresh=refresh,
        announce=announce,
        message=(
            f"computing the near-optimal return of {name} by trajectory optimisation "
            f"(iLQR, under a minute on 2 cores), cached in {directory}"
        ),
    )

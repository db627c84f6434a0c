"""The exploration floor: the near-optimal policy's return while it explores as learners do.

Under section 6.1's noise (sigma = 1 V every third step) even the dynamic programme's greedy policy
loses reward, so an exploring learning curve is judged against this floor, a greedy trial against
the near-optimal return. Cached like the optimum, keyed by the DP's key and the schedule.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from dm_control.rl import control

from rmac_mj.evaluation.metrics import confidence_interval
from rmac_mj.results.files import cached_json
from rmac_mj.solvers import dynamic_programming as optimal
from rmac_mj.solvers.dynamic_programming_config import OptimalConfig
from rmac_mj.solvers.dynamic_programming_grid import (
    Problem,
    action_set,
    interpolate_value,
    simulate_transitions,
)
from rmac_mj.solvers.problem import Ticker, cache_directory


@dataclasses.dataclass(frozen=True)
class ExplorationFloor:
    """What the near-optimal policy scores per trial while exploring as the learners do.

    During learning every ``period``-th step (``k % period == phase``) gets N(0, sigma^2) noise added
    to the action, saturated to the action range (section 6.1: sigma = 1 V every third step). No
    learner's exploring trial can average much better than this policy's, so an exploring learning
    curve is judged against ``mean`` and a greedy trial against the near-optimal return.

    Attributes:
      mean, std: of the sum of rewards over ``rollouts`` noisy trials from x_0.
      ci95: Student-t 95% confidence interval of ``mean``.
      returns: ndarray of shape (rollouts,): each noisy trial's return.
      sigma, period, phase: the exploration schedule (V, steps, step).
      rollouts, seed: how many noisy trials, and the seed of their noise.
      config: the ``OptimalConfig`` of the DP whose greedy policy explores.
      runtime_s, from_cache: as in :class:`OptimalResult`.
    """

    mean: float
    std: float
    ci95: tuple[float, float]
    returns: np.ndarray
    sigma: float
    period: int
    phase: int
    rollouts: int
    seed: int
    config: OptimalConfig
    runtime_s: float
    from_cache: bool = False

    def describe(self) -> str:
        low, high = self.ci95
        cached = (
            ", read from the cache" if self.from_cache else f", computed in {self.runtime_s:.1f} s"
        )
        return (
            f"exploration floor (the same policy with N(0, {self.sigma:g}^2) added every "
            f"{_ordinal(self.period)} step, saturated): {self.mean:.1f} per trial, std "
            f"{self.std:.1f}, 95% CI [{low:.1f}, {high:.1f}] over {self.rollouts} noisy trials "
            f"(seed {self.seed}{cached})"
        )

    def to_json_dict(self) -> dict[str, Any]:
        return {
            "mean": self.mean,
            "std": self.std,
            "ci95": list(self.ci95),
            "returns": self.returns.tolist(),
            "sigma": self.sigma,
            "period": self.period,
            "phase": self.phase,
            "rollouts": self.rollouts,
            "seed": self.seed,
            "config": dataclasses.asdict(self.config),
            "runtime_s": self.runtime_s,
            "solver_version": optimal.SOLVER_VERSION,
        }

    @classmethod
    def from_json_dict(cls, d: dict[str, Any], from_cache: bool = True) -> ExplorationFloor:
        config = OptimalConfig(**d["config"])
        return cls(
            mean=float(d["mean"]),
            std=float(d["std"]),
            ci95=(float(d["ci95"][0]), float(d["ci95"][1])),
            returns=np.asarray(d["returns"], dtype=float),
            sigma=float(d["sigma"]),
            period=int(d["period"]),
            phase=int(d["phase"]),
            rollouts=int(d["rollouts"]),
            seed=int(d["seed"]),
            config=config,
            runtime_s=float(d["runtime_s"]),
            from_cache=from_cache,
        )


def _ordinal(n: int) -> str:
    if n == 1:
        return ""
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def noisy_rollouts(
    config: OptimalConfig,
    problem: Problem,
    values: np.ndarray,
    sigma: float,
    period: int,
    phase: int,
    rollouts: int,
    rng: np.random.Generator,
    announce: Callable[[str], None] | None = None,
) -> np.ndarray:
    """Returns of ``rollouts`` trials of the DP's greedy policy with exploration noise.

    Every trial starts at the task's start; at step k the greedy action is chosen exactly as in
    :func:`greedy_rollout` (one-step look-ahead on V_{k+1} over ``config.lookahead_actions``), then on
    exploring steps (``k % period == phase``) N(0, sigma^2) is added and the sum clipped to the
    action range; the reward is paid for the applied action. The trials run in lockstep, one batched
    ``mujoco.rollout`` per step.

    Returns:
      ndarray of shape (rollouts,): the sum of the H rewards of each trial.
    """
    actions = action_set(problem, config.lookahead_actions)
    threads = config.n_threads or os.cpu_count() or 1
    start = problem.start_z
    phi = np.full(rollouts, start[0])
    phi_dot = np.full(rollouts, start[1])
    total = np.zeros(rollouts)
    n_act = len(actions)
    ticker = Ticker(announce)
    for k in range(problem.horizon):
        ticker(f"noisy trials, step {k}/{problem.horizon}")
        candidates = simulate_transitions(
            problem.dynamics,
            np.repeat(phi, n_act),
            np.repeat(phi_dot, n_act),
            np.tile(actions, rollouts),
            problem.n_substeps,
            threads,
        )
        z = np.stack([phi, phi_dot], axis=-1)
        scores = problem.reward(
            np.broadcast_to(z[:, None, :], (rollouts, n_act, 2)), actions[None, :]
        ) + interpolate_value(config, problem, values[k + 1], candidates).reshape(rollouts, n_act)
        u = actions[np.argmax(scores, axis=1)]  # ties: the lowest action, as greedy_rollout
        if sigma > 0 and k % period == phase:
            u = np.clip(u + rng.normal(0.0, sigma, size=rollouts), problem.low, problem.high)
        total += problem.reward(z, u)
        next_states = simulate_transitions(
            problem.dynamics, phi, phi_dot, u, problem.n_substeps, threads
        )
        phi, phi_dot = next_states[:, 0], next_states[:, 1]
    return total


def exploration_floor(
    env: control.Environment,
    identity: dict[str, Any],
    sigma: float = 1.0,
    period: int = 3,
    phase: int = 0,
    rollouts: int = 100,
    seed: int = 0,
    config: OptimalConfig = OptimalConfig(),
    cache_dir: str | os.PathLike | None = None,
    refresh: bool = False,
    announce: Callable[[str], None] | None = None,
) -> ExplorationFloor:
    """The near-optimal policy's return under exploration, from the cache if there, else computed.

    The DP's values come from :func:`optimal.solved_values` (those this process solved for the
    near-optimal return if it did, else solved now), then ``rollouts`` noisy trials are simulated
    (:func:`noisy_rollouts`). Defaults: the paper's exploration (section 6.1), 100 trials.

    Args:
      env, identity, config, cache_dir, refresh, announce: as in :func:`optimal_return`.
      sigma: exploration noise std (in the action's unit), >= 0.
      period, phase: explore at steps k with ``k % period == phase``.
      rollouts: noisy trials to average, >= 2.
      seed: seed of the noise.
    """
    sigma, period, phase, rollouts, seed = _checked(config, sigma, period, phase, rollouts, seed)
    dp_key = optimal.cache_key(env, identity, config)
    key = hashlib.sha256(
        json.dumps([dp_key, sigma, period, phase, rollouts, seed]).encode()
    ).hexdigest()[:20]
    directory = cache_directory(cache_dir)
    return cached_json(
        directory / f"exploration-floor-{key}.json",
        lambda document: ExplorationFloor.from_json_dict(document, from_cache=True),
        lambda: _computed_floor(
            env, identity, config, (sigma, period, phase, rollouts, seed), announce
        ),
        refresh=refresh,
        announce=announce,
        message=(
            f"computing the exploration floor ({rollouts} noisy trials of the near-optimal "
            f"policy, after its dynamic programming: about 10 s of CPU more; cached after, in "
            f"{directory})"
        ),
    )


def _checked(config, sigma, period, phase, rollouts, seed) -> tuple[float, int, int, int, int]:
    """:func:`exploration_floor`'s settings checked, as (sigma, period, phase, rollouts, seed)."""
    if not isinstance(config, OptimalConfig):
        raise TypeError(
            f"exploration_floor: config must be an OptimalConfig, got {type(config).__name__}"
        )
    if isinstance(sigma, bool) or not (np.isscalar(sigma) and np.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"exploration_floor: sigma must be a finite number >= 0, got {sigma!r}")
    for name, value, minimum in (
        ("period", period, 1),
        ("phase", phase, 0),
        ("rollouts", rollouts, 2),
        ("seed", seed, 0),
    ):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
            raise ValueError(
                f"exploration_floor: {name} must be an integer >= {minimum}, got {value!r}"
            )
    if phase >= period:
        raise ValueError(f"exploration_floor: phase must be in [0, period={period}), got {phase}")
    return float(sigma), int(period), int(phase), int(rollouts), int(seed)


def _computed_floor(
    env: control.Environment,
    identity: dict[str, Any],
    config: OptimalConfig,
    exploration: tuple[float, int, int, int, int],
    announce: Callable[[str], None] | None,
) -> ExplorationFloor:
    """The floor computed: the DP's values, then the noisy trials of ``exploration`` (sigma,
    period, phase, rollouts, seed)."""
    sigma, period, phase, rollouts, seed = exploration
    start = time.perf_counter()
    problem, values = optimal.solved_values(env, identity, config, announce)
    returns = noisy_rollouts(
        config,
        problem,
        values,
        sigma,
        period,
        phase,
        rollouts,
        np.random.default_rng(seed),
        announce,
    )
    mean, low, high = confidence_interval(returns)
    return ExplorationFloor(
        mean=float(mean),
        std=float(returns.std(ddof=1)),
        ci95=(float(low), float(high)),
        returns=returns,
        sigma=sigma,
        period=period,
        phase=phase,
        rollouts=rollouts,
        seed=seed,
        config=config,
        runtime_s=time.perf_counter() - start,
    )

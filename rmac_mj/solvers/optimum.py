"""The near-optimal return per trial of a task: the line the learners are judged against.

A task declares its solver (``tasks.knowledge(domain, task).optimum``): ``"dynamic programming"`` or
``"trajectory optimisation"`` (:mod:`~rmac_mj.solvers.trajopt`); ``optimum_return(domain, task)``
solves once, then reads the cache.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any
from typing import Protocol as Interface

from rmac_mj import tasks
from rmac_mj.solvers import dynamic_programming, trajopt
from rmac_mj.solvers import exploration_floor as floors
from rmac_mj.solvers.dynamic_programming_config import OptimalConfig
from rmac_mj.solvers.problem import Announce, problem_identity
from rmac_mj.solvers.trajopt import TrajoptConfig


class Optimum(Interface):
    """What every solver's result offers (``dynamic_programming.OptimalResult``,
    ``trajopt.TrajoptResult``)."""

    simulated_return: float
    from_cache: bool

    def describe(self) -> str: ...


#: Solver name (``Optimum.method``) -> the function that computes and caches it, and the config
#: class its settings fill.
SOLVERS: dict[str, tuple[Callable[..., Optimum], type]] = {
    "dynamic programming": (dynamic_programming.optimal_return, OptimalConfig),
    "trajectory optimisation": (trajopt.cached_optimise, TrajoptConfig),
}


def has_optimum(domain: str, task: str) -> bool:
    """Whether ``domain``/``task`` declares a near-optimal return."""
    return tasks.knowledge(domain, task).optimum is not None


def optimum_result(
    domain: str,
    task: str,
    cache_dir: str | os.PathLike | None = None,
    refresh: bool = False,
    announce: Announce | None = None,
    settings: dict[str, Any] | None = None,
) -> Optimum:
    """The near-optimal result of ``domain``/``task`` (default task_kwargs), from the cache if
    there, else computed and cached.

    Args:
      cache_dir: the cache directory; default ``$RMAC_MJ_CACHE_DIR`` (``problem.default_cache_dir``).
      refresh: compute again even if cached.
      announce: called with a one-line message before a computation that is not cached, and with its
        progress.
      settings: solver settings that replace the task's (e.g. a coarse grid for a quick look).
    Raises:
      ValueError: the task declares no optimum.
    """
    declared = tasks.knowledge(domain, task).optimum
    if declared is None:
        available = ", ".join(f"{d}/{t}" for d, t in tasks.ALL_TASKS if has_optimum(d, t))
        raise ValueError(f"no near-optimal return for {domain}/{task}; available: {available}")
    if declared.method not in SOLVERS:
        raise ValueError(
            f"{domain}/{task} declares the solver {declared.method!r}; known: {', '.join(SOLVERS)}"
        )
    solve, config_class = SOLVERS[declared.method]
    return solve(
        tasks.load(domain, task),
        problem_identity(domain, task),
        config_class(**{**declared.settings, **(settings or {})}),
        cache_dir=cache_dir,
        refresh=refresh,
        announce=announce,
    )


def optimum_return(
    domain: str,
    task: str,
    cache_dir: str | os.PathLike | None = None,
    refresh: bool = False,
    announce: Announce | None = None,
) -> float:
    """The near-optimal return per trial of ``domain``/``task`` (see :func:`optimum_result`)."""
    return float(
        optimum_result(
            domain, task, cache_dir=cache_dir, refresh=refresh, announce=announce
        ).simulated_return
    )


def exploration_floor(
    domain: str,
    task: str,
    sigma: float,
    period: int,
    phase: int,
    cache_dir: str | os.PathLike | None = None,
    refresh: bool = False,
    announce: Announce | None = None,
):
    """The near-optimal policy's return while exploring with N(0, sigma^2) every ``period``-th step
    (``exploration_floor.ExplorationFloor``), or None when the task's solver gives none (only the
    dynamic programme has a policy to explore with)."""
    declared = tasks.knowledge(domain, task).optimum
    if declared is None or declared.method != "dynamic programming":
        return None
    return floors.exploration_floor(
        tasks.load(domain, task),
        problem_identity(domain, task),
        sigma,
        period,
        phase,
        config=OptimalConfig(**declared.settings),
        cache_dir=cache_dir,
        refresh=refresh,
        announce=announce,
    )


def run_optimum(protocol, announce: Announce | None = None) -> float | None:
    """The near-optimal return of a run's task (its ``domain``, ``task`` and ``task_kwargs``), or
    None when it has none (non-default task_kwargs, no declared optimum)."""
    if protocol.task_kwargs or protocol.knowledge.optimum is None:
        return None
    return optimum_return(protocol.domain, protocol.task, announce=announce)


def run_exploration_floor(
    protocol, algorithm: str, announce: Announce | None = None
) -> float | None:
    """The exploration floor of ``algorithm``'s exploration on a run's task, else None.

    A decaying exploration is taken at its last trial's noise level (the final return averages the
    last trials); exploration only where the model is uncertain has no floor (how often it explores
    depends on the learner), nor has a learner without an ``Exploration`` schedule."""
    if protocol.task_kwargs or protocol.knowledge.optimum is None:
        return None
    from rmac_mj.agents import config_class, config_from_dict

    config = config_from_dict(config_class(algorithm), protocol.agent_configs.get(algorithm, {}))
    exploration = getattr(config, "exploration", None)
    if exploration is None or exploration.where != "always":
        return None
    if exploration.sigma is None:  # the task's: the learner resolves it against the action range
        from rmac_mj.agents.task_knowledge import with_task_units
        from rmac_mj.rollout import action_space_of, state_space_of

        env = protocol.make_environment()
        exploration = with_task_units(exploration, state_space_of(env), action_space_of(env))
    floor = exploration_floor(
        protocol.domain,
        protocol.task,
        exploration.sigma_at(protocol.trials - 1),
        exploration.period,
        exploration.phase,
        announce=announce,
    )
    return None if floor is None else float(floor.mean)

"""The near-optimal return per trial of a task: the line the learners are measured against.

A task declares how its reference is computed (``rmac_mj.tasks.knowledge(domain, task).reference``, a
``tasks.common.Reference``: a solver's name and the settings the task needs); this module holds the
solvers by name, computes a reference once and caches it:

- ``"dynamic programming"``: a grid DP of a one-joint task (:mod:`rmac_mj.solvers.dynamic_programming`), which
  also gives the *exploration floor*, the near-optimal policy's return while exploring as a learner does;
- ``"trajectory optimisation"``: iLQR from several starts (:mod:`rmac_mj.solvers.trajopt`), for any
  deterministic task of the suite.

Both read the whole problem (model, horizon, reward, start) from the task's environment. A run's
reference is the task's with its default task_kwargs: a changed reward or start is another problem,
and an environment from outside the suite declares none.

    from rmac_mj.solvers.optimum import reference_return
    reference_return(domain, task)    # solves once, then reads the cache
"""

from __future__ import annotations

import hashlib
import inspect
import json
import os
from typing import Any, Callable, Protocol as Interface

import mujoco
import numpy as np
from dm_control.rl import control

from rmac_mj import tasks

Announce = Callable[[str], None]


class Reference(Interface):
    """What every reference result offers (``optimal.OptimalResult``, ``trajopt.TrajoptResult``)."""

    simulated_return: float
    from_cache: bool

    def describe(self) -> str: ...


def problem_identity(domain: str, task: str, task_kwargs: dict[str, Any] | None = None
                     ) -> dict[str, Any]:
    """What names a task's problem for the caches: domain, task and task_kwargs."""
    return {"domain": domain, "task": task, "task_kwargs": dict(task_kwargs or {})}


def problem_digest(env: control.Environment, identity: dict[str, Any]) -> str:
    """Hex digest of the problem a reference solves: the compiled model, the source of the task's
    module (its reward, start, horizon: any change computes afresh) and ``identity``."""
    model = env.physics.model.ptr
    buffer = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    module = inspect.getmodule(type(env.task))
    blob = json.dumps({**identity, "model": hashlib.sha256(buffer.tobytes()).hexdigest(),
                       "task_source": hashlib.sha256(inspect.getsource(module).encode()).hexdigest()},
                      sort_keys=True, default=repr)
    return hashlib.sha256(blob.encode()).hexdigest()


def _dynamic_programming(env, identity, settings, cache_dir, refresh, announce) -> Reference:
    from rmac_mj.solvers import dynamic_programming as optimal
    return optimal.optimal_return(env, identity, optimal.OptimalConfig(**settings),
                                  cache_dir=cache_dir, refresh=refresh, announce=announce)


def _trajectory_optimisation(env, identity, settings, cache_dir, refresh, announce) -> Reference:
    from rmac_mj.solvers import trajopt
    return trajopt.cached_optimise(env, identity, trajopt.TrajoptConfig(**settings),
                                   cache_dir=cache_dir, refresh=refresh, announce=announce)


#: Solver name (``Reference.method``) -> the function that computes and caches it.
SOLVERS: dict[str, Callable[..., Reference]] = {
    "dynamic programming": _dynamic_programming,
    "trajectory optimisation": _trajectory_optimisation,
}


def has_reference(domain: str, task: str) -> bool:
    """Whether ``domain``/``task`` declares a near-optimal reference."""
    return tasks.knowledge(domain, task).reference is not None


def reference(domain: str, task: str, cache_dir: str | os.PathLike | None = None,
              refresh: bool = False, announce: Announce | None = None,
              settings: dict[str, Any] | None = None) -> Reference:
    """The near-optimal reference of ``domain``/``task`` (default task_kwargs), from the cache if
    there, else computed and cached.

    Args:
      cache_dir: the cache directory; default ``$RMAC_MJ_CACHE_DIR`` (``optimal.default_cache_dir``).
      refresh: compute again even if cached.
      announce: called with a one-line message before a computation that is not cached, and with its
        progress.
      settings: solver settings that replace the task's (e.g. a coarse grid for a quick look).
    Raises:
      ValueError: the task declares no reference.
    """
    declared = tasks.knowledge(domain, task).reference
    if declared is None:
        available = ", ".join(f"{d}/{t}" for d, t in tasks.ALL_TASKS if has_reference(d, t))
        raise ValueError(f"no near-optimal reference for {domain}/{task}; available: {available}")
    if declared.method not in SOLVERS:
        raise ValueError(f"{domain}/{task} declares the reference solver {declared.method!r}; "
                         f"known: {', '.join(SOLVERS)}")
    env = tasks.load(domain, task)
    return SOLVERS[declared.method](env, problem_identity(domain, task),
                                    {**declared.settings, **(settings or {})}, cache_dir, refresh,
                                    announce)


def reference_return(domain: str, task: str, cache_dir: str | os.PathLike | None = None,
                     refresh: bool = False, announce: Announce | None = None) -> float:
    """The near-optimal return per trial of ``domain``/``task`` (see :func:`reference`)."""
    return float(reference(domain, task, cache_dir=cache_dir, refresh=refresh,
                           announce=announce).simulated_return)


def exploration_floor(domain: str, task: str, sigma: float, period: int, phase: int,
                      cache_dir: str | os.PathLike | None = None, refresh: bool = False,
                      announce: Announce | None = None):
    """The near-optimal policy's return while exploring with N(0, sigma^2) every ``period``-th step
    (``exploration_floor.ExplorationFloor``), or None when the task's reference method gives none (only the
    dynamic programme has a policy to explore with)."""
    declared = tasks.knowledge(domain, task).reference
    if declared is None or declared.method != "dynamic programming":
        return None
    from rmac_mj.solvers import exploration_floor as floors, dynamic_programming as optimal
    return floors.exploration_floor(tasks.load(domain, task), problem_identity(domain, task),
                                    sigma, period, phase,
                                    config=optimal.OptimalConfig(**declared.settings),
                                    cache_dir=cache_dir, refresh=refresh, announce=announce)


def run_reference(protocol, announce: Announce | None = None) -> float | None:
    """The near-optimal return of a run's task (its ``domain``, ``task`` and ``task_kwargs``), or
    None when it has none (non-default task_kwargs, no declared reference)."""
    if protocol.task_kwargs or protocol.knowledge.reference is None:
        return None
    return reference_return(protocol.domain, protocol.task, announce=announce)


def run_exploration_floor(protocol, algorithm: str, announce: Announce | None = None
                          ) -> float | None:
    """The exploration floor of ``algorithm``'s exploration on a run's task, else None.

    A decaying exploration is taken at its last trial's noise level (the final return averages the
    last trials); exploration only where the model is uncertain has no floor (how often it explores
    depends on the learner), nor has a learner without an ``Exploration`` schedule."""
    if protocol.task_kwargs or protocol.knowledge.reference is None:
        return None
    from rmac_mj.agents import config_class, config_from_dict
    config = config_from_dict(config_class(algorithm), protocol.agent_configs.get(algorithm, {}))
    exploration = getattr(config, "exploration", None)
    if exploration is None or exploration.where != "always":
        return None
    floor = exploration_floor(protocol.domain, protocol.task,
                              exploration.sigma_at(protocol.trials - 1), exploration.period,
                              exploration.phase, announce=announce)
    return None if floor is None else float(floor.mean)

"""The near-optimal return per trial of every task that has one: the line the learners are measured against.

Each task's reference is computed by the method that suits it and cached:

- ``dc_pendulum/swingup``: dynamic programming on a grid (``rmac_mj.experiments.optimal``), -748.1;
- ``two_link_arm/reach``: trajectory optimisation by iLQR from several starts
  (``rmac_mj.experiments.trajopt``), which reproduces the pendulum's value within 0.6.

Only the tasks' default task_kwargs have a reference (a changed reward or start is another problem).

    from rmac_mj.experiments.reference import reference_return
    reference_return("two_link_arm", "reach")    # solves once, then reads the cache
"""

from __future__ import annotations

import os
from typing import Callable, Protocol

#: (domain, task) -> the name of the method that computes its reference.
METHODS: dict[tuple[str, str], str] = {
    ("dc_pendulum", "swingup"): "dynamic programming",
    ("two_link_arm", "reach"): "trajectory optimisation (iLQR)",
}


class Reference(Protocol):
    """What every reference result offers (``optimal.OptimalResult``, ``trajopt.TrajoptResult``)."""

    simulated_return: float
    from_cache: bool

    def describe(self) -> str: ...


def _dynamic_programming(domain: str, task: str, cache_dir, refresh: bool, announce) -> Reference:
    from rmac_mj.experiments import optimal
    return optimal.optimal_return(cache_dir=cache_dir, refresh=refresh, announce=announce)


def _trajectory_optimisation(domain: str, task: str, cache_dir, refresh: bool,
                             announce) -> Reference:
    from rmac_mj.experiments import trajopt
    return trajopt.cached_optimise(domain, task, cache_dir=cache_dir, refresh=refresh,
                                   announce=announce)


_SOLVERS: dict[str, Callable[..., Reference]] = {
    "dynamic programming": _dynamic_programming,
    "trajectory optimisation (iLQR)": _trajectory_optimisation,
}


def has_reference(domain: str, task: str) -> bool:
    """Whether ``domain``/``task`` (with default task_kwargs) has a near-optimal reference."""
    return (domain, task) in METHODS


def reference(domain: str, task: str, cache_dir: str | os.PathLike | None = None,
              refresh: bool = False, announce: Callable[[str], None] | None = None) -> Reference:
    """The near-optimal reference of ``domain``/``task``, from the cache if there, else computed and cached.

    Args:
      domain, task: as for ``rmac_mj.tasks.load`` (default task_kwargs).
      cache_dir: the cache directory; default ``optimal.default_cache_dir()``.
      refresh: compute again even if cached.
      announce: called with a one-line message before a computation that is not cached.
    Raises:
      ValueError: the task has no reference.
    """
    if not has_reference(domain, task):
        available = ", ".join(f"{d}/{t}" for d, t in sorted(METHODS))
        raise ValueError(f"no near-optimal reference for {domain}/{task}; available: {available}")
    return _SOLVERS[METHODS[domain, task]](domain, task, cache_dir, refresh, announce)


def reference_return(domain: str, task: str, cache_dir: str | os.PathLike | None = None,
                     refresh: bool = False, announce: Callable[[str], None] | None = None) -> float:
    """The near-optimal return per trial of ``domain``/``task`` (see ``reference``)."""
    return float(reference(domain, task, cache_dir=cache_dir, refresh=refresh,
                           announce=announce).simulated_return)

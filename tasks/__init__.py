"""The rmac-mj task suite, loaded like ``dm_control.suite`` (installed as ``rmac_mj.tasks``).

from rmac_mj import tasks
env = tasks.load("dc_pendulum", "swingup", task_kwargs={"random": 0})

:func:`load` builds a task's environment, :func:`knowledge` says what it declares beyond it (its
near-optimal return, demonstrators, plot hints: :class:`TaskKnowledge`); every task tells the learners
what their state is through its ``learner_state`` (:class:`LearnerStateSpec`).
"""

from __future__ import annotations

import importlib.util
import inspect
from typing import Any

from dm_control.rl import control

from rmac_mj.tasks import common, dc_pendulum, two_link_arm
from rmac_mj.tasks.common import (
    NOTHING_KNOWN,
    Demonstrator,
    LearnerStateSpec,
    Optimum,
    PlotHints,
    TaskKnowledge,
)

_DOMAINS = {
    name: module for name, module in [("dc_pendulum", dc_pendulum), ("two_link_arm", two_link_arm)]
}

#: Every (domain_name, task_name) pair in the suite.
ALL_TASKS = tuple(
    sorted((domain, task) for domain, module in _DOMAINS.items() for task in module.SUITE)
)

#: Domain name -> the tuple of its task names (like ``dm_control.suite.TASKS_BY_DOMAIN``).
TASKS_BY_DOMAIN = {domain: tuple(sorted(module.SUITE)) for domain, module in _DOMAINS.items()}

#: Domain name -> its ``containers.TaggedTasks`` registry.
SUITE = {domain: module.SUITE for domain, module in _DOMAINS.items()}

#: The suite's default task: the paper's swing-up (what ``rmac-mj`` runs when no task is named).
DEFAULT_TASK = ("dc_pendulum", "swingup")


def knowledge(domain_name: str, task_name: str) -> common.TaskKnowledge:
    """What ``domain_name``/``task_name`` declares beyond its environment: its near-optimal return,
    its demonstrators and its plot hints (:class:`~rmac_mj.tasks.common.TaskKnowledge`; a task that
    declares nothing has none of them)."""
    _check_names(domain_name, task_name)
    return getattr(_DOMAINS[domain_name], "KNOWLEDGE", {}).get(task_name, common.NOTHING_KNOWN)


def load(
    domain_name: str,
    task_name: str,
    task_kwargs: dict[str, Any] | None = None,
    environment_kwargs: dict[str, Any] | None = None,
) -> control.Environment:
    """Return the environment of ``domain_name``/``task_name``, mirroring ``dm_control.suite.load``.

    Args:
      domain_name: e.g. ``"dc_pendulum"`` or ``"two_link_arm"``.
      task_name: e.g. ``"swingup"``, ``"balance"`` or ``"reach"``.
      task_kwargs: keyword arguments of the task factory (``time_limit``, ``control_timestep``,
        ``state_weights``, ``action_weights``, ``start_state``, ``start_noise``,
        ``random``).
      environment_kwargs: keyword arguments of ``dm_control.rl.control.Environment``.
    """
    return build_environment(domain_name, task_name, task_kwargs, environment_kwargs)


def build_environment(
    domain_name: str,
    task_name: str,
    task_kwargs: dict[str, Any] | None = None,
    environment_kwargs: dict[str, Any] | None = None,
) -> control.Environment:
    """Like :func:`load`; kept for parity with ``dm_control.suite.build_environment``."""
    _check_names(domain_name, task_name)
    factory = _DOMAINS[domain_name].SUITE[task_name]
    task_kwargs = dict(task_kwargs or {})
    accepted = set(inspect.signature(factory).parameters) - {"environment_kwargs"}
    unknown = sorted(set(task_kwargs) - accepted)
    if unknown:
        raise ValueError(
            f"unknown task_kwargs {unknown} for {domain_name}/{task_name}; "
            f"accepted: {sorted(accepted)}"
        )
    return factory(environment_kwargs=environment_kwargs, **task_kwargs)


def _check_names(domain_name: str, task_name: str) -> None:
    if domain_name not in _DOMAINS:
        raise ValueError(f"unknown domain_name {domain_name!r}; available: {sorted(_DOMAINS)}")
    if task_name not in _DOMAINS[domain_name].SUITE:
        raise ValueError(
            f"unknown task_name {task_name!r} for domain {domain_name!r}; "
            f"available: {sorted(_DOMAINS[domain_name].SUITE)}"
        )


# Every task above as a Gymnasium environment, rmac_mj/<Domain>-<Task>-v0 (see gymnasium_env), when
# Gymnasium is installed (the [gymnasium] extra).
if importlib.util.find_spec("gymnasium") is not None:
    from rmac_mj.tasks import to_gymnasium as gymnasium_env

    gymnasium_env.register_suite()

__all__ = [
    # The suite
    "ALL_TASKS",
    "DEFAULT_TASK",
    "SUITE",
    "TASKS_BY_DOMAIN",
    "build_environment",
    "load",
    # What a task declares
    "NOTHING_KNOWN",
    "Demonstrator",
    "LearnerStateSpec",
    "Optimum",
    "PlotHints",
    "TaskKnowledge",
    "knowledge",
]

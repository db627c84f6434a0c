"""The learner to pick for a new task: S-AC (Algorithm 1) with Dyna planning in its learned local
linear models (:mod:`rmac_mj.agents.planning`), every default in the task's own units
(:func:`rmac_mj.agents.task_knowledge.with_task_units`). docs/new-task.md has what it costs and
what it reached."""

from __future__ import annotations

import dataclasses
from typing import ClassVar

from rmac_mj.agents.planning import Planning
from rmac_mj.agents.sac import SAC, SACConfig


@dataclasses.dataclass(frozen=True)
class RecommendedConfig(SACConfig):
    """S-AC's settings (:class:`SACConfig`) with planning on: ``planning.steps`` simulated
    transitions per real one, and an actor rate of 0.002 at the paper's reward scale (the smaller
    step planning wants on the pendulum, docs/planning.md)."""

    planning: Planning = Planning(steps=30)

    task_units: ClassVar[dict[str, tuple[str, float]]] = {
        **SACConfig.task_units, "alpha_a": ("reward", 0.002)}


class Recommended(SAC):
    """S-AC with planning (module docstring); the same interface and state as :class:`SAC`."""

    name = "recommended"
    display_name = "S-AC + planning"
    config_class = RecommendedConfig

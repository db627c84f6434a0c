"""Whether a result directory's run is the one asked for: the refusals (:class:`ResumeRefused`,
:class:`DamagedDirectory`), the settings in which two protocols differ, and whether one only adds
experiments to the other (:func:`added_experiments`)."""

from __future__ import annotations

import json
from typing import Any

from rmac_mj.errors import UserInputError


class ResumeRefused(UserInputError):
    """The result directory holds a different run; its results must not be mixed with this one's."""


class DamagedDirectory(ResumeRefused):
    """The result directory's config cannot be read: what run it holds cannot be told."""


def added_experiments(stored: Any, protocol: Any) -> int | None:
    """How many experiments ``protocol`` adds to the ``stored`` protocol (both as data) when it
    differs from it in nothing else (negative: it has fewer); None when anything else differs or a
    count is missing. Experiment i's seeds do not depend on the count
    (:func:`~rmac_mj.experiments.experiment.experiment_seeds`), so a run of N experiments grown to M
    holds exactly what a fresh run of M would. The runner's and the sweep's resume both ask it."""
    if not all(
        isinstance(p, dict) and isinstance(p.get("experiments"), int) for p in (stored, protocol)
    ):
        return None
    if differences({**stored, "experiments": 0}, {**protocol, "experiments": 0}):
        return None
    return protocol["experiments"] - stored["experiments"]


def differences(old: Any, new: Any, path: str = "") -> list[str]:
    """``"field: A in the directory, B now"`` for every setting that differs (nested fields dotted)."""
    if isinstance(old, dict) and isinstance(new, dict):
        found = []
        for key in [*old, *(k for k in new if k not in old)]:
            found += differences(old.get(key), new.get(key), f"{path}{key}.")
        return found
    if old == new:
        return []
    return [f"{path.rstrip('.')}: {json.dumps(old)} in the directory, {json.dumps(new)} now"]

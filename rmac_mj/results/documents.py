"""A run's JSON documents read back (``config.json``, ``summary.json``, ``wall_times.json``): each
reader returns the document or raises :class:`~rmac_mj.errors.UserInputError` naming the file and
what is damaged in it, so no reader downstream meets a malformed one; and whether the directory's
config is the run asked for: the refusals (:class:`ResumeRefused`, :class:`DamagedDirectory`), the
settings in which two protocols differ, whether one only adds experiments to the other
(:func:`added_experiments`)."""

from __future__ import annotations

import json
import pathlib
from typing import Any

from rmac_mj.constraints import RESULT_DOCUMENT_BYTES
from rmac_mj.errors import MissingInputError, UserInputError
from rmac_mj.results.files import read_bounded
from rmac_mj.results.snapshots import upgrade_run_config


class ResumeRefused(UserInputError):
    """The result directory holds a different run; its results must not be mixed with this one's."""


class DamagedDirectory(ResumeRefused):
    """The result directory's config cannot be read: what run it holds cannot be told."""


#: The containers a config's readers iterate (the values in them are compared with the run's own).
_CONFIG_KINDS = {
    "agents": dict,
    "protocol.algorithms": list,
    "protocol.prior_parts": list,
    "protocol.snapshot_trials": list,
    "protocol.agent_configs": dict,
    "protocol.task_kwargs": dict,
}

#: What the readers of a summary (``compare``, the report, the figures) take from each learner's row.
_SUMMARY_ROW_KEYS = {
    "experiments": "an integer",
    "final_return_mean": "a number",
    "final_return_ci95": "a list",
    "minutes_to_90pct": "a number",
    "final_return_per_experiment": "a list",
    "mean_return_per_trial": "a list",
    "ci95_low_per_trial": "a list",
    "ci95_high_per_trial": "a list",
}


def _read_text(path: pathlib.Path) -> str:
    """The text of the document at ``path``: a regular file of at most
    :data:`~rmac_mj.constraints.RESULT_DOCUMENT_BYTES` (a result directory copied from elsewhere
    may hold anything under a document's name); FileNotFoundError when there is none."""
    if not path.exists() and not path.is_symlink():
        raise FileNotFoundError(path)
    return read_bounded(path, RESULT_DOCUMENT_BYTES, f"a run's {path.name}").decode()


def _parse(text: str) -> Any:
    """JSON ``text`` parsed; ValueError for what is not JSON, nested too deeply included."""
    try:
        return json.loads(text)
    except RecursionError:
        raise ValueError("nested too deeply to be a run's document") from None


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def summary_problem(summary: Any) -> str | None:
    """What makes ``summary`` not a run's summary (one phrase), or None: a JSON object whose
    learners' rows hold :data:`_SUMMARY_ROW_KEYS` of their kinds."""
    from rmac_mj.agents import ALGORITHMS

    if not isinstance(summary, dict):
        return f"a {type(summary).__name__}, not a run's summary (a JSON object)"
    rows = [name for name in summary if name in ALGORITHMS]
    if not rows:
        protocol = summary.get("protocol")
        listed = protocol.get("algorithms") if isinstance(protocol, dict) else None
        if isinstance(listed, list) and listed:
            return f"it holds the results of none of its learners ({', '.join(map(str, listed))})"
        return "it holds no learner's row"
    for name in rows:
        row = summary[name]
        if not isinstance(row, dict):
            return f"{name!r} is a {type(row).__name__}, not a learner's row (an object)"
        for key, kind in _SUMMARY_ROW_KEYS.items():
            value = row.get(key)
            if key not in row:
                return f"{name!r} lacks {key!r}"
            good = {
                "an integer": isinstance(value, int) and not isinstance(value, bool),
                "a number": value is None or _is_number(value),
                "a list": isinstance(value, list),
            }[kind]
            if not good:
                return f"{name}.{key} must be {kind}, got {value!r}"
    return None


def read_config(path: pathlib.Path) -> dict[str, Any] | None:
    """The directory's ``config.json`` in today's form (one an earlier version wrote upgraded:
    :func:`~rmac_mj.results.snapshots.upgrade_run_config`), or None when there is none;
    :class:`DamagedDirectory` when it cannot be read as a run's config (a JSON object with a
    ``protocol`` object)."""
    try:
        text = _read_text(path)
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError, UserInputError) as error:
        raise DamagedDirectory(f"{path} cannot be read ({error})") from None
    try:
        document = _parse(text)
    except ValueError as error:
        raise DamagedDirectory(
            f"{path} is damaged (not JSON: {error}); the directory's "
            "run cannot be told, so nothing in it is trusted: choose another "
            "--out"
        ) from None
    if not isinstance(document, dict) or not isinstance(document.get("protocol"), dict):
        raise DamagedDirectory(
            f"{path} is damaged (not a run's config: no protocol object); choose another --out"
        )
    for key, kind in _CONFIG_KINDS.items():
        owner, _, name = key.rpartition(".")
        value = (document.get(owner) if owner else document).get(name)
        if value is not None and not isinstance(value, kind):
            raise DamagedDirectory(
                f"{path} is damaged ({key} is {value!r}, not a "
                f"{kind.__name__}); choose another --out"
            )
    return upgrade_run_config(document)


def read_summary(path: pathlib.Path) -> dict[str, Any]:
    """The run's ``summary.json``; MissingInputError when the run has none (not finished)."""
    if not path.is_file():
        raise MissingInputError(
            f"{path.parent} has no summary.json (not a finished `reproduce` run)"
        )
    try:
        summary = _parse(_read_text(path))
    except UserInputError:
        raise
    except (OSError, ValueError) as error:  # UnicodeDecodeError is a ValueError
        raise UserInputError(f"{path}: not a JSON document ({error})") from None
    problem = summary_problem(summary)
    if problem is not None:
        raise UserInputError(f"{path} is damaged: {problem}")
    return summary


def read_wall_times(path: pathlib.Path) -> list[dict[str, Any]]:
    """The parts recorded in ``wall_times.json`` (empty when there is none);
    :class:`UserInputError` naming the file when it is there but damaged."""
    try:
        text = _read_text(path)
    except FileNotFoundError:
        return []
    except (OSError, ValueError) as error:  # a UserInputError of read_bounded too
        raise UserInputError(f"{path} cannot be read ({error})") from None
    try:
        parts = _parse(text)["parts"]
        if not isinstance(parts, list) or not all(
            isinstance(part, dict)
            and all(_is_number(part.get(key)) for key in ("wall_s", "experiments"))
            for part in parts
        ):
            raise TypeError("parts must be a list of {started, wall_s, experiments}")
    except (ValueError, KeyError, TypeError) as error:
        raise UserInputError(
            f"{path} is damaged ({type(error).__name__}: {error}); remove it "
            "to resume without the earlier parts' wall times"
        ) from None
    return [dict(part) for part in parts]


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

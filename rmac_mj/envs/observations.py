"""The learner's state x inferred from an environment's observations: the specs' bounds read,
(cos, sin) pairs folded into angles, what the user declared filled in, what is still missing
refused (:func:`infer_learner_state`). The entries and their map are
:mod:`rmac_mj.envs.observation_map`'s."""

from __future__ import annotations

import dataclasses
import difflib
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from rmac_mj.envs.observation_map import (
    OBSERVATION,
    ObservationLayout,
    ObservationMap,
)
from rmac_mj.tasks.common import LearnerStateSpec

#: |cos^2 + sin^2 - 1| allowed on every probed observation (float32 observations round at 1e-7).
UNIT_TOLERANCE = 1e-5
#: A dimension whose spec gives no bounds and that nobody declared gets the range random actions
#: reach, widened about its centre by this fraction of its half-width on each side: a learned policy
#: goes faster than random actions (docs/design-notes.md).
MEASURED_MARGIN = 0.5


def unit_pairs(layout: ObservationLayout, samples: np.ndarray) -> list[tuple[str, int, int]]:
    """The (cos, sin) pairs of ``samples`` (shape (T, flat size), raw observations flattened in
    layout order): (key, i, j), i < j, elements of one key within [-1, 1] whose squares sum to 1 on
    every sample, and that are not constant. ValueError naming the key where an element belongs to
    more than one such pair (which angle it is cannot be told)."""
    pairs: list[tuple[str, int, int]] = []
    offset = 0
    for key in layout.keys:
        size = layout.sizes[key]
        block = samples[:, offset : offset + size]
        offset += size
        candidates = [
            (i, j)
            for i, j in _possible_pairs(block, layout.low[key], layout.high[key])
            if _is_unit_pair(block[:, i], block[:, j], layout, key, i, j)
        ]
        used: dict[int, list[tuple[int, int]]] = {}
        for i, j in candidates:
            used.setdefault(i, []).append((i, j))
            used.setdefault(j, []).append((i, j))
        clashes = sorted(
            {
                pair
                for element_pairs in used.values()
                if len(element_pairs) > 1
                for pair in element_pairs
            }
        )
        if clashes:
            listed = ", ".join(f"({key}[{i}], {key}[{j}])" for i, j in clashes)
            raise ValueError(
                f"observation {key!r} is ambiguous: its elements form overlapping "
                f"(cos, sin) pairs {listed}; declare learner_state.keys (e.g. "
                f"'atan2({key}[{clashes[0][1]}], {key}[{clashes[0][0]}])')"
            )
        pairs.extend((key, i, j) for i, j in candidates)
    return pairs


#: Candidate pairs checked on every sample at once, at most (memory: this many times the samples).
_PAIR_CHUNK = 4096


def _possible_pairs(block: np.ndarray, low: np.ndarray, high: np.ndarray) -> list[tuple[int, int]]:
    """The pairs (i, j), i < j, in order, whose squares sum to 1 within :data:`UNIT_TOLERANCE` on
    every sample of ``block`` (shape (T, size)), of elements whose bounds allow it: a superset of
    the pairs :func:`_is_unit_pair` accepts, found by sorting the first sample's squares (near
    ``size log size``, where trying every pair took hours for 100,000 elements)."""
    size = block.shape[1]
    if size < 2 or block.shape[0] == 0:
        return []
    limit = 1 + UNIT_TOLERANCE
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)  # NaN: unbounded
    allowed = ~(low < -limit) & ~(high > limit) & np.all(np.abs(block) <= limit, axis=0)
    index = np.flatnonzero(allowed)
    squares = block[:, index] * block[:, index]
    order = np.argsort(squares[0], kind="stable")
    first = squares[0, order]
    slack = 2 * UNIT_TOLERANCE  # wider than the test below, so that rounding loses no pair
    lows = np.searchsorted(first, 1.0 - first - slack, side="left")
    highs = np.searchsorted(first, 1.0 - first + slack, side="right")
    pairs = [
        (a, b)
        for k in range(len(order))
        for a, b in ((order[k], m) for m in order[lows[k] : highs[k]])
        if a < b
    ]
    kept = []
    for start in range(0, len(pairs), _PAIR_CHUNK):
        a, b = np.array(pairs[start : start + _PAIR_CHUNK]).T
        unit = np.all(np.abs(squares[:, a] + squares[:, b] - 1.0) <= UNIT_TOLERANCE, axis=0)
        kept.extend(zip(index[a[unit]].tolist(), index[b[unit]].tolist()))
    return sorted(kept)


def _is_unit_pair(
    c: np.ndarray, s: np.ndarray, layout: ObservationLayout, key: str, i: int, j: int
) -> bool:
    for index in (i, j):
        low, high = layout.bound(key, index)
        if (not math.isnan(low) and low < -1 - UNIT_TOLERANCE) or (
            not math.isnan(high) and high > 1 + UNIT_TOLERANCE
        ):
            return False
    if not np.all(np.abs(c * c + s * s - 1.0) <= UNIT_TOLERANCE):
        return False
    return bool(np.ptp(np.arctan2(s, c)) > 1e-6)  # a constant pair is no angle that moves


def inferred_entries(layout: ObservationLayout, samples: np.ndarray) -> list[str]:
    """Every element of the observation as an entry, each (cos, sin) pair folded into one angle
    (at the cosine's place; the cosine is taken to come first, as in Gymnasium and dm-control)."""
    pairs = unit_pairs(layout, samples)
    folded = {(key, i): f"atan2({key}[{j}], {key}[{i}])" for key, i, j in pairs}
    dropped = {(key, j) for key, _, j in pairs}
    entries = []
    for key in layout.keys:
        for index in range(layout.sizes[key]):
            if (key, index) in folded:
                entries.append(folded[key, index])
            elif (key, index) not in dropped:
                entries.append(
                    f"{key}[{index}]" if layout.sizes[key] > 1 or key == OBSERVATION else key
                )
    return entries


def default_weights(low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Input weighting of each dimension: 2 pi / (high - low), so a nominal range weighs as one
    turn of an angle. On dc_pendulum this gives (1, 0.125) for Table 2's (1, 0.1)."""
    return 2.0 * math.pi / (np.asarray(high, dtype=float) - np.asarray(low, dtype=float))


_FIELDS = tuple(f.name for f in dataclasses.fields(LearnerStateSpec))
#: What a declaration may hold: LearnerStateSpec's fields, and ``bounds``: {dimension name: [low, high]}
#: for some dimensions of x (named as in the messages, e.g. "velocity[0]"), the others inferred.
DECLARABLE = _FIELDS + ("bounds",)


def check_declaration(declared: Mapping[str, Any] | None) -> dict[str, Any]:
    """A ``[learner_state]`` table (some of :data:`DECLARABLE`) as a dict; unknown fields refused."""
    declared = dict(declared or {})
    for name in declared:
        if name not in DECLARABLE:
            close = difflib.get_close_matches(name, DECLARABLE, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ValueError(
                f"learner_state has no field {name!r}{hint}; its fields: {', '.join(DECLARABLE)}"
            )
    bounds = declared.get("bounds", {})
    if not isinstance(bounds, Mapping):
        raise ValueError(
            f"learner_state.bounds must map dimension names to [low, high], got {bounds!r}"
        )
    return declared


def measured_box(x: np.ndarray, margin: float = MEASURED_MARGIN) -> tuple[np.ndarray, np.ndarray]:
    """(low, high), shape (n,): the range of the states ``x`` (shape (T, n)) widened about its centre
    by ``margin`` times its half-width on each side; a dimension that never moved gets +-1 about its
    value (a box must have width)."""
    x = np.asarray(x, dtype=float)
    lo, hi = x.min(axis=0), x.max(axis=0)
    centre, half = (lo + hi) / 2.0, (hi - lo) / 2.0 * (1.0 + margin)
    half = np.where(half > 0.0, half, 1.0)
    return centre - half, centre + half


def infer_learner_state(
    layout: ObservationLayout,
    samples: np.ndarray,
    action_low: np.ndarray,
    action_high: np.ndarray,
    declared: Mapping[str, Any] | None = None,
    owner: str = "the environment",
    measure: Any = None,
    measured: dict[str, list[float]] | None = None,
) -> LearnerStateSpec:
    """The full LearnerStateSpec: the ``declared`` fields as given, the others inferred.

    Args:
      layout: the raw observation's entries and spec bounds.
      samples: probed observations, flattened in layout order, shape (T, flat size); used only to
        find (cos, sin) pairs when ``declared`` gives no ``keys``.
      action_low, action_high: the action bounds, shape (m,).
      declared: some of LearnerStateSpec's fields (a ``[learner_state]`` table).
      owner: how the environment is named in messages (its SPEC).
      measure: where the specs give no bounds and none are declared, a function ``mapping -> x``
        (an :class:`ObservationMap` to states of shape (T, n), e.g. of random-action rollouts) whose
        :func:`measured_box` bounds them; None: such dimensions are refused.
      measured: filled with the measured dimensions, name -> [low, high].
    Raises:
      ValueError: in one line, naming what is missing (bounds of an unbounded entry) or ambiguous.
    """
    declared = check_declaration(declared)
    entries = _entries(declared, layout, samples, owner)
    mapping = ObservationMap(entries, layout)
    spec_low, spec_high = mapping.spec_bounds()
    low = _declared_vector(declared, "low", spec_low, mapping, owner)
    high = _declared_vector(declared, "high", spec_high, mapping, owner)
    _apply_bounds(declared, low, high, mapping.dimension_names(), owner)
    _bound_the_rest(low, high, mapping, measure, measured, owner)
    action_low = np.asarray(action_low, dtype=float).reshape(-1)
    action_high = np.asarray(action_high, dtype=float).reshape(-1)
    inferred = _inferred_fields(entries, low, high, mapping, action_low, action_high)
    given = _given_fields(declared, action_low.size, owner)
    try:
        return LearnerStateSpec(**{**inferred, **given})
    except ValueError as error:
        raise ValueError(f"{owner}: {error}") from None


def _entries(declared: dict[str, Any], layout: ObservationLayout, samples, owner: str) -> list:
    """The entries of x: the declared ``keys``, else inferred from the ``samples``."""
    if "bounds" in declared and ("low" in declared or "high" in declared):
        raise ValueError(
            f"{owner}: declare the state box either as learner_state.low and .high or "
            f"as learner_state.bounds, not both"
        )
    keys = declared.get("keys")
    if isinstance(keys, str):
        raise ValueError(f"learner_state.keys must be a list of entries, got the string {keys!r}")
    return list(keys) if keys is not None else inferred_entries(layout, samples)


def _declared_vector(
    declared: dict[str, Any], name: str, default: np.ndarray, mapping: ObservationMap, owner: str
) -> np.ndarray:
    """The declared ``name`` (low or high) as a vector of x's dimension, else ``default``."""
    if name not in declared:
        return default
    value = np.asarray(declared[name], dtype=float).reshape(-1)
    if value.shape != (mapping.dim,):
        raise ValueError(
            f"{owner}: learner_state.{name} needs {mapping.dim} values, one per dimension of "
            f"x = [{', '.join(mapping.dimension_names())}], got {declared[name]!r}"
        )
    return value


def _apply_bounds(declared, low: np.ndarray, high: np.ndarray, names: tuple[str, ...], owner: str):
    """The declared ``bounds`` (dimension name -> [low, high]) written into ``low`` and ``high``."""
    for name, bound in declared.get("bounds", {}).items():
        if name not in names:
            close = difflib.get_close_matches(name, names, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ValueError(
                f"{owner}: learner_state.bounds names {name!r}{hint}, not a dimension "
                f"of x = [{', '.join(names)}]"
            )
        bound = np.asarray(bound, dtype=float).reshape(-1)
        if bound.shape != (2,):
            raise ValueError(
                f"{owner}: learner_state.bounds[{name!r}] must be [low, high], got "
                f"{declared['bounds'][name]!r}"
            )
        low[names.index(name)], high[names.index(name)] = bound


def _bound_the_rest(low, high, mapping: ObservationMap, measure, measured, owner: str) -> None:
    """The dimensions still without a bound measured in place (``measure``, ``measured``: as for
    :func:`infer_learner_state`); ValueError naming them where nothing can measure them."""
    names = mapping.dimension_names()
    missing = [name for name, lo, hi in zip(names, low, high) if math.isnan(lo) or math.isnan(hi)]
    if not missing:
        return
    if measure is None:
        example = ", ".join(f'"{name}" = [LOW, HIGH]' for name in missing)
        as_json = ", ".join(f'"{name}": [LOW, HIGH]' for name in missing)
        raise ValueError(
            f"{owner}: no finite bounds for {', '.join(missing)} (the observation spec "
            f"gives none); declare them: learner_state.bounds = {{{example}}} in a --config "
            f"file, or --learner-state '{{\"bounds\": {{{as_json}}}}}'"
        )
    at = [names.index(name) for name in missing]
    box_low, box_high = measured_box(np.asarray(measure(mapping), dtype=float)[:, at])
    for i, name, lo, hi in zip(at, missing, box_low, box_high):
        low[i] = lo if math.isnan(low[i]) else low[i]  # a spec's one-sided bound is kept
        high[i] = hi if math.isnan(high[i]) else high[i]
        if measured is not None:
            measured[name] = [float(low[i]), float(high[i])]


def _inferred_fields(entries, low, high, mapping: ObservationMap, action_low, action_high):
    """Every field of the LearnerStateSpec as inferred from the specs."""
    names = mapping.dimension_names()
    return {
        "keys": tuple(entries),
        "low": tuple(low),
        "high": tuple(high),
        "periodic": mapping.periodic(),
        # The suite's label convention is "description symbol [unit]" (the overlay of a video shows
        # the last word): an entry without spaces is its own symbol.
        "labels": tuple(
            name.replace(" ", "") + (" [rad]" if p else "")
            for name, p in zip(names, mapping.periodic())
        ),
        "input_weights": tuple(default_weights(low, high)),
        "action_input_weights": tuple(default_weights(action_low, action_high)),
        "action_labels": tuple(f"u[{i}]" for i in range(action_low.size)),
        # What the reward charges for the action cannot be read from the specs: only declared.
        "action_cost": None,
    }


def _given_fields(declared: dict[str, Any], actions: int, owner: str) -> dict[str, Any]:
    """The declared fields beside the box, lists as tuples; ``actions``: the action's dimension."""
    given = {
        name: (tuple(value) if isinstance(value, list) else value)
        for name, value in declared.items()
        if name in _FIELDS and name not in ("low", "high")
    }
    if given.get("action_cost") is not None and len(given["action_cost"]) != actions:
        raise ValueError(
            f"{owner}: learner_state.action_cost needs {actions} values, one per "
            f"action dimension, got {declared['action_cost']!r}"
        )
    return given

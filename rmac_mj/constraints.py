"""Parameter constraints, declared once per configuration (as scikit-learn's).

A config declares ``{parameter: [constraint, ...]}`` (:class:`Interval`, :class:`Options`,
:class:`Boolean`, :class:`TupleOf`, :class:`InstanceOf`; ``None`` allows None); :func:`check`
applies it with one kind of message, the sweep checker reads it (:func:`lookup`, :func:`unmet`).
A bound may be another field (:class:`Field`) or a :class:`Limit`: a size that scales a loop or an
allocation, capped once at the end of this module with the reason every refusal says.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import numbers
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

__all__ = [
    "Boolean",
    "Field",
    "InstanceOf",
    "Interval",
    "InvalidParameterError",
    "Limit",
    "Options",
    "TupleOf",
    "WEIGHTS",
    "check",
    "finite_vector",
    "invalid",
    "lookup",
    "unknown",
    "unmet",
]


class InvalidParameterError(ValueError, TypeError):
    """A configuration value its table refuses (a ValueError and, for a wrong type, a TypeError to
    code that catches that, as scikit-learn's)."""


@dataclasses.dataclass(frozen=True)
class Field:
    """A bound taken from another parameter of the same configuration, e.g. ``Field("capacity")``."""

    name: str


@dataclasses.dataclass(frozen=True)
class Limit:
    """An upper bound on a size that scales a loop or an allocation (experiments, trials, a grid's
    points), with why it is there; an :class:`Interval` bound, its reason said in every refusal."""

    value: int
    reason: str
    #: The smallest size that makes sense (for :meth:`constraint`).
    low: int = 1

    def constraint(self) -> Interval:
        """The integers in [low, value], as a constraint (its message says the reason)."""
        return Interval(numbers.Integral, self.low, self)

    def refusal(self, name: str, value: Any) -> str:
        """The one message of a size beyond the limit: ``{name} must be at most {limit}
        ({reason}), got {value!r}``."""
        return f"{name} must be at most {self.value} ({self.reason}), got {value!r}"


class Constraint:
    """One rule a value may satisfy; ``str(constraint)`` says what it expects."""

    def satisfied(self, value: Any, context: Mapping[str, Any] | None = None) -> bool:
        raise NotImplementedError

    def normalise(self, value: Any) -> Any:
        """The value as the configuration keeps it (e.g. a list as a tuple); called once satisfied."""
        return value

    def describe(self, context: Mapping[str, Any] | None = None) -> str:
        raise NotImplementedError

    def __str__(self) -> str:
        return self.describe()


def _is_real(value: Any) -> bool:
    return (
        isinstance(value, (numbers.Real, np.floating, np.integer))
        and not isinstance(value, (bool, np.bool_))
        and math.isfinite(value)
    )


def _is_integer(value: Any) -> bool:
    return isinstance(value, (numbers.Integral, np.integer)) and not isinstance(
        value, (bool, np.bool_)
    )


class Interval(Constraint):
    """A real number (``numbers.Real``) or an integer (``numbers.Integral``) in a range.

    Args:
      kind: ``numbers.Real`` or ``numbers.Integral``.
      low, high: the bounds, None for none, or a :class:`Field` naming another parameter.
      closed: which bounds belong to the range: 'both', 'left', 'right' or 'neither'.
    """

    def __init__(self, kind: type, low: Any = None, high: Any = None, closed: str = "both") -> None:
        if kind not in (numbers.Real, numbers.Integral):
            raise ValueError(
                f"Interval kind must be numbers.Real or numbers.Integral, got {kind!r}"
            )
        if closed not in ("both", "left", "right", "neither"):
            raise ValueError(
                f"Interval closed must be 'both', 'left', 'right' or 'neither', got {closed!r}"
            )
        self.kind, self.low, self.high, self.closed = kind, low, high, closed

    @staticmethod
    def _bound(bound: Any, context: Mapping[str, Any] | None) -> Any:
        """A Field's value from ``context`` (None when unknown or not a number: then no bound)."""
        if isinstance(bound, Limit):
            return bound.value
        if not isinstance(bound, Field):
            return bound
        value = (context or {}).get(bound.name)
        return value if _is_real(value) else None

    def satisfied(self, value: Any, context: Mapping[str, Any] | None = None) -> bool:
        if not (_is_integer(value) if self.kind is numbers.Integral else _is_real(value)):
            return False
        low, high = self._bound(self.low, context), self._bound(self.high, context)
        if low is not None and (
            value < low or (value == low and self.closed in ("right", "neither"))
        ):
            return False
        if high is not None and (
            value > high or (value == high and self.closed in ("left", "neither"))
        ):
            return False
        return True

    def describe(self, context: Mapping[str, Any] | None = None) -> str:
        noun = "an integer" if self.kind is numbers.Integral else "a number"

        def show(bound: Any) -> str:
            if isinstance(bound, Limit):
                return str(bound.value)
            if isinstance(bound, Field):
                value = (context or {}).get(bound.name)
                return f"{bound.name}={value!r}" if value is not None else bound.name
            return f"{bound:g}" if isinstance(bound, float) else str(bound)

        if self.low is not None and self.high is not None:
            left = "[" if self.closed in ("both", "left") else "("
            right = "]" if self.closed in ("both", "right") else ")"
            why = f" ({self.high.reason})" if isinstance(self.high, Limit) else ""
            return f"{noun} in {left}{show(self.low)}, {show(self.high)}{right}{why}"
        if self.kind is numbers.Real:
            noun = "a finite number"
        if self.low is not None:
            return f"{noun} {'>=' if self.closed in ('both', 'left') else '>'} {show(self.low)}"
        if self.high is not None:
            return f"{noun} {'<=' if self.closed in ('both', 'right') else '<'} {show(self.high)}"
        return "a finite number" if self.kind is numbers.Real else "an integer"


class Options(Constraint):
    """One of the given values: strings, or ints (a bool never counts as an int here)."""

    def __init__(self, *values: Any) -> None:
        self.values = tuple(values)

    def satisfied(self, value: Any, context: Mapping[str, Any] | None = None) -> bool:
        if isinstance(value, str):
            return value in [v for v in self.values if isinstance(v, str)]
        if _is_integer(value):
            return any(_is_integer(v) and value == v for v in self.values)
        return False

    def describe(self, context: Mapping[str, Any] | None = None) -> str:
        shown = [repr(v) for v in self.values]
        if len(shown) == 2:
            return f"{shown[0]} or {shown[1]}"
        return "one of " + ", ".join(shown)


class Boolean(Constraint):
    """True or False."""

    def satisfied(self, value: Any, context: Mapping[str, Any] | None = None) -> bool:
        return isinstance(value, (bool, np.bool_))

    def normalise(self, value: Any) -> bool:
        return bool(value)

    def describe(self, context: Mapping[str, Any] | None = None) -> str:
        return "True or False"


class TupleOf(Constraint):
    """A sequence (tuple, list, 1-D array) of at least one entry, each satisfying ``elements`` (a
    constraint, or a list of them with None allowed); normalised to a tuple (real entries as floats).
    ``length``: a required number of entries (an int or a :class:`Field`), else any."""

    def __init__(self, elements: Any, length: Any = None, what: str | None = None) -> None:
        self.elements = list(elements) if isinstance(elements, (list, tuple)) else [elements]
        self.length = length
        self.what = what

    def _entries(self, value: Any) -> list | None:
        if isinstance(value, np.ndarray):
            return list(value.tolist()) if value.ndim == 1 else None
        if isinstance(value, (tuple, list)):
            return list(value)
        return None

    def satisfied(self, value: Any, context: Mapping[str, Any] | None = None) -> bool:
        entries = self._entries(value)
        if not entries:
            return False
        length = Interval._bound(self.length, context)
        if length is not None and len(entries) != length:
            return False
        return all(_first_satisfied(self.elements, entry, context) is not None for entry in entries)

    def normalise(self, value: Any) -> tuple:
        out = []
        for entry in self._entries(value):
            if _is_real(entry) and not _is_integer(entry):
                entry = float(entry)
            elif _is_integer(entry) and any(
                isinstance(c, Interval) and c.kind is numbers.Real for c in self.elements
            ):
                entry = float(entry)
            elif _is_integer(entry):
                entry = int(entry)
            out.append(entry)
        return tuple(out)

    def describe(self, context: Mapping[str, Any] | None = None) -> str:
        if self.what:
            return self.what
        element = _alternatives(self.elements, context)
        length = self.length
        if isinstance(length, Field):
            value = (context or {}).get(length.name)
            count = f"{length.name}={value!r}" if value is not None else length.name
            return f"a list of {count} entries, each {element}"
        if length is not None:
            return f"a list of {length} entries, each {element}"
        return f"a list of one or more entries, each {element}"


class InstanceOf(Constraint):
    """An instance of ``cls`` (for a dataclass, the sweep checker descends into its own table)."""

    def __init__(self, cls: type) -> None:
        self.cls = cls

    def satisfied(self, value: Any, context: Mapping[str, Any] | None = None) -> bool:
        return isinstance(value, self.cls)

    def describe(self, context: Mapping[str, Any] | None = None) -> str:
        name = self.cls.__name__
        return f"{'an' if name[0] in 'AEIOU' else 'a'} {name}"


#: Input weightings of an LLR memory: finite numbers >= 0, one per input dimension.
WEIGHTS = TupleOf(Interval(numbers.Real, 0, None), what="a list of finite numbers >= 0")

#: What every TD(lambda) learner here declares alike (Table 2): the discount gamma in [0, 1), the
#: trace decay lambda and the critic's learning rate alpha_c in [0, 1].
TD_LAMBDA = {
    "gamma": [Interval(numbers.Real, 0, 1, closed="left"), None],
    "lam": [Interval(numbers.Real, 0, 1), None],
    "alpha_c": [Interval(numbers.Real, 0, 1)],
}
#: A learner's compute back end: compiled kernels or their numpy version (the same results).
BACKEND = [Options("numba", "numpy")]


def _alternatives(constraints: Sequence[Any], context: Mapping[str, Any] | None = None) -> str:
    """What a list of constraints expects, e.g. "a number in [0, 1] or None"."""
    shown = ["None" if c is None else c.describe(context) for c in constraints]
    return (", or " if any("," in text for text in shown) else " or ").join(shown)


#: What :func:`_first_satisfied` returns for a None its constraints allow.
_NONE_ALLOWED = object()


def _first_satisfied(
    constraints: Iterable[Any], value: Any, context: Mapping[str, Any] | None = None
) -> Any:
    """The first constraint ``value`` satisfies (``_NONE_ALLOWED`` for an allowed None), or None."""
    for constraint in constraints:
        if constraint is None:
            if value is None:
                return _NONE_ALLOWED
        elif constraint.satisfied(value, context):
            return constraint
    return None


def unmet(
    value: Any, constraints: Sequence[Any], context: Mapping[str, Any] | None = None
) -> str | None:
    """None when ``value`` satisfies one of ``constraints``, else what was expected (for messages).

    ``context`` holds the configuration's other values, for bounds that name them; without it such
    a bound is not applied (the whole configuration is checked later). A nested configuration may
    be given as data, a dict of some of its parameters (as a TOML table gives it), which are then
    judged by its own table."""
    if _first_satisfied(constraints, value, context) is not None:
        return None
    nested = nested_class(constraints)
    if nested is not None and isinstance(value, dict):
        table = nested.parameter_constraints
        for key, item in value.items():
            if key not in table:
                return f"{nested.__name__} parameters ({', '.join(table)}), not {key!r}"
            problem = unmet(item, table[key], value)
            if problem is not None:
                return f"{nested.__name__}.{key} to be {problem}"
        return None
    return _alternatives(constraints, context)


def invalid(owner: str, name: str, value: Any, expected: str) -> InvalidParameterError:
    """The one message of a refused value: ``{owner}.{name} must be {expected}, got {value!r}``."""
    return InvalidParameterError(f"{owner}.{name} must be {expected}, got {value!r}")


def unknown(owner: str, name: str, known: Iterable[str], prefix: str = "") -> InvalidParameterError:
    """The one message of a parameter ``owner`` does not have, with the closest known name as the
    user writes it (after ``prefix``, e.g. ``"rmac."``). ``known`` may be the owner's table: then a
    flat name of a nested config's parameter (``critic_capacity``) is told its dotted name
    (``critic.capacity``)."""
    table = known if isinstance(known, Mapping) else None
    known = list(known)
    close = difflib.get_close_matches(name, known, n=1)
    for field in sorted(known, key=len, reverse=True) if table is not None else ():
        nested = nested_class(table[field])
        leaf = name[len(field) + 1 :]
        if (
            nested is not None
            and name.startswith(f"{field}_")
            and leaf in nested.parameter_constraints
        ):
            close = [f"{field}.{leaf}"]
            break
    hint = f" (did you mean {prefix + close[0]!r}?)" if close else f"; it has {', '.join(known)}"
    return InvalidParameterError(f"{owner} has no parameter {name!r}{hint}")


def check(owner: str, table: Mapping[str, Sequence[Any]], values: Mapping[str, Any]) -> dict:
    """Check every ``values[name]`` against ``table[name]``; return the normalised values.

    Raises :class:`InvalidParameterError` naming the first refused parameter (in table order), its
    value and what was expected. Every name of ``values`` must be in ``table``.

    The messages read::

        RMACConfig.gamma must be a number in [0, 1), got 1.0 LLRMemory.n_neighbours must be an
        integer in [1, capacity=100], got 200 RMACConfig has no parameter 'alpha_x' (did you mean
        'alpha_r'?)
    """
    for name in values:
        if name not in table:
            raise unknown(owner, name, table)
    normalised = {}
    for name, constraints in table.items():
        if name not in values:
            continue
        value = values[name]
        chosen = _first_satisfied(constraints, value, values)
        if chosen is None:
            raise invalid(owner, name, value, unmet(value, constraints, values))
        normalised[name] = value if chosen is _NONE_ALLOWED else chosen.normalise(value)
    return normalised


def finite_vector(value: Any, dim: int, name: str, owner: str = "") -> np.ndarray:
    """``value`` (any array of ``dim`` entries) as a new float64 vector of shape (dim,); ValueError
    naming ``name`` (after ``owner: ``) when it has another size or an entry that is not finite.
    The check of an input vector at a boundary: an action, a state to encode."""
    v = np.array(value, dtype=float).reshape(-1)
    said = f"{owner}: {name}" if owner else name
    if v.shape != (dim,):
        raise ValueError(f"{said} must have shape ({dim},), got shape {np.shape(value)}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{said} must be finite, got {value!r}")
    return v


def check_config(config: Any) -> None:
    """Check a frozen dataclass config against its class's ``parameter_constraints`` table, and keep
    the normalised values (e.g. weightings as tuples of floats) in place."""
    cls = type(config)
    values = {field.name: getattr(config, field.name) for field in dataclasses.fields(config)}
    normalised = check(cls.__name__, cls.parameter_constraints, values)
    for name, value in normalised.items():
        if value is not values[name]:
            object.__setattr__(config, name, value)


def lookup(cls: type, path: Sequence[str], prefix: str = "") -> list:
    """The constraints of the (possibly nested) parameter ``path`` of config class ``cls``, e.g.
    ``lookup(RMACConfig, ["exploration", "sigma"])``; descends through :class:`InstanceOf` a
    dataclass. Raises :class:`InvalidParameterError` for an unknown name (with the closest one,
    written as the dotted key after ``prefix``, e.g. ``"rmac."``)."""
    constraints: list = []
    owner = cls
    for depth, name in enumerate(path):
        table = getattr(owner, "parameter_constraints", None)
        if table is None:
            raise InvalidParameterError(f"{owner.__name__} has no parameters (no {name!r})")
        if name not in table:
            raise unknown(
                owner.__name__, name, table, prefix + "".join(f"{p}." for p in path[:depth])
            )
        constraints = list(table[name])
        if depth < len(path) - 1:
            nested = [
                c.cls
                for c in constraints
                if isinstance(c, InstanceOf) and hasattr(c.cls, "parameter_constraints")
            ]
            if not nested:
                raise InvalidParameterError(f"{owner.__name__}.{name} has no parameters of its own")
            owner = nested[0]
    return constraints


def nested_class(constraints: Sequence[Any]) -> type | None:
    """The config class of a nested parameter (an :class:`InstanceOf` a class with its own table)."""
    for constraint in constraints:
        if isinstance(constraint, InstanceOf) and hasattr(constraint.cls, "parameter_constraints"):
            return constraint.cls
    return None


# ----------------------------------------------------------------------------------------------------
# Sizes that scale a loop or an allocation: each is capped here, once, with its reason, far above any
# run this package's studies make and below what would hang or exhaust a machine. Memories,
# tilings and networks are not capped by a number: their estimated bytes are checked against the
# machine's memory before anything is allocated (``rmac_mj.experiments.admission``).

#: Learning experiments per learner (a Protocol's ``experiments``; the paper runs 40).
EXPERIMENTS = Limit(10_000, "each is a process's task, a curve file and a seed stream")
#: Learning trials per experiment (the paper runs 600).
TRIALS = Limit(1_000_000, "every trial is kept, a row of the curve in memory and on disk")
#: Greedy trials from distinct starts per evaluation (``evaluate_starts``).
EVALUATE_STARTS = Limit(1_000, "every evaluation runs this many greedy trials", low=0)
#: Demonstrator trials recorded per experiment (``prior_trials``).
PRIOR_TRIALS = Limit(10_000, "each experiment records and keeps them before its first trial")
#: Environment steps per learner step of an outside environment (``action_repeat``).
ACTION_REPEAT = Limit(1_000, "every learner step holds its action for this many environment steps")
#: Learner steps after which an outside environment's trial is truncated (``trial_steps``).
TRIAL_STEPS = Limit(10_000_000, "a trial of an environment without a time limit runs this long")
#: Rehearsed transitions (planning's simulated, replay's stored) per real transition, after each trial.
REHEARSAL_STEPS = Limit(10_000, "each real trial is followed by this many times its transitions")
#: Configurations of one sweep file (the variants times the grid's points).
SWEEP_CONFIGURATIONS = Limit(
    10_000, "each is built and checked before anything runs, then given a directory of its own"
)
#: Numbers in one observation of an outside environment, checked before it is probed.
OBSERVATION_SIZE = Limit(100_000, "the learners' memories and tilings scale with the state's size")
#: Bytes of one rendered episode's frames (width x height x 3 per frame, ``render``).
VIDEO_BYTES = Limit(4 * 10**9, "every frame is kept in memory until the video is written")
#: Grid points along each axis of a policy or critic map (``policy --resolution``).
MAP_RESOLUTION = Limit(2_000, "a map evaluates the learner at resolution**2 states", low=2)
#: The shortest control step in seconds (``control_timestep``, or an environment's own): the
#: learners carry their per-step factors from the paper's 0.03 s step (gamma ** (dt / 0.03)), and
#: much shorter steps make them 1, a discount no learner converges with.
MIN_CONTROL_TIMESTEP = 1e-6
#: Bytes of a sweep or ``--config`` file (the study files are a few kilobytes).
CONFIG_FILE_BYTES = Limit(1_000_000, "the file is read whole and checked before anything runs")
#: Arrays and inline tables nested in one another in a sweep or ``--config`` file.
CONFIG_NESTING = Limit(32, "the parser descends into each level")
#: Characters of one key of a sweep or ``--config`` file, a dotted key whole
#: (``rmac.exploration.sigma`` has 22).
CONFIG_KEY_LENGTH = Limit(200, "the parser makes a table of each part, and messages name the key")
#: Bytes of one of a result directory's JSON documents (config.json, summary.json, wall_times.json).
RESULT_DOCUMENT_BYTES = Limit(10**9, "the document is read whole into memory")

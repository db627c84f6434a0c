"""The raw observation's layout (entries, sizes, spec bounds) and the map from it to the learner's
state x: an entry is ``KEY``, ``KEY[i]`` or ``atan2(KEY[j], KEY[i])`` (one periodic dimension)."""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

#: The key of a Box (non-dict) observation.
OBSERVATION = "observation"
#: A bound at or beyond this magnitude counts as none (float32's max stands in for "unbounded").
UNBOUNDED = 1e30

_ELEMENT = re.compile(r"^(?P<key>[^\[\]()]+)\[(?P<index>\d+)\]$")
_ANGLE = re.compile(r"^atan2\((?P<sin>[^,()]+\[\d+\]),\s*(?P<cos>[^,()]+\[\d+\])\)$")


@dataclasses.dataclass(frozen=True)
class ObservationLayout:
    """The raw observation's entries: key -> (size, low, high), low/high of shape (size,), NaN where
    the spec gives no finite bound."""

    sizes: dict[str, int]
    low: dict[str, np.ndarray]
    high: dict[str, np.ndarray]

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(self.sizes)

    def check_key(self, key: str, owner: str) -> None:
        if key not in self.sizes:
            close = difflib.get_close_matches(key, self.keys, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ValueError(
                f"{owner}: the observation has no entry {key!r}{hint}; it has "
                f"{', '.join(self.keys)}"
            )

    def bound(self, key: str, index: int) -> tuple[float, float]:
        """(low, high) of element ``index`` of ``key``; NaN where unbounded."""
        return float(self.low[key][index]), float(self.high[key][index])


def _bounds(low: Any, high: Any, size: int) -> tuple[np.ndarray, np.ndarray]:
    lo = np.broadcast_to(np.asarray(low, dtype=float), (size,)).reshape(size).copy()
    hi = np.broadcast_to(np.asarray(high, dtype=float), (size,)).reshape(size).copy()
    lo[~(np.abs(lo) < UNBOUNDED)] = np.nan
    hi[~(np.abs(hi) < UNBOUNDED)] = np.nan
    return lo, hi


def layout_of_dm_env(spec: Any) -> ObservationLayout:
    """The layout of a dm_env observation spec (a dict of ``specs.Array``, or one Array)."""
    specs = spec if isinstance(spec, Mapping) else {OBSERVATION: spec}
    sizes, low, high = {}, {}, {}
    for key, array_spec in specs.items():
        if isinstance(array_spec, Mapping):
            raise ValueError(
                f"observation entry {key!r} is a nested dict; declare the learner "
                f"state as a LearnerStateSpec of a flat observation"
            )
        size = int(np.prod(array_spec.shape, dtype=int))
        lo, hi = (getattr(array_spec, "minimum", np.nan), getattr(array_spec, "maximum", np.nan))
        sizes[str(key)] = size
        low[str(key)], high[str(key)] = _bounds(lo, hi, size)
    return ObservationLayout(sizes, low, high)


def layout_of_gymnasium(space: Any) -> ObservationLayout:
    """The layout of a Gymnasium observation space: a Box, or a Dict of Boxes."""
    from gymnasium import spaces

    boxes = dict(space.spaces) if isinstance(space, spaces.Dict) else {OBSERVATION: space}
    sizes, low, high = {}, {}, {}
    for key, box in boxes.items():
        if not isinstance(box, spaces.Box):
            raise ValueError(
                f"observation entry {key!r} is a {type(box).__name__} space; the "
                f"learners take Box observations (or a Dict of Boxes)"
            )
        size = int(np.prod(box.shape, dtype=int))
        sizes[str(key)] = size
        low[str(key)], high[str(key)] = _bounds(box.low, box.high, size)
    return ObservationLayout(sizes, low, high)


# ----------------------------------------------------------------------------------------------------
# Entries: expressions over the raw observation, compiled into one map observation -> x.


@dataclasses.dataclass(frozen=True)
class _Entry:
    """One parsed entry: plain elements (key, indices) or an angle (sin element, cos element)."""

    text: str
    key: str | None = None
    indices: tuple[int, ...] = ()
    sin: tuple[str, int] | None = None
    cos: tuple[str, int] | None = None

    @property
    def is_angle(self) -> bool:
        return self.sin is not None

    @property
    def size(self) -> int:
        return 1 if self.is_angle else len(self.indices)


def parse_entry(text: str, layout: ObservationLayout) -> _Entry:
    """Parse ``KEY``, ``KEY[i]`` or ``atan2(KEY[j], KEY[i])`` against ``layout``; ValueError naming it."""
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"learner_state.keys: an entry must be a non-empty string, got {text!r}")
    text = text.strip()

    def element(part: str) -> tuple[str, int]:
        match = _ELEMENT.match(part.strip())
        if match is None:
            raise ValueError(
                f"learner_state.keys: {text!r} must read KEY, KEY[i] or atan2(KEY[j], KEY[i])"
            )
        key, index = match["key"].strip(), int(match["index"])
        layout.check_key(key, f"learner_state.keys entry {text!r}")
        if index >= layout.sizes[key]:
            raise ValueError(
                f"learner_state.keys entry {text!r}: {key!r} has {layout.sizes[key]} "
                f"elements, index {index} is out of range"
            )
        return key, index

    angle = _ANGLE.match(text)
    if angle is not None:
        return _Entry(text, sin=element(angle["sin"]), cos=element(angle["cos"]))
    if "[" in text or "(" in text:
        key, index = element(text)
        return _Entry(text, key=key, indices=(index,))
    layout.check_key(text, f"learner_state.keys entry {text!r}")
    return _Entry(text, key=text, indices=tuple(range(layout.sizes[text])))


class ObservationMap:
    """x from a raw observation: the entries' elements gathered from one flat vector, angles folded.

    ``__call__(observation) -> ndarray of shape (n,)``; ``entries(observation)`` gives the same as a
    dict entry -> ndarray, the observation a wrapped environment hands to the trial loop.
    """

    def __init__(self, entries: Sequence[str], layout: ObservationLayout) -> None:
        self.layout = layout
        self._keys = layout.keys
        offsets = dict(zip(self._keys, np.cumsum([0] + [layout.sizes[k] for k in self._keys])))
        self.entries_ = tuple(parse_entry(e, layout) for e in entries)
        if len({e.text for e in self.entries_}) != len(self.entries_):
            raise ValueError(f"learner_state.keys must not repeat an entry, got {list(entries)}")
        plain, sin, cos, angle_at, slices = [], [], [], [], []
        at = 0
        for entry in self.entries_:
            slices.append(slice(at, at + entry.size))
            if entry.is_angle:
                sin.append(offsets[entry.sin[0]] + entry.sin[1])
                cos.append(offsets[entry.cos[0]] + entry.cos[1])
                angle_at.append(at)
                plain.append(0)  # placeholder, overwritten by the angle
            else:
                plain.extend(offsets[entry.key] + i for i in entry.indices)
            at += entry.size
        self.dim = at
        self._plain = np.asarray(plain, dtype=np.int64)
        self._sin = np.asarray(sin, dtype=np.int64)
        self._cos = np.asarray(cos, dtype=np.int64)
        self._angle_at = np.asarray(angle_at, dtype=np.int64)
        self._slices = tuple(slices)
        self.names = tuple(e.text for e in self.entries_)

    def flat(self, observation: Any) -> np.ndarray:
        """The raw observation's entries concatenated in layout order, as floats."""
        if not isinstance(observation, Mapping):
            observation = {OBSERVATION: observation}
        return np.concatenate([observation[k] for k in self._keys], axis=None, dtype=float)

    def __call__(self, observation: Any) -> np.ndarray:
        return self.state_of_flat(self.flat(observation))

    def state_of_flat(self, flat: np.ndarray) -> np.ndarray:
        """x (shape (n,)) from a raw observation flattened by :meth:`flat`."""
        x = flat[self._plain]
        if self._angle_at.size:
            x[self._angle_at] = np.arctan2(flat[self._sin], flat[self._cos])
        return x

    def entries(self, observation: Any) -> dict[str, np.ndarray]:
        return self.split(self(observation))

    def split(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """x (shape (n,)) as its entries, name -> array."""
        return {name: x[s] for name, s in zip(self.names, self._slices)}

    def periodic(self) -> tuple[bool, ...]:
        return tuple(flag for e in self.entries_ for flag in [e.is_angle] * e.size)

    def spec_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) of shape (n,) from the specs: [-pi, pi) for angles, NaN where unbounded."""
        low, high = [], []
        for e in self.entries_:
            if e.is_angle:
                low.append(-math.pi), high.append(math.pi)
            else:
                low.extend(self.layout.low[e.key][list(e.indices)])
                high.extend(self.layout.high[e.key][list(e.indices)])
        return np.asarray(low, dtype=float), np.asarray(high, dtype=float)

    def dimension_names(self) -> tuple[str, ...]:
        """A name per dimension of x: the entry, or ``KEY[i]`` for the elements of a whole key."""
        names = []
        for e in self.entries_:
            if e.size == 1:
                names.append(e.text)
            else:
                names.extend(f"{e.key}[{i}]" for i in e.indices)
        return tuple(names)

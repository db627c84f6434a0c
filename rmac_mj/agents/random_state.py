"""A learner's random generator as numbers, so that snapshots need no pickle (``Agent.state_dict``)."""

from __future__ import annotations

from typing import Any

import numpy as np

_MASK64 = (1 << 64) - 1


def generator_state_array(rng: np.random.Generator) -> np.ndarray:
    """The state of a PCG64 generator as 6 uint64 words: state (hi, lo), inc (hi, lo), has_uint32,
    uinteger. Numeric, so snapshots need no pickle and no ``eval``."""
    st = rng.bit_generator.state
    if st.get("bit_generator") != "PCG64":
        raise ValueError(f"only PCG64 generators can be saved, got {st.get('bit_generator')!r}")
    s, inc = int(st["state"]["state"]), int(st["state"]["inc"])
    return np.array(
        [
            s >> 64,
            s & _MASK64,
            inc >> 64,
            inc & _MASK64,
            int(st["has_uint32"]),
            int(st["uinteger"]),
        ],
        dtype=np.uint64,
    )


def set_generator_state(rng: np.random.Generator, words: Any) -> None:
    """Restore a PCG64 generator from :func:`generator_state_array`'s words."""
    w = np.asarray(words)
    if w.shape != (6,) or w.dtype != np.uint64:
        raise ValueError(f"rng state must be 6 uint64 words, got dtype {w.dtype} shape {w.shape}")
    if rng.bit_generator.state.get("bit_generator") != "PCG64":
        raise ValueError("only PCG64 generators can be restored")
    hi_lo = [int(v) for v in w]
    rng.bit_generator.state = {
        "bit_generator": "PCG64",
        "state": {"state": (hi_lo[0] << 64) | hi_lo[1], "inc": (hi_lo[2] << 64) | hi_lo[3]},
        "has_uint32": hi_lo[4],
        "uinteger": hi_lo[5],
    }

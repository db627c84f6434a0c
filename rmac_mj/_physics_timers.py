"""MuJoCo's profiling timers switched off while we simulate many steps (:func:`untimed`).

MuJoCo times every stage of a step through the global callback ``mjcb_time`` when it is set, and
its Python bindings set it on import to a clock of their own (``mujoco.set_mjcb_time(None)``
restores that clock, it does not unset it). For a one-joint model that is about 40% of a step's
CPU: a dozen clock reads per RK4 stage against a few hundred floating-point operations. The timers
only fill ``MjData.timer`` (profiling figures nobody here reads); no simulated number depends on
them, so every trajectory is bit for bit the same without them (tests/test_physics_timers.py). The
one way to unset the callback is to write NULL into the library's global, which is what this
module does, within a ``with`` block, and puts the bindings' clock back after the last one ends.
A shared helper: it imports no room.
"""

from __future__ import annotations

import contextlib
import ctypes
import glob
import os
import threading
from collections.abc import Iterator

import mujoco

_guard = threading.Lock()
_state: dict = {"depth": 0, "saved": None}


def _callback() -> ctypes.c_void_p | None:
    """The global ``mjcb_time`` of the loaded MuJoCo library, or None where it cannot be found."""
    if "callback" not in _state:
        _state["callback"] = None
        folder = os.path.dirname(mujoco.__file__)
        for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
            for path in sorted(glob.glob(os.path.join(folder, pattern))):
                with contextlib.suppress(OSError, ValueError):
                    # the library the bindings loaded: dlopen of its path returns the same handle
                    _state["callback"] = ctypes.c_void_p.in_dll(ctypes.CDLL(path), "mjcb_time")
                    return _state["callback"]
    return _state["callback"]


@contextlib.contextmanager
def untimed() -> Iterator[None]:
    """MuJoCo steps without its profiling timers inside the block (process-wide while any block of
    any thread is open; nested and concurrent blocks are counted). Where the library's global
    cannot be found, nothing changes."""
    callback = _callback()
    if callback is None:
        yield
        return
    with _guard:
        if _state["depth"] == 0:
            _state["saved"] = callback.value
            callback.value = None
        _state["depth"] += 1
    try:
        yield
    finally:
        with _guard:
            _state["depth"] -= 1
            if _state["depth"] == 0:
                callback.value = _state["saved"]

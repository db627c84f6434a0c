"""Long work says what it is doing: a line every :data:`INTERVAL` seconds while it runs.

Code that may take long names its work (:func:`working`) and may count how far it is
(``work.done`` of ``work.total``); a program that shows lines to someone listens
(:func:`listening`), as ``rmac-mj`` does. Without a listener nothing is said and no thread runs, so
a library user and the worker processes hear nothing. A shared helper: it imports no room.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator

#: Seconds between two lines about the same work (the compile's progress says one as often).
INTERVAL = 10.0

_listener: Callable[[str], None] | None = None
_works: list[Work] = []  # what runs now, outermost first: the innermost is said
_other_voices: list[Callable[[], bool]] = []  # while one of them speaks, nothing is said here
_guard = threading.Lock()


class Work:
    """One piece of long work: ``what`` it is, when it started, and how far it is when it counts
    (``done`` of ``total`` ``unit``, or ``done`` ``unit`` without a total)."""

    def __init__(self, what: str, total: int | None = None, unit: str = "") -> None:
        self.what, self.total, self.unit = what, total, unit
        self.done = 0
        self.started = time.perf_counter()

    def line(self) -> str:
        """``what: 30 s so far`` (and ``, 2000 of 10000 steps`` when it counts)."""
        text = f"{self.what}: {time.perf_counter() - self.started:.0f} s so far"
        if self.total is not None:
            text += f", {self.done} of {self.total} {self.unit}".rstrip()
        elif self.unit:
            text += f", {self.done} {self.unit}"
        return text


@contextlib.contextmanager
def listening(say: Callable[[str], None]) -> Iterator[None]:
    """Let ``say`` hear, in the body, what long work is doing every :data:`INTERVAL` seconds."""
    global _listener
    before, _listener = _listener, say
    try:
        yield
    finally:
        _listener = before


@contextlib.contextmanager
def quiet_while(speaking: Callable[[], bool]) -> Iterator[None]:
    """In the body, nothing is said while ``speaking()`` holds: another voice tells of the same
    wait (the compile's own progress, while numba compiles in a learner's first trial)."""
    with _guard:
        _other_voices.append(speaking)
    try:
        yield
    finally:
        with _guard:
            _other_voices.remove(speaking)


@contextlib.contextmanager
def working(what: str, total: int | None = None, unit: str = "") -> Iterator[Work]:
    """The body is long work ``what`` (e.g. ``"env 'x.py:make': probing it with random actions"``):
    while it runs, the listener hears its line every :data:`INTERVAL` seconds (of the innermost
    work, when works nest). The body may count ``work.done`` of ``total`` ``unit``."""
    work = Work(what, total, unit)
    say = _listener
    if say is None:
        yield work
        return
    with _guard:
        _works.append(work)
        outermost = len(_works) == 1
    done = threading.Event()
    ticker = None
    if outermost:

        def tick() -> None:
            while not done.wait(INTERVAL):
                with _guard:
                    innermost = _works[-1] if _works else None
                    hushed = any(speaking() for speaking in _other_voices)
                if innermost is not None and not hushed:
                    say(innermost.line())

        ticker = threading.Thread(target=tick, name="rmac-mj heartbeat", daemon=True)
        ticker.start()
    try:
        yield work
    finally:
        done.set()
        with _guard:
            _works.remove(work)
        if ticker is not None:
            ticker.join()

"""Where experiments run: in this process, in local worker processes, or on a Dask cluster.

Every back end takes work items and ``run(item)`` and yields results as they finish, drawing items
only as workers free up; an experiment's randomness is its own seed sequence, so every back end
gives the same results.
"""

from __future__ import annotations

import collections
import concurrent.futures
import contextlib
import itertools
import logging
import multiprocessing
import os
import queue
import signal
import socket
import struct
import threading
import time
from collections.abc import Callable, Hashable, Iterable, Iterator
from typing import Any

from rmac_mj.errors import UserInputError

#: Seconds between two calls of ``poll`` while the driver waits for a worker.
POLL_SECONDS = 0.5
#: Items handed to the workers beyond one each, so that none waits for the driver.
_AHEAD = 1
#: Seconds between a worker's looks at whether its driver is still there.
WATCHDOG_SECONDS = 0.5
#: Seconds to wait for a Dask scheduler to answer.
DASK_CONNECT_SECONDS = 10.0
#: The largest greeting a Dask scheduler sends (its handshake: versions and settings, under 1 kB).
_GREETING_BYTES = 2**20


class BackendError(UserInputError):
    """The Dask scheduler cannot be reached, or was lost while experiments ran on it."""


def start_worker(driver: int) -> None:
    """Worker initialiser. Ctrl-C reaches the whole process group; only the driver handles it. And a
    worker whose driver is gone (killed with SIGKILL, which it cannot answer by stopping its
    workers) stops too: a watchdog thread sees the parent change and ends the process."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch() -> None:
        while os.getppid() == driver:
            time.sleep(WATCHDOG_SECONDS)
        os._exit(1)

    threading.Thread(target=watch, name="rmac-mj driver watchdog", daemon=True).start()


@contextlib.contextmanager
def ctrl_c_ignored_by_new_processes() -> Iterator[None]:
    """Processes started inside ignore Ctrl-C from their first instruction: an ignored signal stays
    ignored through exec, and Python then installs no KeyboardInterrupt of its own. A worker still
    importing when Ctrl-C reaches the process group would otherwise print a traceback; the driver's
    own handler is back as soon as they are started (it stops them, :func:`local_outcomes`)."""
    if threading.current_thread() is not threading.main_thread():
        yield  # signal handlers belong to the main thread; a caller's thread keeps Python's default
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


class Prerequisites:
    """Work the workers do before the items that need it: ``tasks`` maps a key to a picklable
    callable, run first, one per worker; ``needs(item)`` is the key an item waits for (None: none);
    the driver calls ``done(key)`` as each task finishes and ``poll()`` every :data:`POLL_SECONDS`
    while it waits. An item whose key is done runs before the earlier items still waiting."""

    def __init__(
        self,
        tasks: dict[Hashable, Callable[[], Any]],
        needs: Callable[[Any], Hashable | None],
        done: Callable[[Hashable], None] | None = None,
        poll: Callable[[], None] | None = None,
    ) -> None:
        self.tasks, self.needs = tasks, needs
        self.done = done or (lambda key: None)
        self.poll = poll or (lambda: None)


class _Gate:
    """The items in their order, handed out only once their prerequisite is done; those still
    waiting are held, without holding back the ready ones behind them."""

    def __init__(self, items: Iterator, before: Prerequisites) -> None:
        self.items, self.needs, self.tasks = items, before.needs, before.tasks
        self.held: collections.deque = collections.deque()
        self.done: set[Hashable] = set()

    def _ready(self, item: Any) -> bool:
        key = self.needs(item)
        return key in self.done or key not in self.tasks

    def next(self) -> Any | None:
        """The first item that may run now; None when none may (yet)."""
        for item in self.held:
            if self._ready(item):
                self.held.remove(item)
                return item
        for item in self.items:
            if self._ready(item):
                return item
            self.held.append(item)
        return None


def local_outcomes(
    items: Iterable,
    run: Callable,
    jobs: int,
    on_trial: Callable[..., None] | None = None,
    poll: Callable[[], None] | None = None,
    on_start: Callable[[Any], None] | None = None,
    prerequisites: Prerequisites | None = None,
) -> Iterator:
    """``run(item)`` of every item, in the order they finish; ``on_start(item)`` as each starts.

    With ``jobs == 1``, or a single item, they run in this process, one after another, as
    ``run(item, on_trial)``, and ``on_trial`` sees every trial (after the ``prerequisites``, here).
    Otherwise ``jobs`` worker processes run the prerequisites' tasks first, then the items, each as
    soon as its prerequisite is done, and the driver calls ``poll()`` every :data:`POLL_SECONDS`
    while it waits. Closing the generator (an interrupt) terminates the workers at once: only the
    items in flight are lost.
    """
    before = prerequisites or Prerequisites({}, lambda item: None)
    items = iter(items)
    first = list(itertools.islice(items, 1 if jobs == 1 else jobs + _AHEAD))
    if len(first) <= 1:
        for key, task in before.tasks.items():
            task()
            before.done(key)
        for item in itertools.chain(first, items):
            if on_start is not None:
                on_start(item)
            yield run(item, on_trial)
        return
    # "spawn": workers start clean (no inherited GL contexts or numba state); the numba cache (filled
    # by the driver's warm-up or the prerequisites) makes their start-up cheap.
    context = multiprocessing.get_context("spawn")
    with ctrl_c_ignored_by_new_processes():
        pool = context.Pool(
            processes=min(jobs, len(first)), initializer=start_worker, initargs=(os.getpid(),)
        )
    try:
        yield from _pooled(
            pool,
            _Gate(itertools.chain(first, items), before),
            run,
            jobs,
            poll,
            on_start,
            before,
        )
        pool.close()
    finally:
        pool.terminate()
        pool.join()


def _pooled(
    pool, gate: _Gate, run: Callable, jobs: int, poll, on_start, before: Prerequisites
) -> Iterator:
    """:func:`local_outcomes` on the workers of ``pool``: the prerequisites' tasks first, then the
    items the gate lets through, ``jobs`` + :data:`_AHEAD` in flight at most."""
    finished: queue.SimpleQueue = queue.SimpleQueue()

    def submit(task: Callable, args: tuple, key: Hashable) -> None:
        pool.apply_async(
            task,
            args,
            callback=lambda result: finished.put((key, True, result)),
            error_callback=lambda error: finished.put((key, False, error)),
        )

    for key, task in before.tasks.items():
        submit(task, (), key)
    in_flight, item_key = len(before.tasks), object()  # the key of an item's result
    while True:
        while in_flight < jobs + _AHEAD and (item := gate.next()) is not None:
            if on_start is not None:
                on_start(item)
            submit(run, (item,), item_key)
            in_flight += 1
        if not in_flight:
            break
        while True:
            try:
                key, ok, outcome = finished.get(timeout=POLL_SECONDS)
                break
            except queue.Empty:
                before.poll()
                if poll is not None:
                    poll()
        in_flight -= 1
        if not ok:
            raise outcome
        if key is item_key:
            yield outcome
        else:
            gate.done.add(key)
            before.done(key)


def connect_dask(address: str, timeout: float | None = None):
    """A ``distributed.Client`` of the scheduler at ``address``; :class:`BackendError` in one line
    when the address is not one or nothing answers within ``timeout`` seconds (default
    :data:`DASK_CONNECT_SECONDS`)."""
    try:
        from distributed import Client
        from distributed.comm import parse_address
    except ImportError as error:  # pragma: no cover - depends on the optional extra
        raise BackendError("--scheduler needs Dask: pip install 'rmac-mj[distributed]'") from error
    try:
        parse_address(address, strict=True)
    except ValueError:
        raise BackendError(
            f"--scheduler {address!r} is not a scheduler address (expected e.g. tcp://host:8786)"
        ) from None
    timeout = DASK_CONNECT_SECONDS if timeout is None else timeout
    _greeted(address, timeout)
    # A lost scheduler is reported once, in one line (dask_outcomes), not by the client's own
    # tracebacks of its reconnection attempts.
    logging.getLogger("distributed.client").setLevel(logging.CRITICAL)
    try:
        return Client(address, timeout=timeout)
    except ValueError as error:  # an unknown scheme ("foo://host:8786"), a malformed address
        raise BackendError(
            f"--scheduler {address!r} is not a scheduler address ({error}; e.g. tcp://host:8786)"
        ) from None
    except (OSError, TimeoutError) as error:
        raise BackendError(
            f"cannot reach the Dask scheduler at {address} ({error}); is "
            "`dask scheduler` running there?"
        ) from None


def _greeted(address: str, timeout: float) -> None:
    """Check that the peer at a ``tcp://`` ``address`` greets as a Dask scheduler does, before the
    client, which waits for a silent peer as long as it keeps the connection open and takes a
    garbage peer's first bytes as the size of a frame to allocate. A scheduler writes its handshake
    as soon as it accepts a connection: distributed's TCP frames, a byte count (a native uint64)
    first. :class:`BackendError` naming the address when nothing answers within ``timeout``
    seconds, or the first bytes are no such count."""
    from distributed.comm import parse_address, parse_host_port

    scheme, location = parse_address(address)
    if scheme != "tcp":  # tls greets only after its own handshake; others are not sockets
        return
    host, port = parse_host_port(location)
    header = b""
    try:
        with socket.create_connection((host, port), timeout=timeout) as connection:
            deadline = time.monotonic() + timeout
            while len(header) < 8:
                connection.settimeout(max(deadline - time.monotonic(), 1e-3))
                chunk = connection.recv(8 - len(header))
                if not chunk:
                    raise BackendError(
                        f"the peer at {address} closed the connection without a word: not a "
                        "Dask scheduler"
                    )
                header += chunk
    except TimeoutError:  # socket.timeout
        raise BackendError(
            f"the peer at {address} said nothing within {timeout:g} s (a Dask scheduler greets "
            "at once): is `dask scheduler` running there, or another server?"
        ) from None
    except OSError as error:
        raise BackendError(
            f"cannot reach the Dask scheduler at {address} ({error.strerror or error}); is "
            "`dask scheduler` running there?"
        ) from None
    (size,) = struct.unpack("Q", header)
    if not 0 < size <= _GREETING_BYTES:
        raise BackendError(
            f"the peer at {address} answered, but not as a Dask scheduler (its first frame "
            f"would hold {size} bytes)"
        )


def _started(items: Iterable, on_start: Callable[[Any], None] | None) -> Iterator:
    for item in items:
        if on_start is not None:
            on_start(item)
        yield item


def dask_outcomes(
    items: Iterable,
    run: Callable,
    client,
    window: int | None = None,
    on_start: Callable[[Any], None] | None = None,
) -> Iterator:
    """``run(item)`` of every item on the Dask cluster of ``client``, in the order they finish.

    At most ``window`` items (default: twice the cluster's worker threads, at least 2) are submitted
    at a time; closing the generator cancels those still pending. A lost scheduler ends it with a
    :class:`BackendError` (the results already yielded are the caller's to keep)."""
    from distributed import as_completed

    items = _started(items, on_start)
    try:
        if window is None:
            window = max(2, 2 * sum(client.nthreads().values()))
        futures = collections.deque(
            client.submit(run, item, pure=False) for item in itertools.islice(items, window)
        )
        running = as_completed(futures)
        try:
            for future in running:
                outcome = future.result()
                futures.remove(future)
                for item in itertools.islice(items, 1):
                    futures.append(client.submit(run, item, pure=False))
                    running.add(futures[-1])
                yield outcome
        finally:
            if client.status == "running":
                client.cancel(list(futures))
    except (OSError, TimeoutError, concurrent.futures.CancelledError) as error:
        # a dropped connection cancels every pending future ("scheduler-connection-lost")
        reason = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise BackendError(
            f"lost the Dask scheduler at {client.scheduler.address} ({reason})"
        ) from None

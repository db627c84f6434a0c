"""The near-optimal return of a run's task and each learner's exploration floor
(:func:`near_optimal`), what its summary and Fig. 2 are measured against; for several runs computed
beside their experiments, in a process of its own (:class:`NearOptimalService`)."""

from __future__ import annotations

import multiprocessing
import os
import threading
from collections.abc import Callable
from typing import Any

from rmac_mj.experiments import execution
from rmac_mj.experiments.protocol import Protocol
from rmac_mj.solvers import optimum

NearOptimal = tuple[float | None, dict[str, float | None]]

#: In the process that computes the near-optimal returns: where its messages go (to the driver).
_messages: Any = None


def _start_near_optimal(driver: int, messages) -> None:
    global _messages
    execution.start_worker(driver)
    _messages = messages


def _announce(message: str) -> None:
    _messages.put(message)


def near_optimal(protocol: Protocol, announce: Callable[[str], None] | None = None) -> NearOptimal:
    """The near-optimal return of the protocol's task and each learner's exploration floor (None
    where there is none): what its summary and Fig. 2 are measured against."""
    return (
        optimum.run_optimum(protocol, announce),
        {a: optimum.run_exploration_floor(protocol, a, announce) for a in protocol.algorithms},
    )


class NearOptimalService:
    """:func:`near_optimal` of several runs, computed beside their experiments.

    With ``background``, one process of its own computes them, in the runs' order, from the start:
    while the driver compiles the kernels and while the workers run the first experiments, not after
    the last one (a sweep's floors of one dynamic programme reuse its values in that process). Its
    messages reach ``log`` through the driver. Without, each is computed when asked for, here.
    """

    def __init__(
        self,
        protocols: list[Protocol | None],
        log: Callable[[str], None] | None,
        background: bool,
        compute: Callable[..., NearOptimal] = near_optimal,
    ):
        self.protocols, self.log, self.compute = protocols, log, compute
        self.pending: dict[int, Any] = {}
        self.pool = self.relay = None
        if not background or not any(p is not None for p in protocols):
            return
        context = multiprocessing.get_context("spawn")
        self.messages = context.Queue()
        self.pool = context.Pool(
            1, initializer=_start_near_optimal, initargs=(os.getpid(), self.messages)
        )
        for k, protocol in enumerate(protocols):
            if protocol is not None:
                self.pending[k] = self.pool.apply_async(compute, (protocol, _announce))
        self.pool.close()
        self.relay = threading.Thread(
            target=self._relay, name="rmac-mj near-optimal messages", daemon=True
        )
        self.relay.start()

    def _relay(self) -> None:
        while True:
            message = self.messages.get()
            if message is None:
                return
            if self.log is not None:
                self.log(message)

    def result(self, k: int) -> NearOptimal | None:
        """Run ``k``'s near-optimal return and floors (waiting for them), or None if it asked none."""
        protocol = self.protocols[k]
        if protocol is None:
            return None
        if k in self.pending:
            return self.pending[k].get()
        return self.compute(protocol, self.log)

    def close(self) -> None:
        """Let the process end; one still computing is stopped at once (what it has not finished
        is computed again next time)."""
        if self.pool is not None:
            if not all(result.ready() for result in self.pending.values()):
                self.pool.terminate()
            self.pool.join()
            self.messages.put(None)
            self.relay.join(timeout=5)
            self.pool = None

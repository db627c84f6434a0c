"""The wall time of a run over all its parts, the first and every resume (:class:`WallClock`),
kept in the result directory's ``wall_times.json``."""

from __future__ import annotations

import datetime
import time
from typing import Any

from rmac_mj.results.store import ResultStore


class WallClock:
    """The wall time of this part of a run, counted from ``started`` (the process's start: compilation,
    the near-optimal return and the figures included), kept in ``wall_times.json`` beside the earlier
    parts, so that a resumed run reports the total over all of them. It is written after every saved
    experiment; a killed part loses only the time since its last one."""

    def __init__(self, store: ResultStore, started: float, resume: bool):
        self.store = store
        self.started = started
        self.earlier: list[dict[str, Any]] = store.read_wall_times() if resume else []
        self.part = {
            "started": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "wall_s": 0.0,
            "experiments": 0,
        }

    def record(self, experiments: int = 0) -> None:
        self.part["wall_s"] = time.perf_counter() - self.started
        self.part["experiments"] += experiments
        self.store.write_wall_times([*self.earlier, self.part])

    @property
    def parts(self) -> list[float]:
        return [float(part.get("wall_s", 0.0)) for part in [*self.earlier, self.part]]

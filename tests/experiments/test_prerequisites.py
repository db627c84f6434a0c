"""Work that items need first (a learner's compile before its experiments) runs on the workers, and
each item starts as soon as its own prerequisite is done, not after all of them."""

from __future__ import annotations

import functools
import pathlib
import time

import pytest

from rmac_mj.experiments import execution

#: Seconds a slow prerequisite waits for what it waits for before it gives up (a failure).
PATIENCE = 60.0


def _slow(folder: str) -> None:
    """A prerequisite done only once both "fast" items have run: it cannot end first."""
    deadline = time.monotonic() + PATIENCE
    while len(list(pathlib.Path(folder).glob("fast-*"))) < 2:
        if time.monotonic() > deadline:
            raise TimeoutError("the fast items never ran while the slow prerequisite did")
        time.sleep(0.01)


def _fast() -> None:
    pass


def _run(item: tuple[str, int, str]) -> str:
    key, index, folder = item
    (pathlib.Path(folder) / f"{key}-{index}").touch()
    return f"{key}-{index}"


def _failing() -> None:
    raise RuntimeError("the compile failed")


@pytest.mark.slow
def test_each_item_starts_once_its_own_prerequisite_is_done(tmp_path):
    folder = str(tmp_path)
    events = []
    before = execution.Prerequisites(
        {"slow": functools.partial(_slow, folder), "fast": _fast},
        needs=lambda item: item[0],
        done=lambda key: events.append(f"{key} done"),
    )
    # experiment-major, the slow learner first, as a run lists them
    items = [(key, index, folder) for index in range(2) for key in ("slow", "fast")]
    for outcome in execution.local_outcomes(
        items,
        _run,
        jobs=2,
        on_start=lambda item: events.append(f"{item[0]}-{item[1]} starts"),
        prerequisites=before,
    ):
        events.append(f"{outcome} finished")
    # the fast items ran while the slow prerequisite still waited for them; the slow ones after it
    assert events.index("fast done") < events.index("fast-0 starts")
    assert events.index("fast-1 finished") < events.index("slow done")
    assert events.index("slow done") < events.index("slow-0 starts")
    assert sorted(e for e in events if e.endswith("finished")) == [
        "fast-0 finished",
        "fast-1 finished",
        "slow-0 finished",
        "slow-1 finished",
    ]


@pytest.mark.slow
def test_a_failed_prerequisite_stops_the_run(tmp_path):
    before = execution.Prerequisites({"a": _failing}, needs=lambda item: item[0])
    items = [("a", index, str(tmp_path)) for index in range(3)]
    with pytest.raises(RuntimeError, match="the compile failed"):
        list(execution.local_outcomes(items, _run, jobs=2, prerequisites=before))
    assert not list(tmp_path.iterdir())  # no item ran


def test_in_one_process_the_prerequisites_run_first(tmp_path):
    events = []

    def run(item, on_trial=None):
        events.append(f"{item[0]}-{item[1]}")
        return item

    before = execution.Prerequisites(
        {"a": lambda: events.append("a compiled")},
        needs=lambda item: item[0],
        done=lambda key: events.append(f"{key} done"),
    )
    list(execution.local_outcomes([("a", 0), ("b", 0)], run, jobs=1, prerequisites=before))
    assert events == ["a compiled", "a done", "a-0", "b-0"]

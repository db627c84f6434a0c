"""Every file a resume keeps holds what the run would have written: a snapshot or checkpoint whose
learned state the run's learner would refuse (another shape, another dtype, a key missing or
foreign) is not kept, but recomputed, and the results equal an undamaged run's."""

from __future__ import annotations

import json
import pathlib
import shutil

import numpy as np
import pytest

from rmac_mj.experiments import ExperimentSpec, Protocol, RunOptions, run_experiment, run_protocol
from rmac_mj.results import ResultStore

SNAPSHOT = "snapshots/s-ac/exp_001/trial_0002.npz"
TINY = dict(algorithms=("s-ac",), experiments=2, trials=4, snapshot_trials=(1, 2), evaluate_every=2)


def arrays_of(out: pathlib.Path) -> dict[str, dict[str, np.ndarray]]:
    """Every array of every .npz under ``out`` but the timings."""
    found = {}
    for path in sorted(out.rglob("*.npz")):
        with np.load(path, allow_pickle=False) as data:
            found[str(path.relative_to(out))] = {
                k: data[k] for k in data.files if k not in ("wall_time_s", "cpu_time_s")
            }
    return found


def _resave(path: pathlib.Path, **changes) -> None:
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    arrays.update(changes)
    np.savez(path, **{k: v for k, v in arrays.items() if v is not None})


def _entry(path: pathlib.Path, key: str) -> np.ndarray:
    with np.load(path, allow_pickle=False) as data:
        return data[key]


#: Damage to a snapshot's learned state -> what the message names.
LEARNER_STATE = {
    "critic of another shape": (
        lambda path: _resave(path, **{"agent/critic": np.zeros(7)}),
        "'critic' must have shape",
    ),
    "float32 critic": (
        lambda path: _resave(
            path, **{"agent/critic": _entry(path, "agent/critic").astype(np.float32)}
        ),
        "'critic' must hold float64, got dtype float32",
    ),
    "int32 step count": (
        lambda path: _resave(path, **{"agent/k": _entry(path, "agent/k").astype(np.int32)}),
        "'k' must hold int64",
    ),
    "actor missing": (lambda path: _resave(path, **{"agent/actor": None}), "lacks 'actor'"),
    "a foreign key": (
        lambda path: _resave(path, **{"agent/process.X": np.zeros((3, 3))}),
        "has 'process.X'",
    ),
    "tile index out of range": (
        lambda path: _resave(
            path, **{"agent/tiles": np.full_like(_entry(path, "agent/tiles"), -1)}
        ),
        "'tiles' must hold tile indices",
    ),
}


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> pathlib.Path:
    out = tmp_path_factory.mktemp("finished") / "run"
    run_protocol(Protocol(**TINY), out, RunOptions(jobs=1, progress=False, figures=False))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("damage", list(LEARNER_STATE))
def test_a_snapshot_the_learner_would_refuse_is_redone_equal(finished, tmp_path, damage):
    # A snapshot whose agent/critic was replaced by a finite array of another shape survived a
    # resume (rc 0, no message) and failed later in render.
    out = tmp_path / "run"
    shutil.copytree(finished, out)
    change, named = LEARNER_STATE[damage]
    change(out / SNAPSHOT)
    said = []
    run_protocol(
        Protocol(**TINY),
        out,
        RunOptions(jobs=1, resume=True, progress=False, figures=False, log=said.append),
    )
    redone = [line for line in said if "run again" in line]
    assert len(redone) == 1, said
    assert (
        redone[0].startswith(f"s-ac experiment 1 is run again: {SNAPSHOT}: ")
        and named in (redone[0])
    )
    assert "\n" not in redone[0]
    for name, arrays in arrays_of(finished).items():
        for key, value in arrays.items():
            np.testing.assert_array_equal(arrays_of(out)[name][key], value, err_msg=f"{name} {key}")
    assert arrays_of(out).keys() == arrays_of(finished).keys()
    summary = json.loads((out / "summary.json").read_text())["s-ac"]
    before = json.loads((finished / "summary.json").read_text())["s-ac"]
    assert summary["mean_return_per_trial"] == before["mean_return_per_trial"]


class Stop(Exception):
    """Stands for a kill between two trials."""


def _stopped(tmp_path, trial=3):
    protocol = Protocol(algorithms=("s-ac",), experiments=1, trials=6, snapshot_trials=(2, 5))
    spec = ExperimentSpec(protocol, "s-ac", 0, stream_to=str(tmp_path), checkpoint_seconds=0.0)

    def on_trial(algorithm, index, done, value, env_steps):
        if done == trial:
            raise Stop

    with pytest.raises(Stop):
        run_experiment(spec, on_trial=on_trial)
    return protocol, spec, ResultStore(tmp_path)


def _assert_same(a, b):
    for name in ("returns", "env_steps", "greedy_trials", "greedy_returns"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.snapshots.keys() == b.snapshots.keys()
    for trial in a.snapshots:
        assert a.snapshots[trial].keys() == b.snapshots[trial].keys()
        for key, value in a.snapshots[trial].items():
            assert value.tobytes() == b.snapshots[trial][key].tobytes(), (trial, key)


@pytest.mark.parametrize("damage", [*LEARNER_STATE, "kept snapshot missing"])
@pytest.mark.parametrize("where", ["checkpoint", "kept snapshot"])
def test_a_checkpoint_the_learner_would_refuse_starts_the_experiment_again(tmp_path, damage, where):
    protocol, spec, store = _stopped(tmp_path)
    whole = run_experiment(ExperimentSpec(protocol, "s-ac", 0))
    path = (
        store.checkpoint_path("s-ac", 0)
        if where == "checkpoint"
        else store.snapshot_path("s-ac", 0, 2)
    )
    if damage == "kept snapshot missing":
        store.snapshot_path("s-ac", 0, 2).unlink()
    else:
        LEARNER_STATE[damage][0](path)
    _assert_same(run_experiment(spec), whole)  # from trial 1: the same result


@pytest.mark.parametrize(
    "change",
    [
        {"curve/returns": np.array([np.nan, 1.0, 2.0])},
        {"curve/env_steps": np.array([5, 3, 9])},
        {"curve/greedy_trials": np.array([7])},
        {"env/mt19937_keys": np.zeros(3, dtype=np.uint32)},
        {"env/mt19937_gauss": None},
    ],
    ids=["NaN return", "steps decrease", "greedy trial not done", "short keys", "no gauss"],
)
def test_a_checkpoint_with_a_damaged_curve_or_environment_is_not_used(tmp_path, change):
    protocol, spec, store = _stopped(tmp_path)
    whole = run_experiment(ExperimentSpec(protocol, "s-ac", 0))
    _resave(store.checkpoint_path("s-ac", 0), **change)
    _assert_same(run_experiment(spec), whole)

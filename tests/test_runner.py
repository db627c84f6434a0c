"""The comparison runner end to end on a tiny protocol: files, determinism, interruption, resume."""

import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from rmac_mj.experiments import runner
from rmac_mj.experiments.episode import run_trial
from rmac_mj.experiments.snapshots import load_snapshot

TINY = dict(algorithms=("s-ac",), experiments=2, trials=4, snapshot_trials=(1, 2), evaluate_every=2)


def returns_of(out, protocol):
    return {a: runner.load_curves(pathlib.Path(out), protocol, a)[0] for a in protocol.algorithms}


def test_tiny_protocol_end_to_end(tmp_path):
    protocol = runner.Protocol(**TINY)
    summary = runner.run_protocol(protocol, tmp_path, jobs=1, progress=False,
                                  optimal=lambda p: -900.0)
    for name in ("config.json", "summary.json", "returns.csv", "fig2_learning_curves.png",
                 "fig2_learning_curves.pdf"):
        assert (tmp_path / name).is_file(), name
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    assert on_disk["paper_protocol"] is False and on_disk["optimal_return"] == -900.0
    row = on_disk["s-ac"]
    for key in ("experiments", "trials", "mean_return_per_trial", "ci95_low_per_trial",
                "ci95_high_per_trial", "final_return_mean", "final_return_ci95", "minutes_to_90pct",
                "mean_return_first_10min", "stuck_experiments", "greedy_return_per_eval"):
        assert key in row, key
    assert len(row["mean_return_per_trial"]) == 4 and len(row["greedy_return_per_eval"]) == 2
    assert row == summary["s-ac"]
    config = json.loads((tmp_path / "config.json").read_text())
    assert config["protocol"]["trials"] == 4 and "numpy" in config["provenance"]["packages"]
    snapshots = sorted(p.name for p in (tmp_path / "snapshots/s-ac/exp_001").iterdir())
    assert snapshots == ["trial_0001.npz", "trial_0002.npz", "trial_0004.npz"]
    with np.load(tmp_path / "curves/s-ac/exp_000.npz", allow_pickle=False) as data:
        assert data["returns"].shape == (4,) and list(data["greedy_trials"]) == [2, 4]
    lines = (tmp_path / "returns.csv").read_text().splitlines()
    assert lines[0] == "algorithm,experiment,trial,return" and len(lines) == 1 + 2 * 4


def test_serial_and_parallel_runs_are_identical(tmp_path):
    protocol = runner.Protocol(**TINY)
    runner.run_protocol(protocol, tmp_path / "serial", jobs=1, progress=False, figures=False)
    runner.run_protocol(protocol, tmp_path / "parallel", jobs=2, progress=False, figures=False)
    serial, parallel = returns_of(tmp_path / "serial", protocol), returns_of(tmp_path / "parallel", protocol)
    np.testing.assert_array_equal(serial["s-ac"], parallel["s-ac"])
    assert not np.array_equal(serial["s-ac"][0], serial["s-ac"][1])  # experiments are independent


def test_resume_with_a_changed_config_is_refused(tmp_path):
    runner.run_protocol(runner.Protocol(**TINY), tmp_path, jobs=1, progress=False, figures=False)
    with pytest.raises(runner.ResumeRefused, match="already holds a run"):
        runner.run_protocol(runner.Protocol(**TINY), tmp_path, jobs=1, progress=False)
    changed = runner.Protocol(**{**TINY, "trials": 5})
    with pytest.raises(runner.ResumeRefused, match="different config"):
        runner.run_protocol(changed, tmp_path, jobs=1, resume=True, progress=False)


def test_killed_run_resumed_equals_uninterrupted(tmp_path):
    args = ["--algorithms", "s-ac", "--experiments", "6", "--trials", "40", "--jobs", "1",
            "--no-optimal", "--no-progress"]
    command = [sys.executable, "-m", "rmac_mj.cli", "reproduce", *args]
    killed = tmp_path / "killed"
    process = subprocess.Popen([*command, "--out", str(killed)], stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    curves = killed / "curves" / "s-ac"
    deadline = time.time() + 120
    while time.time() < deadline and not (curves.is_dir() and any(curves.glob("exp_*.npz"))):
        time.sleep(0.005)
    process.send_signal(signal.SIGKILL)
    process.wait()
    done = sorted(curves.glob("exp_*.npz"))
    assert 1 <= len(done) < 6, "the kill should land mid-run"
    for path in done:  # whatever was renamed into place is complete
        np.load(path, allow_pickle=False)["returns"]
    assert not (killed / "summary.json").exists()
    resumed = subprocess.run([*command, "--out", str(killed), "--resume"], capture_output=True,
                             text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    whole = tmp_path / "whole"
    subprocess.run([*command, "--out", str(whole)], check=True, capture_output=True, timeout=300)
    protocol = runner.Protocol(algorithms=("s-ac",), experiments=6, trials=40)
    np.testing.assert_array_equal(returns_of(killed, protocol)["s-ac"],
                                  returns_of(whole, protocol)["s-ac"])
    assert not list(killed.rglob("*.tmp"))


def test_snapshot_round_trip_reproduces_the_policy(tmp_path):
    protocol = runner.Protocol(**{**TINY, "experiments": 1})
    outcome = runner.run_experiment(runner.ExperimentSpec(protocol, "s-ac", 0))
    runner.save_outcome(tmp_path, outcome)
    agent, meta = load_snapshot(runner.snapshot_path(tmp_path, "s-ac", 0, 4))
    assert meta["trial"] == 4 and meta["algorithm"] == "s-ac"
    env = runner.make_environment(protocol)
    # The greedy trial after trial 4, recorded during learning, is what the reloaded agent does.
    assert run_trial(env, agent, learn=False) == pytest.approx(outcome["greedy_returns"][-1], abs=1e-9)


def test_protocol_validation_names_the_parameter():
    for kwargs, name in [({"experiments": 0}, "experiments"), ({"trials": -1}, "trials"),
                         ({"algorithms": ("q-learning",)}, "unknown algorithm"),
                         ({"seed": -3}, "seed"), ({"evaluate_every": -1}, "evaluate_every"),
                         ({"task_kwargs": {"random": 1}}, "random")]:
        with pytest.raises(ValueError, match=name):
            runner.Protocol(**kwargs)
    assert runner.Protocol().is_paper_protocol
    assert not runner.Protocol(experiments=4).is_paper_protocol


def test_dask_scheduler_path_matches_local_run(tmp_path):
    distributed = pytest.importorskip("distributed")
    protocol = runner.Protocol(**TINY)
    runner.run_protocol(protocol, tmp_path / "local", jobs=1, progress=False, figures=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        runner.run_protocol(protocol, tmp_path / "dask", scheduler=cluster.scheduler_address,
                            progress=False, figures=False)
    np.testing.assert_array_equal(returns_of(tmp_path / "local", protocol)["s-ac"],
                                  returns_of(tmp_path / "dask", protocol)["s-ac"])


def test_ctrl_c_stops_workers_and_says_how_to_resume(tmp_path):
    out = tmp_path / "run"
    command = [sys.executable, "-m", "rmac_mj.cli", "reproduce", "--algorithms", "s-ac",
               "--experiments", "8", "--trials", "60", "--jobs", "2", "--no-optimal",
               "--no-progress", "--out", str(out)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True,  # its own process group, like a terminal's
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    curves = out / "curves" / "s-ac"
    deadline = time.time() + 120
    while time.time() < deadline and not (curves.is_dir() and any(curves.glob("exp_*.npz"))):
        time.sleep(0.005)
    os.killpg(process.pid, signal.SIGINT)  # Ctrl-C reaches the driver and its workers
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 130
    assert "run again with --resume" in stderr and "Traceback" not in stderr
    assert 1 <= len(list(curves.glob("exp_*.npz"))) < 8
    resumed = subprocess.run([*command, "--resume"], capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert len(list(curves.glob("exp_*.npz"))) == 8

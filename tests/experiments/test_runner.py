"""The comparison runner end to end on a tiny protocol: files, determinism, interruption, resume."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from stoppable_run import hooked_cli, wait_for  # tests/ is on sys.path

from rmac_mj.experiments import (
    ExperimentSpec,
    NearOptimalService,
    Progress,
    Protocol,
    RunOptions,
    TrialFeed,
    run_experiment,
    run_protocol,
    run_protocols,
)
from rmac_mj.experiments import progress as progress_module
from rmac_mj.results import ResultStore, ResumeRefused, load_snapshot
from rmac_mj.rollout import run_trial

TINY = dict(algorithms=("s-ac",), experiments=2, trials=4, snapshot_trials=(1, 2), evaluate_every=2)


def returns_of(out, protocol):
    return {
        a: ResultStore(out).load_curves(a, protocol.experiments).returns
        for a in protocol.algorithms
    }


@pytest.mark.slow
def test_tiny_protocol_end_to_end(tmp_path, monkeypatch):
    from rmac_mj.solvers import optimum

    monkeypatch.setattr(optimum, "run_optimum", lambda protocol, log=None: -900.0)
    monkeypatch.setattr(
        optimum, "run_exploration_floor", lambda protocol, algorithm, log=None: -950.0
    )
    protocol = Protocol(**TINY)
    summary = run_protocol(protocol, tmp_path, RunOptions(jobs=1, progress=False, references=True))
    for name in (
        "config.json",
        "summary.json",
        "returns.csv",
        "fig2_learning_curves.png",
        "fig2_learning_curves.pdf",
    ):
        assert (tmp_path / name).is_file(), name
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    assert on_disk["paper_protocol"] is False and on_disk["optimal_return"] == -900.0
    assert on_disk["exploration_floor"] == -950.0
    row = on_disk["s-ac"]
    for key in (
        "experiments",
        "trials",
        "mean_return_per_trial",
        "ci95_low_per_trial",
        "ci95_high_per_trial",
        "final_return_mean",
        "final_return_ci95",
        "minutes_to_90pct",
        "mean_return_first_10min",
        "stuck_experiments",
        "greedy_return_per_eval",
    ):
        assert key in row, key
    assert len(row["mean_return_per_trial"]) == 4 and len(row["greedy_return_per_eval"]) == 2
    assert row == summary["s-ac"]
    config = json.loads((tmp_path / "config.json").read_text())
    assert config["protocol"]["trials"] == 4 and "numpy" in config["provenance"]["packages"]
    assert config["protocol"]["snapshot_trials"] == [
        1,
        2,
        4,
    ]  # the final trial's snapshot is listed
    snapshots = sorted(p.name for p in (tmp_path / "snapshots/s-ac/exp_001").iterdir())
    assert snapshots == ["trial_0001.npz", "trial_0002.npz", "trial_0004.npz"]
    with np.load(tmp_path / "curves/s-ac/exp_000.npz", allow_pickle=False) as data:
        assert data["returns"].shape == (4,) and list(data["greedy_trials"]) == [2, 4]
    lines = (tmp_path / "returns.csv").read_text().splitlines()
    assert lines[0] == "algorithm,experiment,trial,return,env_steps" and len(lines) == 1 + 2 * 4


@pytest.mark.slow
def test_serial_and_parallel_runs_are_identical(tmp_path):
    from learners import quick_config

    from rmac_mj.agents import sb3

    # a deep-RL baseline too, when installed: its torch and numpy streams are the learner's own
    algorithms = ("s-ac", "sb3-sac") if sb3.available() else ("s-ac",)
    protocol = Protocol(
        **{**TINY, "algorithms": algorithms}, agent_configs={"sb3-sac": quick_config("sb3-sac")}
    )
    run_protocol(protocol, tmp_path / "serial", RunOptions(jobs=1, progress=False, figures=False))
    run_protocol(protocol, tmp_path / "parallel", RunOptions(jobs=2, progress=False, figures=False))
    serial, parallel = (
        returns_of(tmp_path / "serial", protocol),
        returns_of(tmp_path / "parallel", protocol),
    )
    for algorithm in algorithms:
        np.testing.assert_array_equal(serial[algorithm], parallel[algorithm])
        assert not np.array_equal(
            serial[algorithm][0], serial[algorithm][1]
        )  # independent experiments


def test_a_learners_experiments_do_not_depend_on_the_other_learners_of_the_run(tmp_path):
    # experiment i of every learner sees the same task seeds, whoever shares the run: so runs of
    # some learners each, on one protocol, read together are one run of all of them (docs/panel.md)
    together = Protocol(**{**TINY, "algorithms": ("mlac", "s-ac")})
    alone = Protocol(**TINY)
    run_protocol(together, tmp_path / "together", RunOptions(jobs=1, progress=False, figures=False))
    run_protocol(alone, tmp_path / "alone", RunOptions(jobs=1, progress=False, figures=False))
    np.testing.assert_array_equal(
        returns_of(tmp_path / "together", together)["s-ac"],
        returns_of(tmp_path / "alone", alone)["s-ac"],
    )


@pytest.mark.slow
def test_resume_with_a_changed_config_is_refused(tmp_path):
    run_protocol(Protocol(**TINY), tmp_path, RunOptions(jobs=1, progress=False, figures=False))
    with pytest.raises(ResumeRefused, match="already holds this run, finished"):
        run_protocol(Protocol(**TINY), tmp_path, RunOptions(jobs=1, progress=False))
    ResultStore(tmp_path).curve_path("s-ac", 1).unlink()
    with pytest.raises(ResumeRefused, match="already holds this run, unfinished; pass --resume"):
        run_protocol(Protocol(**TINY), tmp_path, RunOptions(jobs=1, progress=False))
    changed = Protocol(**{**TINY, "trials": 5})
    with pytest.raises(ResumeRefused, match="different config") as refusal:
        run_protocol(changed, tmp_path, RunOptions(jobs=1, resume=True, progress=False))
    assert "trials: 4 in the directory, 5 now" in str(refusal.value)  # names what differs
    assert "snapshot_trials: [1, 2, 4] in the directory, [1, 2, 5] now" in str(refusal.value)


@pytest.mark.slow
def test_a_resume_adds_experiments_and_never_drops_any(tmp_path):
    grown, fresh = tmp_path / "grown", tmp_path / "fresh"
    small, large = Protocol(**TINY), Protocol(**{**TINY, "experiments": 3})
    run_protocol(small, grown, RunOptions(jobs=1, progress=False, figures=False))
    first = ResultStore(grown).curve_path("s-ac", 0).stat().st_mtime_ns
    with pytest.raises(ResumeRefused, match="already holds another run"):  # growing needs --resume
        run_protocol(large, grown, RunOptions(jobs=1, progress=False, figures=False))
    summary = run_protocol(
        large, grown, RunOptions(jobs=1, resume=True, progress=False, figures=False)
    )
    assert ResultStore(grown).curve_path("s-ac", 0).stat().st_mtime_ns == first  # kept, not re-run
    config = json.loads((grown / "config.json").read_text())
    assert config["protocol"]["experiments"] == 3 and config["experiments_grown_from"] == [2]
    whole = run_protocol(large, fresh, RunOptions(jobs=1, progress=False, figures=False))
    np.testing.assert_array_equal(
        returns_of(grown, large)["s-ac"], returns_of(fresh, large)["s-ac"]
    )
    assert summary["s-ac"]["final_return_mean"] == whole["s-ac"]["final_return_mean"]
    with pytest.raises(ResumeRefused, match="never drops any"):
        run_protocol(small, grown, RunOptions(jobs=1, resume=True, progress=False))
    with pytest.raises(
        ResumeRefused, match="trials: 4 in the directory, 5 now"
    ):  # and nothing else
        run_protocol(
            Protocol(**{**TINY, "experiments": 4, "trials": 5}),
            grown,
            RunOptions(jobs=1, resume=True, progress=False),
        )


@pytest.mark.slow
def test_killed_run_resumed_equals_uninterrupted(tmp_path):
    args = [
        "reproduce",
        "--algorithms",
        "s-ac",
        "--experiments",
        "4",
        "--trials",
        "10",
        "--jobs",
        "1",
        "--no-optimal",
        "--no-progress",
    ]
    killed, marker = tmp_path / "killed", tmp_path / "saved-one"
    process = subprocess.Popen(
        [*hooked_cli(marker), *args, "--out", str(killed)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    wait_for(marker, process)
    process.send_signal(signal.SIGKILL)
    process.wait()
    curves = killed / "curves" / "s-ac"
    done = sorted(curves.glob("exp_*.npz"))
    assert len(done) == 1
    np.load(done[0], allow_pickle=False)["returns"]  # what was renamed into place is complete
    assert not (killed / "summary.json").exists()
    from rmac_mj.cli import main  # the rest in this process: the same commands, no start-up

    assert main([*args, "--out", str(killed), "--resume"]) == 0
    whole = tmp_path / "whole"
    assert main([*args, "--out", str(whole)]) == 0
    protocol = Protocol(algorithms=("s-ac",), experiments=4, trials=10)
    np.testing.assert_array_equal(
        returns_of(killed, protocol)["s-ac"], returns_of(whole, protocol)["s-ac"]
    )
    assert not list(killed.rglob("*.tmp"))


def test_snapshot_round_trip_reproduces_the_policy(tmp_path):
    protocol = Protocol(**{**TINY, "experiments": 1})
    outcome = run_experiment(ExperimentSpec(protocol, "s-ac", 0))
    ResultStore(tmp_path).save(outcome)
    agent, meta = load_snapshot(ResultStore(tmp_path).snapshot_path("s-ac", 0, 4))
    assert meta["trial"] == 4 and meta["algorithm"] == "s-ac"
    env = protocol.make_environment()
    # The greedy trial after trial 4, recorded during learning, is what the reloaded agent does.
    assert run_trial(env, agent, learn=False) == pytest.approx(outcome.greedy_returns[-1], abs=1e-9)


def test_protocol_validation_names_the_parameter():
    for kwargs, name in [
        ({"experiments": 0}, "experiments"),
        ({"trials": -1}, "trials"),
        ({"algorithms": ("q-learning",)}, "unknown algorithm"),
        ({"seed": -3}, "seed"),
        ({"evaluate_every": -1}, "evaluate_every"),
        ({"task_kwargs": {"random": 1}}, "random"),
    ]:
        with pytest.raises(ValueError, match=name):
            Protocol(**kwargs)
    assert Protocol().is_paper_protocol
    assert not Protocol(experiments=4).is_paper_protocol


@pytest.mark.slow
def test_dask_scheduler_path_matches_local_run(tmp_path):
    distributed = pytest.importorskip("distributed")
    protocol = Protocol(**TINY)
    run_protocol(protocol, tmp_path / "local", RunOptions(jobs=1, progress=False, figures=False))
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        run_protocol(
            protocol,
            tmp_path / "dask",
            RunOptions(scheduler=cluster.scheduler_address, progress=False, figures=False),
        )
    np.testing.assert_array_equal(
        returns_of(tmp_path / "local", protocol)["s-ac"],
        returns_of(tmp_path / "dask", protocol)["s-ac"],
    )


@pytest.mark.slow
def test_ctrl_c_stops_workers_and_says_how_to_resume(tmp_path):
    out, marker = tmp_path / "run", tmp_path / "saved-one"
    args = [
        "reproduce",
        "--algorithms",
        "s-ac",
        "--experiments",
        "4",
        "--trials",
        "5",
        "--jobs",
        "2",
        "--no-optimal",
        "--no-progress",
        "--out",
        str(out),
    ]
    process = subprocess.Popen(
        [*hooked_cli(marker), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, like a terminal's
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    wait_for(marker, process)
    os.killpg(process.pid, signal.SIGINT)  # Ctrl-C reaches the driver and its workers
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 130
    # the command that finishes it as it was started (without the reference)
    assert f"finish it with: rmac-mj reproduce --resume --out {out} --no-optimal\n" in stderr
    assert "Traceback" not in stderr
    curves = out / "curves" / "s-ac"
    assert len(list(curves.glob("exp_*.npz"))) == 1
    # The command it prints finishes the run: the settings come from the directory.
    from rmac_mj.cli import main

    assert main(["reproduce", "--resume", "--out", str(out), "--no-optimal", "--no-progress"]) == 0
    assert len(list(curves.glob("exp_*.npz"))) == 4


@pytest.mark.slow
@pytest.mark.baselines  # every learner, the deep-RL baselines included
def test_every_result_file_is_readable_by_others(tmp_path):
    """Under umask 022 every file a run writes (curves, snapshots of every learner, summaries,
    figures) is group- and other-readable, as a cluster's shared result directory needs."""
    import stat

    from learners import quick_config

    from rmac_mj.agents import ALGORITHMS

    protocol = Protocol(
        algorithms=ALGORITHMS,
        experiments=1,
        trials=2,
        snapshot_trials=(1,),
        agent_configs={a: quick_config(a) for a in ALGORITHMS},
    )
    old = os.umask(0o022)
    try:
        run_protocol(protocol, tmp_path, RunOptions(jobs=1, progress=False))
    finally:
        os.umask(old)
    files = [p for p in tmp_path.rglob("*") if p.is_file()]
    for algorithm in ALGORITHMS:
        assert any(f"snapshots/{algorithm}/" in str(p) for p in files), algorithm
    for path in files:
        assert stat.S_IMODE(path.stat().st_mode) == 0o644, (path, oct(path.stat().st_mode))


@pytest.mark.slow
def test_a_non_terminal_run_prints_plain_progress_lines(tmp_path):
    """Under nohup or Slurm (output not a terminal): periodic plain lines, no carriage returns or
    escape codes; the mean return of the last trials per learner is in them."""
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "rmac_mj",
            "reproduce",
            "--algorithms",
            "s-ac",
            "--experiments",
            "2",
            "--trials",
            "3",
            "--jobs",
            "1",
            "--no-optimal",
            "--out",
            str(tmp_path / "run"),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    for text in (result.stdout, result.stderr):
        assert "\x1b" not in text and "\r" not in text
    assert "6/6 trials (2/2 experiments)" in result.stderr
    assert "s-ac 6/6 trials, last 6 trials -" in result.stderr
    assert "wall time" in result.stdout


def test_trials_are_streamed_to_disk_as_they_happen(tmp_path):
    protocol = Protocol(**{**TINY, "experiments": 1})
    log = ResultStore(tmp_path).progress_path("s-ac", 0)
    seen = []

    def on_trial(algorithm, index, trial, value, env_steps):  # the log holds this trial
        seen.append(log.read_text().splitlines()[-1].split(",")[0])

    streamed = run_experiment(
        ExperimentSpec(protocol, "s-ac", 0, stream_to=str(tmp_path)), on_trial=on_trial
    )
    assert seen == ["1", "2", "3", "4"]
    lines = log.read_text().splitlines()
    assert lines[0] == "trial,return,greedy_return,env_steps"
    np.testing.assert_array_equal(
        [float(line.split(",")[1]) for line in lines[1:]], streamed.returns
    )
    assert [line.split(",")[2] != "" for line in lines[1:]] == [False, True, False, True]
    np.testing.assert_array_equal(
        [int(line.split(",")[3]) for line in lines[1:]], streamed.env_steps
    )
    silent = run_experiment(ExperimentSpec(protocol, "s-ac", 0))
    np.testing.assert_array_equal(silent.returns, streamed.returns)  # streaming changes nothing


def test_the_driver_reads_only_complete_lines_of_the_live_logs(tmp_path):
    protocol = Protocol(**TINY)
    display = Progress([protocol], [{}], enabled=False)
    feed = TrialFeed(display)
    log = ResultStore(tmp_path).progress_path("s-ac", 1)
    feed.watch((0, "s-ac", 1), log)
    log.parent.mkdir(parents=True)
    log.write_text("trial,return,greedy_return\n1,-4000.5,\n2,-39")  # trial 2 half written
    feed.poll()
    assert display.progressed == {"all": 1, "s-ac": 1} and list(display.recent["s-ac"]) == [-4000.5]
    with open(log, "a") as handle:
        handle.write("00.25,-3800.0\n")
    feed.poll()
    assert display.progressed["s-ac"] == 2 and list(display.recent["s-ac"]) == [-4000.5, -3900.25]
    display.experiment((0, "s-ac", 1))  # the rest of the experiment, once it is saved
    assert display.progressed["s-ac"] == 4 and display.done["s-ac"] == 1


def test_progress_bars_show_the_mean_of_the_last_trials():
    import io

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    stream = Terminal()
    protocol = Protocol(**TINY)
    display = Progress([protocol], [{}], enabled=True, stream=stream)
    for trial, value in enumerate([-3000.0, -2000.0, -1000.0], start=1):
        display.trial((0, "s-ac", 0), trial, value)
    display.close()
    assert "last 3 trials -2000" in stream.getvalue() and not display.plain


def test_the_trial_rate_counts_only_the_experiments_own_time(monkeypatch):
    import io

    clock = [100.0]
    monkeypatch.setattr(progress_module.time, "monotonic", lambda: clock[0])
    stream = io.StringIO()
    protocol = Protocol(**TINY)  # 2 experiments of 4 trials
    display = Progress([protocol], [{}], enabled=True, stream=stream, interval=1e9)
    clock[0] += 2.0
    display.experiment((0, "s-ac", 0))
    display.experiment((0, "s-ac", 1))  # 8 trials in 2 s
    clock[0] += 60.0  # then a minute of something else (the reference, the figures)
    display.close()
    assert (
        stream.getvalue()
        .splitlines()[-1]
        .startswith("[1 min 02 s] 8/8 trials (2/2 experiments), 4 trials/s")
    )


def _fake_near_optimal(protocol, announce):
    announce(f"computing the floors of {', '.join(protocol.algorithms)}")
    return -748.0, {a: -870.0 for a in protocol.algorithms}


@pytest.mark.slow
def test_the_near_optimal_returns_are_computed_in_a_process_of_their_own():
    messages = []
    service = NearOptimalService(
        [Protocol(**TINY), None], messages.append, background=True, compute=_fake_near_optimal
    )
    try:
        assert service.result(0) == (-748.0, {"s-ac": -870.0}) and service.result(1) is None
    finally:
        service.close()
    assert messages == ["computing the floors of s-ac"]  # relayed to the driver's log


def test_compiling_says_what_and_how_long_while_it_lasts(monkeypatch):
    import numba

    from rmac_mj.experiments import admission

    lines = []

    def warm_up(protocol, algorithms):  # a kernel compiled afresh, then until a tick is seen
        numba.njit(lambda x: x + 1)(1)
        deadline = time.monotonic() + 60
        while not any("so far" in line for line in lines) and time.monotonic() < deadline:
            time.sleep(0.01)

    monkeypatch.setattr(admission, "warm_up", warm_up)
    admission.warm_up_announced([Protocol(**TINY)], lines.append, interval=0.01)
    assert lines[0].startswith("compiling the kernels of s-ac, first run only (cached in ")
    assert any(
        line.startswith("compiling the kernels of s-ac: ") and line.endswith(" s so far")
        for line in lines[1:-1]
    )
    assert lines[-1].startswith("kernels compiled in ")


@pytest.mark.slow
def test_a_cold_run_compiles_in_its_workers_each_learner_before_its_experiments(
    tmp_path, monkeypatch, capfd
):
    from rmac_mj import _cache

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))  # the workers' cold cache
    monkeypatch.setattr(_cache, "started_with_empty_cache", lambda: True)
    runs = [(Protocol(**TINY), tmp_path / "a"), (Protocol(**TINY, task="balance"), tmp_path / "b")]
    lines = []
    run_protocols(runs, RunOptions(jobs=2, progress=False, figures=False, log=lines.append))
    cached = {path.name.split(".")[0] for path in (tmp_path / "numba").rglob("*.nbi")}
    assert {"standard_ac", "tile_coding"} <= cached  # compiled by the workers, into the cache
    lines = [line for line in lines if not line.endswith(" s so far")]  # a slow machine's
    assert lines[0].startswith("compiling the kernels of s-ac, first run only (cached in ")
    assert lines[1].startswith("kernels of s-ac compiled in ")  # one task's: its experiments start
    assert lines[2].startswith("kernels compiled in ")
    assert "numba is compiling" not in capfd.readouterr().err  # the driver says it, once
    for protocol, out in runs:  # the same results as one process gives
        run_protocol(
            protocol, tmp_path / "alone", RunOptions(jobs=1, progress=False, figures=False)
        )
        np.testing.assert_array_equal(
            returns_of(out, protocol)["s-ac"], returns_of(tmp_path / "alone", protocol)["s-ac"]
        )
        shutil.rmtree(tmp_path / "alone")


@pytest.mark.slow
def test_a_resumed_run_reports_the_wall_time_of_all_its_parts(tmp_path):
    protocol = Protocol(**TINY)
    first = run_protocol(protocol, tmp_path, RunOptions(jobs=1, progress=False, figures=False))
    assert first["wall_time_parts_s"] == [first["wall_time_s"]] and first["wall_time_s"] > 0
    ResultStore(tmp_path).curve_path("s-ac", 1).unlink()  # as if killed before the last experiment
    resumed = run_protocol(
        protocol, tmp_path, RunOptions(jobs=1, resume=True, progress=False, figures=False)
    )
    parts = resumed["wall_time_parts_s"]
    assert len(parts) == 2 and parts[0] == pytest.approx(first["wall_time_s"], abs=0.5)
    assert resumed["wall_time_s"] == pytest.approx(sum(parts))
    stored = json.loads(ResultStore(tmp_path).wall_times_path.read_text())["parts"]
    assert [part["experiments"] for part in stored] == [2, 1]


def test_one_progress_display_counts_the_learners_trials_over_several_runs(tmp_path):
    first = Protocol(**TINY)
    second = Protocol(**{**TINY, "experiments": 3, "trials": 5})
    display = Progress([first, second], [{}, {"s-ac": 1}], enabled=False)  # one already finished
    assert display.total == {"all": 2 * 4 + 3 * 5, "s-ac": 23}
    assert display.progressed["s-ac"] == 5 and display.done == {"all": 1, "s-ac": 1}
    display.trial((1, "s-ac", 0), 2, -100.0)
    display.experiment((1, "s-ac", 0), returns=np.arange(5.0))  # 3 more trials of that run's 5
    assert list(display.recent["s-ac"]) == [-100.0, 2.0, 3.0, 4.0]
    display.experiment((1, "s-ac", 1))
    assert display.progressed["s-ac"] == 15 and display.runs_done == 1
    display.experiment((0, "s-ac", 0))
    display.experiment((0, "s-ac", 1))
    assert display.progressed == {"all": 23, "s-ac": 23} and display.runs_done == 2


def test_workers_start_with_ctrl_c_ignored_and_the_driver_keeps_its_handler():
    """A worker still importing when Ctrl-C reaches the process group prints no traceback: processes
    the pool starts ignore SIGINT from their first instruction (kept through exec); the driver's
    own handler is back at once."""
    import signal
    import subprocess
    import sys

    from rmac_mj.experiments import execution

    before = signal.getsignal(signal.SIGINT)
    probe = [
        sys.executable,
        "-c",
        "import signal; print(signal.getsignal(signal.SIGINT) == signal.SIG_IGN)",
    ]
    with execution.ctrl_c_ignored_by_new_processes():
        started = subprocess.run(probe, capture_output=True, text=True, check=True)
    assert started.stdout.strip() == "True"
    assert signal.getsignal(signal.SIGINT) is before
    # Outside, a new process inherits the driver's own disposition: ignored only where the driver's
    # was (a job started in the background of a shell without job control).
    outside = subprocess.run(probe, capture_output=True, text=True, check=True)
    assert outside.stdout.strip() == str(before is signal.SIG_IGN)

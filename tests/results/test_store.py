"""A result directory that never lies (issue 20): locked while a run writes, refused when no config
describes it, every damaged file found and its experiment redone equal to an undamaged run, the
summary written last, and the run bounded before it starts."""

from __future__ import annotations

import errno
import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from stoppable_run import hooked_cli, wait_for  # tests/ is on sys.path

from rmac_mj.cli import main
from rmac_mj.experiments import Protocol, RunOptions, admission, experiment_seeds, run_protocol
from rmac_mj.results import ResultStore, files
from rmac_mj.results.snapshots import FORMAT

TINY = dict(algorithms=("s-ac",), experiments=2, trials=4, snapshot_trials=(1, 2), evaluate_every=2)
CLI = [
    "--algorithms",
    "s-ac",
    "--experiments",
    "2",
    "--trials",
    "4",
    "--evaluate-every",
    "2",
    "--jobs",
    "1",
    "--no-optimal",
    "--no-progress",
]


def arrays_of(out: pathlib.Path) -> dict[str, dict[str, np.ndarray]]:
    """Every array of every .npz under ``out`` (wall and CPU times left out: they are timings)."""
    found = {}
    for path in sorted(out.rglob("*.npz")):
        with np.load(path, allow_pickle=False) as data:
            found[str(path.relative_to(out))] = {
                k: data[k] for k in data.files if k not in ("wall_time_s", "cpu_time_s")
            }
    return found


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> pathlib.Path:
    """One finished tiny run, copied by the tests that damage it."""
    out = tmp_path_factory.mktemp("finished") / "run"
    run_protocol(Protocol(**TINY), out, RunOptions(jobs=1, progress=False, figures=False))
    return out


# -- the lock ----------------------------------------------------------------------------------------


def _lock_holder(out: pathlib.Path) -> subprocess.Popen:
    """Another process that holds ``out``'s lock (as a run writing there does) until killed."""
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time\nfrom rmac_mj.results.store import ResultStore\n"
            "lock = ResultStore(sys.argv[1]).lock()\nlock.acquire()\nprint('held', flush=True)\n"
            "time.sleep(120)",
            str(out),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert holder.stdout.readline().strip() == "held"
    return holder


@pytest.mark.slow
def test_a_directory_in_use_is_refused_naming_the_run_that_holds_it(tmp_path, capsys):
    out = tmp_path / "run"
    holder = _lock_holder(out)
    try:
        assert main(["reproduce", *CLI, "--out", str(out)]) == 2
        error = capsys.readouterr().err
        assert f"is in use by another run (pid {holder.pid} on " in error
        assert len(error.strip().splitlines()) == 1 and not (out / "config.json").exists()
    finally:
        holder.kill()
        holder.wait()
    assert main(["reproduce", *CLI, "--out", str(out)]) == 0  # the lock died with its holder


def test_a_finished_run_leaves_no_lock_file(finished):
    assert not (finished / ".lock").exists() and (finished / "summary.json").is_file()


def test_a_lock_file_removed_by_its_last_holder_is_not_shared(tmp_path):
    from rmac_mj.results import integrity

    first, second = integrity.DirectoryLock(tmp_path), integrity.DirectoryLock(tmp_path)
    first.acquire()
    with pytest.raises(integrity.DirectoryBusy):
        second.acquire()
    stale = open(tmp_path / ".lock", "a+")  # opened before the holder let go, as a racing process
    first.release()
    assert not (tmp_path / ".lock").exists()
    second.acquire()  # takes the new file, not the one removed
    assert json.loads((tmp_path / ".lock").read_text())["pid"] == os.getpid()
    import fcntl

    fcntl.flock(stale, fcntl.LOCK_EX | fcntl.LOCK_NB)  # the removed file's lock guards nothing now
    assert integrity._same_file(stale, tmp_path / ".lock") is False
    stale.close()
    with pytest.raises(integrity.DirectoryBusy):
        first.acquire()
    second.release()


@pytest.mark.slow
def test_a_sweep_directory_in_use_is_refused_before_anything_is_written(tmp_path, capsys):
    """Issue 20 asks the lock of a sweep too: a second sweep on one --out is refused in one line
    naming the holder, and writes neither the index nor a configuration's directory."""
    grid = tmp_path / "grid.toml"
    grid.write_text(
        '[protocol]\nalgorithms = ["s-ac"]\nexperiments = 1\ntrials = 1\n'
        '[grid]\n"s-ac.alpha_a" = [0.01, 0.02]\n'
    )
    out = tmp_path / "sweep"
    holder = _lock_holder(out)
    try:
        assert (
            main(
                [
                    "sweep",
                    str(grid),
                    "--jobs",
                    "1",
                    "--no-optimal",
                    "--no-progress",
                    "--out",
                    str(out),
                ]
            )
            == 2
        )
        errors = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
        assert len(errors) == 1 and f"is in use by another run (pid {holder.pid} on " in errors[0]
        assert not (out / "sweep.json").exists() and not any(p.is_dir() for p in out.iterdir())
    finally:
        holder.kill()
        holder.wait()


@pytest.mark.slow
def test_two_runs_started_at_once_on_one_directory_never_mix(tmp_path):
    """The issue's reproduction: two reproduce runs with different seeds on one --out at once. One
    runs; the other is refused naming it (or, if the first already finished, naming the setting
    that differs); the directory holds one run's files only."""
    out = tmp_path / "mix"
    command = [sys.executable, "-m", "rmac_mj.cli", "reproduce", *CLI, "--out", str(out)]
    first = subprocess.Popen([*command, "--seed", "1"], stderr=subprocess.PIPE, text=True)
    second = subprocess.Popen([*command, "--seed", "0"], stderr=subprocess.PIPE, text=True)
    results = [(p.wait(timeout=300), p.stderr.read()) for p in (first, second)]
    assert sorted(code for code, _ in results) == [0, 2], results
    refusal = next(text for code, text in results if code == 2)
    assert "in use by another run" in refusal or "already holds another run (seed:" in refusal
    seed = json.loads((out / "config.json").read_text())["protocol"]["seed"]
    assert json.loads((out / "summary.json").read_text())["protocol"]["seed"] == seed
    for index in (0, 1):  # every curve is of that run
        with np.load(out / f"curves/s-ac/exp_{index:03d}.npz") as curve:
            assert int(curve["task_seed"]) == experiment_seeds(seed, index)[1]


# -- what no config describes ------------------------------------------------------------------------


def test_results_without_a_config_are_refused(finished, tmp_path, capsys):
    out = tmp_path / "run"
    shutil.copytree(finished, out)
    (out / "config.json").unlink()
    assert main(["reproduce", *CLI[:4], "--trials", "8", *CLI[6:], "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert "holds curves and snapshots but no config.json" in error
    assert not (out / "config.json").exists()


@pytest.mark.parametrize(
    "text, named",
    [
        ('{"protocol": {"experiments": 2', "config.json is damaged (not JSON"),
        ("[1, 2]", "config.json is damaged (not a run's config"),
        ('{"code": {}}', "config.json is damaged (not a run's config"),
    ],
)
def test_a_damaged_config_is_one_line_not_a_traceback(finished, tmp_path, capsys, text, named):
    out = tmp_path / "run"
    shutil.copytree(finished, out)
    (out / "config.json").write_text(text)
    assert main(["reproduce", *CLI, "--out", str(out), "--resume"]) == 2
    error = capsys.readouterr().err
    assert named in error and len(error.strip().splitlines()) == 1


# -- damaged files: detected, redone, equal to an undamaged run --------------------------------------


def _resave(path: pathlib.Path, **changes) -> None:
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    arrays.update(changes)
    np.savez(path, **{k: v for k, v in arrays.items() if v is not None})


DAMAGE = {
    "truncated curve": lambda out: (out / "curves/s-ac/exp_001.npz").write_bytes(
        (out / "curves/s-ac/exp_001.npz").read_bytes()[:200]
    ),
    "empty curve": lambda out: (out / "curves/s-ac/exp_001.npz").write_bytes(b""),
    "wrong trial count": lambda out: _resave(out / "curves/s-ac/exp_001.npz", returns=np.zeros(3)),
    "missing key": lambda out: _resave(out / "curves/s-ac/exp_001.npz", greedy_returns=None),
    "object array": lambda out: np.savez(
        out / "curves/s-ac/exp_001.npz", returns=np.array([[1.0], [1.0, 2.0]], dtype=object)
    ),
    "NaN in a curve": lambda out: _resave(
        out / "curves/s-ac/exp_001.npz", returns=np.array([np.nan, 1.0, 2.0, 3.0])
    ),
    "truncated snapshot": lambda out: (out / "snapshots/s-ac/exp_001/trial_0002.npz").write_bytes(
        (out / "snapshots/s-ac/exp_001/trial_0002.npz").read_bytes()[:300]
    ),
    "missing snapshot": lambda out: (out / "snapshots/s-ac/exp_001/trial_0004.npz").unlink(),
}


@pytest.mark.slow
@pytest.mark.parametrize("damage", list(DAMAGE))
def test_a_damaged_file_is_found_and_its_experiment_redone_equal(finished, tmp_path, damage):
    out = tmp_path / "run"
    shutil.copytree(finished, out)
    DAMAGE[damage](out)
    said = []
    summary = run_protocol(
        Protocol(**TINY),
        out,
        RunOptions(jobs=1, resume=True, progress=False, figures=False, log=said.append),
    )
    redone = [line for line in said if "run again" in line]  # (a first run also says it compiles)
    assert len(redone) == 1 and redone[0].startswith("s-ac experiment 1 is run again: "), said
    assert arrays_of(out).keys() == arrays_of(finished).keys()
    for name, arrays in arrays_of(finished).items():
        for key, value in arrays.items():
            np.testing.assert_array_equal(arrays_of(out)[name][key], value, err_msg=f"{name} {key}")
    assert (
        summary["s-ac"]["mean_return_per_trial"]
        == json.loads((finished / "summary.json").read_text())["s-ac"]["mean_return_per_trial"]
    )


def test_a_failure_while_summarising_leaves_no_summary_to_trust(finished, tmp_path, monkeypatch):
    """The summary is written last and removed first: a run that fails while summarising has none
    (it counts as unfinished), and a resume writes it."""
    out = tmp_path / "run"
    shutil.copytree(finished, out)
    from rmac_mj.figures import plots

    def broken(*args, **kwargs):
        raise RuntimeError("the figure failed")

    monkeypatch.setattr(plots, "plot_learning_curves", broken)
    with pytest.raises(RuntimeError, match="the figure failed"):
        run_protocol(Protocol(**TINY), out, RunOptions(jobs=1, resume=True, progress=False))
    assert not (out / "summary.json").exists()
    monkeypatch.undo()
    run_protocol(
        Protocol(**TINY), out, RunOptions(jobs=1, resume=True, progress=False, figures=False)
    )
    assert (out / "summary.json").exists()


def test_a_non_finite_summary_value_is_written_as_null(tmp_path):
    store = ResultStore(tmp_path)
    store.write_summary({"s-ac": {"final_return_mean": float("nan"), "ci": [float("inf"), 1.0]}})
    assert json.loads(store.summary_path.read_text()) == {
        "s-ac": {"final_return_mean": None, "ci": [None, 1.0]}
    }


# -- bounded before it starts ------------------------------------------------------------------------


def test_learners_that_cannot_fit_in_memory_are_refused_before_anything_is_allocated(
    tmp_path, monkeypatch, capsys
):
    from rmac_mj.agents import agent_class

    monkeypatch.setattr(
        agent_class("s-ac"),
        "memory_estimate",
        classmethod(lambda cls, config, state_space, action_space: 10**15),
        raising=False,
    )

    def allocate(*args, **kwargs):
        raise AssertionError("a learner was built")

    monkeypatch.setattr(admission, "make_agent", allocate)
    out = tmp_path / "run"
    assert main(["reproduce", *CLI, "--jobs", "2", "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert "s-ac needs about 1000000.0 GB per experiment; 2 workers and the driver need" in error
    assert len(error.strip().splitlines()) == 1 and not (out / "config.json").exists()


def test_a_memory_no_machine_holds_is_refused_from_its_estimate(tmp_path, capsys):
    """The issue's case: the learner's own estimate (no monkeypatching), one line, in seconds."""
    out = tmp_path / "run"
    assert (
        main(
            [
                "reproduce",
                "--algorithms",
                "rmac",
                "--set",
                "rmac.critic.capacity=1000000000",
                "--no-optimal",
                "--no-progress",
                "--out",
                str(out),
            ]
        )
        == 2
    )
    error = capsys.readouterr().err
    assert 'rmac with {"critic": {"capacity": 1000000000}} needs about' in error
    assert "more than this machine's" in error and not (out / "config.json").exists()


def test_the_resolved_hyperparameters_of_every_learner_are_in_the_config(tmp_path):
    protocol = Protocol(algorithms=("rmac",), experiments=1, trials=1)
    run_protocol(protocol, tmp_path, RunOptions(jobs=1, progress=False, figures=False))
    agents = json.loads((tmp_path / "config.json").read_text())["agents"]
    assert agents["rmac"]["critic"]["weights"] == [1.0, 0.1]  # None in the config: the task's


@pytest.mark.slow
def test_sigterm_is_answered_within_a_second_on_a_huge_plan(tmp_path):
    """As many experiments planned as a protocol may have: nothing is O(planned), so the interrupt
    is answered at once and the bookkeeping (what was saved) counts what finished."""
    from rmac_mj.constraints import EXPERIMENTS

    config = tmp_path / "huge.toml"
    config.write_text(
        f'[protocol]\nalgorithms = ["s-ac"]\nexperiments = {EXPERIMENTS.value}\ntrials = 1\n'
    )
    marker, out = tmp_path / "saved-one", tmp_path / "run"
    process = subprocess.Popen(
        [
            *hooked_cli(marker),
            "reproduce",
            "--config",
            str(config),
            "--jobs",
            "1",
            "--no-optimal",
            "--no-progress",
            "--out",
            str(out),
        ],
        stderr=subprocess.PIPE,
        text=True,
    )
    wait_for(marker, process)
    sent = time.monotonic()
    process.send_signal(signal.SIGTERM)
    answer = process.stderr.readline()
    while answer and "interrupted" not in answer:
        answer = process.stderr.readline()
    answered = time.monotonic() - sent  # the answer printed (the interpreter then tears down)
    assert process.wait(timeout=30) == 130
    assert "1 finished experiment is saved" in answer and answered < 1.0, (answer, answered)


@pytest.mark.slow
def test_a_sweep_says_its_size_first_and_makes_directories_as_experiments_start(tmp_path):
    sweep = tmp_path / "grid.toml"
    values = ", ".join(str(0.001 * (k + 1)) for k in range(100))
    sweep.write_text(
        f'[protocol]\nalgorithms = ["s-ac"]\nexperiments = 1\ntrials = 1\n'
        f'[grid]\n"s-ac.alpha_a" = [{values}]\n'
    )
    marker, out = tmp_path / "saved-one", tmp_path / "sweep"
    process = subprocess.Popen(
        [
            *hooked_cli(marker),
            "sweep",
            str(sweep),
            "--jobs",
            "1",
            "--no-optimal",
            "--no-progress",
            "--out",
            str(out),
        ],
        stderr=subprocess.PIPE,
        text=True,
    )
    wait_for(marker, process)
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=30)
    assert stderr.splitlines()[0].endswith(
        "100 configurations x 1 experiments = 100 experiments of "
        "1 trials; checking every configuration"
    )
    made = [p for p in out.iterdir() if p.is_dir()]
    assert 1 <= len(made) <= 2, made  # the started configurations only, not 100
    assert stderr.rstrip().endswith(
        f"finish the sweep with: rmac-mj sweep {sweep} --resume --out {out} --no-optimal"
    )  # as it was started


def _children(pid: int) -> list[int]:
    found = []
    for stat in pathlib.Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def _alive(pid: int) -> bool:
    try:
        state = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.slow
@pytest.mark.skipif(not pathlib.Path("/proc/self/stat").exists(), reason="reads /proc")
def test_workers_stop_when_the_driver_is_killed(tmp_path):
    out = tmp_path / "run"
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "rmac_mj.cli",
            "reproduce",
            "--algorithms",
            "s-ac",
            "--experiments",
            "4",
            "--trials",
            "100000",
            "--jobs",
            "2",
            "--no-optimal",
            "--no-progress",
            "--out",
            str(out),
        ],
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.time() + 240
        while len(list((out / "progress").rglob("*.csv"))) < 2:  # both workers are in experiments
            assert process.poll() is None and time.time() < deadline
            time.sleep(0.1)
        workers = [pid for pid in _children(process.pid) if _alive(pid)]
        assert len(workers) >= 2
    finally:
        process.send_signal(signal.SIGKILL)
        process.wait()
    deadline = time.time() + 10
    while any(_alive(pid) for pid in workers) and time.time() < deadline:
        time.sleep(0.1)
    assert not any(_alive(pid) for pid in workers)


# -- one line, not a traceback -----------------------------------------------------------------------


def test_a_full_disk_is_one_line(tmp_path, monkeypatch, capsys):
    def full(path, write):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(files, "write_atomic", full)
    assert main(["reproduce", *CLI, "--out", str(tmp_path / "run")]) == 1
    error = capsys.readouterr().err
    assert "cannot write" in error and "No space left on device" in error
    assert (
        "Traceback" not in error
        and len([line for line in error.splitlines() if line.startswith("rmac-mj: error")]) == 1
    )


@pytest.mark.slow
@pytest.mark.parametrize(
    "address, named",
    [
        ("not-an-address", "is not a scheduler address"),
        ("tcp://127.0.0.1:1", "cannot reach the Dask scheduler at tcp://127.0.0.1:1"),
    ],
)
def test_a_bad_or_unreachable_scheduler_is_one_line_and_writes_nothing(
    tmp_path, monkeypatch, capsys, address, named
):
    pytest.importorskip("distributed")
    from rmac_mj.experiments import execution

    monkeypatch.setattr(execution, "DASK_CONNECT_SECONDS", 2.0)
    out = tmp_path / "run"
    started = time.monotonic()
    assert (
        main(
            [
                "reproduce",
                *CLI[:-4],
                "--no-optimal",
                "--no-progress",
                "--scheduler",
                address,
                "--out",
                str(out),
            ]
        )
        == 2
    )
    error = capsys.readouterr().err
    assert named in error and len(error.strip().splitlines()) == 1
    assert not (out / "config.json").exists() and time.monotonic() - started < 20


@pytest.mark.slow
def test_a_scheduler_lost_mid_run_is_one_line_naming_what_is_saved(tmp_path, monkeypatch, capsys):
    """The scheduler goes away once the first experiment is saved: one line naming what is saved
    and how to finish, the saved experiments whole, and a resume without it completes the run."""
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
    )
    save = ResultStore.save

    def save_then_lose_the_scheduler(store, result):
        save(store, result)
        cluster.close()

    monkeypatch.setattr(ResultStore, "save", save_then_lose_the_scheduler)
    out = tmp_path / "run"
    try:
        assert (
            main(
                [
                    "reproduce",
                    *CLI[:-4],
                    "--experiments",
                    "4",
                    "--no-optimal",
                    "--no-progress",
                    "--scheduler",
                    cluster.scheduler_address,
                    "--out",
                    str(out),
                ]
            )
            == 2
        )
    finally:
        cluster.close()
    monkeypatch.undo()
    error = capsys.readouterr().err
    saved = sorted((out / "curves" / "s-ac").glob("exp_*.npz"))
    assert len(error.strip().splitlines()) == 1 and "Traceback" not in error
    assert "lost the Dask scheduler at" in error
    assert (
        f"{len(saved)} finished experiment{'s' * (len(saved) != 1)} saved in {out}: finish "
        f"with rmac-mj reproduce --resume --out {out} --no-optimal (with --scheduler or --jobs)"
    ) in error
    assert 1 <= len(saved) < 4 and not (out / "summary.json").exists()
    assert (
        main(
            [
                "reproduce",
                "--resume",
                "--out",
                str(out),
                "--jobs",
                "1",
                "--no-optimal",
                "--no-progress",
            ]
        )
        == 0
    )
    assert len(list((out / "curves" / "s-ac").glob("exp_*.npz"))) == 4


def test_a_hyperparameter_the_task_cannot_take_is_one_line_before_anything_runs(tmp_path, capsys):
    out = tmp_path / "run"
    assert (
        main(
            [
                "reproduce",
                "--algorithms",
                "rmac",
                "--experiments",
                "1",
                "--trials",
                "1",
                "--set",
                "rmac.critic.weights=[1]",
                "--no-optimal",
                "--out",
                str(out),
            ]
        )
        == 2
    )
    error = capsys.readouterr().err
    assert "rmac on dc_pendulum/swingup: " in error and "critic.weights" in error
    assert len(error.strip().splitlines()) == 1 and not (out / "config.json").exists()


def test_long_computations_say_they_are_alive(monkeypatch):
    from rmac_mj import tasks
    from rmac_mj.solvers import dynamic_programming as optimal
    from rmac_mj.solvers import problem

    monkeypatch.setattr(problem, "PROGRESS_SECONDS", 0.0)
    said = []
    optimal.solve(
        tasks.load("dc_pendulum", "swingup", task_kwargs={"time_limit": 0.3}),
        optimal.OptimalConfig(
            n_phi=24, n_phi_dot=15, n_actions=3, lookahead_actions=3, check_convergence=False
        ),
        announce=said.append,
    )
    assert any("simulated" in line and "transitions" in line for line in said)
    assert any("backup 10/10" in line for line in said)


def _row(mean: float) -> dict:
    return {
        "experiments": 1,
        "final_return_mean": mean,
        "final_return_ci95": [mean, mean],
        "minutes_to_90pct": None,
        "final_return_per_experiment": [mean],
        "mean_return_per_trial": [mean],
        "ci95_low_per_trial": [mean],
        "ci95_high_per_trial": [mean],
    }


def test_a_directory_written_before_format_3_is_read_under_todays_learner_keys(tmp_path):
    # Before format 3, MPC was keyed "mpc" and S-AC with Dyna planning "recommended": read
    # under today's keys, neither is labelled with the other's name.
    protocol = {"algorithms": ["mpc", "recommended"], "experiments": 1, "agent_configs": {}}
    (tmp_path / "config.json").write_text(
        json.dumps({"protocol": protocol, "agents": {"mpc": {}, "recommended": {"lookahead": 5}}})
    )
    summary = {"protocol": protocol, "mpc": _row(-1.0), "recommended": _row(-2.0)}
    (tmp_path / "summary.json").write_text(json.dumps(summary))
    for stored, value in (("mpc", -1.0), ("recommended", -2.0)):
        (tmp_path / "curves" / stored).mkdir(parents=True)
        (tmp_path / "snapshots" / stored / "exp_000").mkdir(parents=True)
        np.savez(
            tmp_path / "curves" / stored / "exp_000.npz",
            returns=np.array([value]),
            greedy_trials=np.zeros(0, dtype=int),
            greedy_returns=np.zeros(0),
            wall_time_s=1.0,
            cpu_time_s=1.0,
            task_seed=0,
            demonstration_returns=np.zeros(0),
        )
    store = ResultStore(tmp_path)
    assert store.read_protocol()["algorithms"] == ["recommended", "s-ac-dyna"]
    assert store.read_config()["agents"] == {"recommended": {}, "s-ac-dyna": {"lookahead": 5}}
    assert store.load_curves("recommended").returns.tolist() == [[-1.0]]
    assert store.load_curves("s-ac-dyna").returns.tolist() == [[-2.0]]
    assert store.finished("s-ac-dyna") == {0} and store.snapshot_algorithms() == [
        "recommended",
        "s-ac-dyna",
    ]
    read = store.read_summary()
    assert (read["recommended"], read["s-ac-dyna"]) == (_row(-1.0), _row(-2.0))
    # A directory written today says its format, and its keys are today's.
    today = ResultStore(tmp_path / "today")
    today.write_config({"protocol": {"algorithms": ["recommended"]}})
    assert json.loads(today.config_path.read_text())["format"] == FORMAT
    assert today.curve_path("recommended", 0).parent.name == "recommended"

"""A file is data: opening a snapshot (policy, render, load_snapshot, --prior) or resuming a result
directory never imports or calls the code it names unless the user names it again (--env) or
trusts it (--trust-env); every code-running case here asserts that its marker file does not exist.
A run is one environment: a run on a file of the user's records the file's resolved path and
digest, and a resume, policy or render from anywhere uses that file or refuses, naming both."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import pathlib
import shutil
import textwrap

import numpy as np
import pytest

from rmac_mj.agents import ActionSpace, StateSpace, make_agent
from rmac_mj.cli import main
from rmac_mj.errors import EXIT_BAD_INPUT, UserInputError
from rmac_mj.experiments import Protocol
from rmac_mj.results import load_snapshot, save_snapshot, snapshot_environment

FAST = ["--algorithms", "s-ac", "--trials", "2", "--jobs", "1", "--no-optimal", "--no-progress"]

ENVS = textwrap.dedent(
    """
    import dm_env
    import numpy as np
    from dm_env import specs

    REWARD = {reward}

    class Line(dm_env.Environment):
        def __init__(self, seed=None):
            self.rng, self.t = np.random.default_rng(seed), 0
        def control_timestep(self):
            return 0.1
        def observation_spec(self):
            return {{"x": specs.BoundedArray((2,), float, [-1, -1], [1, 1])}}
        def action_spec(self):
            return specs.BoundedArray((1,), float, -1, 1)
        def reset(self):
            self.t = 0
            return dm_env.restart({{"x": self.rng.uniform(-1, 1, 2)}})
        def step(self, action):
            self.t += 1
            last = dm_env.truncation if self.t >= 4 else dm_env.transition
            return last(REWARD, {{"x": self.rng.uniform(-1, 1, 2)}})

    def make(seed=None):
        return Line(seed)
    """
)


def run(*args) -> tuple[int, list[str]]:
    """``rmac-mj ARGS`` in this process: its exit status and its stderr's lines."""
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main([str(a) for a in args])
    return code, [line for line in err.getvalue().splitlines() if line.strip()]


# -- snapshots that name code ------------------------------------------------------------------------


def _snapshot(path: pathlib.Path, environment: dict) -> pathlib.Path:
    """A snapshot of a fresh S-AC whose meta names ``environment`` (as a run on it would)."""
    spaces = StateSpace([-1.0, -1.0], [1.0, 1.0], [False, False]), ActionSpace([-1.0], [1.0])
    agent = make_agent("s-ac", *spaces, config={"backend": "numpy"}, seed=0)
    return save_snapshot(path, agent, *spaces, environment=environment, trial=1, experiment=0)


@pytest.fixture
def hostile(tmp_path, monkeypatch):
    """Snapshots naming code that would leave a marker: (snapshots by name, the marker)."""
    marker = tmp_path / "MARKER"
    (tmp_path / "pwn.py").write_text(f"open({str(marker)!r}, 'w').close()\ndef make(): pass\n")
    monkeypatch.syspath_prepend(str(tmp_path))  # pwn importable as a module too
    snapshots = {
        name: _snapshot(tmp_path / f"{name}.npz", environment)
        for name, environment in {
            "os_system": {"env": "os:system", "kwargs": {"command": f"touch {marker}"}},
            "getoutput": {"env": "subprocess:getoutput", "kwargs": {"cmd": f"touch {marker}"}},
            "module_file": {"env": f"{tmp_path / 'pwn.py'}:make"},
            "module": {"env": "pwn:make"},
            "gymnasium_module": {"env": "gymnasium:pwn:Env-v0"},
        }.items()
    }
    return snapshots, marker


@pytest.mark.parametrize(
    "name", ["os_system", "getoutput", "module_file", "module", "gymnasium_module"]
)
def test_opening_a_snapshot_runs_nothing_it_names(hostile, tmp_path, name):
    snapshots, marker = hostile
    path = snapshots[name]
    agent, meta = load_snapshot(path)  # the learner: from the package's own registry
    with pytest.raises(UserInputError, match="code of yours: opening a snapshot runs none of it"):
        snapshot_environment(agent, meta)
    for command in (["policy", path], ["render", path, "--out", tmp_path / "v.gif"]):
        code, lines = run(*command)
        assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
        assert f"--env {meta['environment']['env']} (or --trust-env" in lines[0]
    assert not marker.exists()


def test_a_result_directory_of_such_snapshots_is_rendered_only_when_trusted(hostile, tmp_path):
    snapshots, marker = hostile
    out = tmp_path / "run" / "snapshots" / "s-ac" / "exp_000"
    out.mkdir(parents=True)
    shutil.copy(snapshots["os_system"], out / "trial_0001.npz")
    code, lines = run("render", "--progression", tmp_path / "run", "--out", tmp_path / "v.gif")
    assert code == EXIT_BAD_INPUT and "code of yours" in lines[-1]
    assert not marker.exists()


def test_a_snapshot_given_as_prior_knowledge_runs_nothing(hostile, tmp_path):
    snapshots, marker = hostile
    code, lines = run(
        "reproduce", "--prior", snapshots["os_system"], "--algorithms", "rmac",
        "--experiments", "1", "--trials", "1", "--no-optimal", "--out", tmp_path / "out",
    )  # fmt: skip
    assert code == EXIT_BAD_INPUT and "a demonstration holds exactly the keys" in lines[-1]
    assert not marker.exists()


# -- result directories that name code ---------------------------------------------------------------


def test_a_copied_directory_naming_code_is_resumed_only_when_named(tmp_path):
    marker = tmp_path / "MARKER"
    out = tmp_path / "copied"
    out.mkdir()
    protocol = Protocol(algorithms=("s-ac",), experiments=1, trials=2).as_dict()
    protocol.update(
        env="os:system", domain=None, task=None, task_kwargs={"command": f"touch {marker}"}
    )
    (out / "config.json").write_text(json.dumps({"protocol": protocol, "code": {}}))
    code, lines = run("reproduce", "--resume", "--out", out, "--no-optimal", "--no-progress")
    assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
    assert "ran on env 'os:system', code of yours" in lines[0]
    assert "Add --env os:system (or --trust-env)" in lines[0]
    code, lines = run("reproduce", *FAST, "--experiments", "1", "--out", out)  # not resumed
    assert code == EXIT_BAD_INPUT and "already holds another run" in lines[-1], lines
    assert not marker.exists()


# -- a run is one environment ------------------------------------------------------------------------


@pytest.fixture
def two_folders(tmp_path, monkeypatch):
    """A run of ``--env envs.py:make`` made in folder A (reward -0.25 per step), and a folder B
    with another envs.py (reward 100); the working directory is B."""
    a, b = tmp_path / "A", tmp_path / "B"
    for folder, reward in ((a, -0.25), (b, 100.0)):
        folder.mkdir()
        (folder / "envs.py").write_text(ENVS.format(reward=reward))
    monkeypatch.chdir(a)
    code, lines = run("reproduce", "--env", "envs.py:make", *FAST, "--experiments", "1")
    assert code == 0, lines
    monkeypatch.chdir(b)
    shutil.copytree(a / "results" / "reproduce", b / "run")
    return a, b


def _returns(out: pathlib.Path) -> set[float]:
    with open(out / "returns.csv") as handle:
        return {float(row["return"]) for row in csv.DictReader(handle)}


def test_a_resume_from_another_folder_uses_the_runs_file_or_refuses(two_folders):
    a, b = two_folders
    config = json.loads((b / "run" / "config.json").read_text())
    assert config["protocol"]["env"] == f"{a / 'envs.py'}:make"  # resolved, not "envs.py:make"
    digest = config["environment_origin"]["sha256"]
    assert config["environment_origin"] == {"file": str(a / "envs.py"), "sha256": digest}
    _, meta = load_snapshot(b / "run" / "snapshots" / "s-ac" / "exp_000" / "trial_0002.npz")
    assert meta["environment_origin"] == config["environment_origin"]
    grow = ["reproduce", "--resume", "--experiments", "2", "--out", b / "run", *FAST[4:]]
    code, lines = run(*grow)  # unnamed: refused
    assert code == EXIT_BAD_INPUT and "code of yours" in lines[-1], lines
    code, lines = run(*grow, "--env", "envs.py:make")  # B's file: refused naming both
    assert code == EXIT_BAD_INPUT, lines
    assert f"ran on env '{a / 'envs.py'}:make', not '{b / 'envs.py'}:make'" in lines[-1]
    code, lines = run(*grow, "--trust-env")  # A's file, as recorded
    assert code == 0, lines
    assert _returns(b / "run") == {-1.0}  # 4 steps of -0.25 in both experiments, never 400
    (a / "envs.py").write_text(ENVS.format(reward=-0.5))  # the run's file changed
    code, lines = run(*grow[:3], "3", *grow[4:], "--trust-env")
    assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
    assert "as it was then, not as it is now (file " in lines[0] and "sha256" in lines[0]


def test_policy_from_another_folder_draws_where_the_snapshot_learned_or_says_so(two_folders):
    a, b = two_folders
    snapshot = b / "run" / "snapshots" / "s-ac" / "exp_000" / "trial_0002.npz"
    common = [snapshot, "--no-trajectory", "--resolution", "5", "--out", b / "map"]
    code, lines = run("policy", *common)
    assert code == EXIT_BAD_INPUT and "code of yours" in lines[-1], lines
    assert run("policy", *common, "--trust-env")[0] == 0  # A's file
    code, lines = run("policy", *common, "--env", "envs.py:make")  # B's: said, naming both
    assert (
        code == 0
        and f"learned on {a / 'envs.py'}:make; drawn on {b / 'envs.py'}:make" in (lines[0])
    )
    os.utime(a / "envs.py")  # touched, not changed: the same bytes
    assert run("policy", *common, "--trust-env")[0] == 0
    (a / "envs.py").write_text(ENVS.format(reward=-0.5))
    code, lines = run("policy", *common, "--trust-env")
    assert code == EXIT_BAD_INPUT and "is not what the snapshot learned on (file" in lines[-1]
    code, lines = run("policy", *common, "--env", f"{a / 'envs.py'}:make")  # named: drawn, said
    assert code == 0 and "has changed since the snapshot learned on it" in lines[0], lines


def test_a_registry_environment_is_rebuilt_from_a_snapshot_of_its_version():
    pytest.importorskip("gymnasium")
    environment = {"env": "gymnasium:Pendulum-v1", "learner_state": {"action_cost": [0.001]}}
    spaces = StateSpace([-np.pi, -8.0], [np.pi, 8.0], [True, False]), ActionSpace([-2.0], [2.0])
    agent = make_agent("s-ac", *spaces, config={"backend": "numpy"}, seed=0)
    meta = {"environment": environment}
    assert snapshot_environment(agent, meta).name == "gymnasium:Pendulum-v1"  # unnamed: built
    meta["environment_origin"] = {"package": "gymnasium", "version": "0.0.1"}
    with pytest.raises(UserInputError, match=r"gymnasium 0.0.1 then, gymnasium \S+ now"):
        snapshot_environment(agent, meta)
    heard = []
    env = snapshot_environment(agent, meta, env="gymnasium:Pendulum-v1", log=heard.append)
    assert env.name == "gymnasium:Pendulum-v1" and "has changed" in heard[0]


def test_a_file_changed_during_a_run_is_refused_where_an_experiment_is_built(tmp_path):
    (tmp_path / "envs.py").write_text(ENVS.format(reward=1.0))
    protocol = Protocol(env=f"{tmp_path / 'envs.py'}:make", algorithms=("s-ac",), trials=1)
    assert protocol.make_environment(0) is not None
    (tmp_path / "envs.py").write_text(ENVS.format(reward=2.0))
    with pytest.raises(UserInputError, match="changed during the run"):
        protocol.make_environment(1)

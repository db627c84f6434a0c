"""The one rule at the command's boundary (rmac_mj.cli.main): a bad input is one line and exit status
2, an outside environment's failure one line and exit status 3, never a traceback on stderr; result
files damaged after a run, and snapshots that are not snapshots, are named in that line."""

from __future__ import annotations

import contextlib
import io
import json
import os
import pathlib
import shutil
import textwrap
import zipfile

import numpy as np
import pytest

from rmac_mj.cli import build_parser, main
from rmac_mj.errors import EXIT_BAD_INPUT, EXIT_ENVIRONMENT

FACTORIES = textwrap.dedent(
    '''
    import sys
    import dm_env
    import numpy as np
    from dm_env import specs

    class Plain(dm_env.Environment):
        """Runs well until its seeded instance has taken 60 steps (the probes and the first trial
        before the experiments use seed 0), then loses power."""
        def __init__(self, seed):
            self.seed, self.t, self.taken = seed, 0, 0
        def control_timestep(self):
            return 0.05
        def observation_spec(self):
            return {"x": specs.BoundedArray((2,), float, [-1, -1], [1, 1])}
        def action_spec(self):
            return specs.BoundedArray((1,), float, -1, 1)
        def reset(self):
            self.t = 0
            return dm_env.restart({"x": np.zeros(2)})
        def step(self, action):
            self.t += 1
            self.taken += 1
            if self.seed not in (0, None) and self.taken > 60:
                raise RuntimeError("the robot lost power")
            if self.t >= 20:
                return dm_env.truncation(0.0, {"x": np.zeros(2)})
            return dm_env.transition(0.0, {"x": np.zeros(2)})

    def fails_later(seed=None):
        return Plain(seed)
    def exits():
        sys.exit(0)

    class Rewarding(Plain):
        reward = 0.0
        def step(self, action):
            return super().step(action)._replace(reward=self.reward)
    def huge_reward():
        env = Rewarding(0); env.reward = 1e308; return env
    def string_reward():
        env = Rewarding(0); env.reward = "1.0"; return env
    class Wide(Plain):
        def observation_spec(self):
            return {"x": specs.BoundedArray((1000,), float, -np.ones(1000), np.ones(1000))}
        def reset(self):
            return super().reset()._replace(observation={"x": np.zeros(1000)})
    def wide():
        return Wide(0)
    '''
)


def run(*args) -> tuple[int, list[str]]:
    """``rmac-mj ARGS`` in this process: its exit status and stderr's non-blank lines, less the
    progress lines of a first compile (they say the command is working, not what went wrong)."""
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in args])
        except SystemExit as exit:  # argparse's own errors
            code = exit.code
    lines = err.getvalue().splitlines()
    return code, [
        x for x in lines if x.strip() and not x.startswith("rmac-mj: compiling the kernels")
    ]


@pytest.fixture
def factories(tmp_path, monkeypatch):
    monkeypatch.setenv("RMAC_MJ_CACHE_DIR", str(tmp_path / "cache"))  # where a log goes
    path = tmp_path / "user_envs.py"
    path.write_text(FACTORIES)
    return path


@pytest.fixture
def finished(finished_run) -> pathlib.Path:
    """The finished tiny run (tests/cli/conftest.py), copied by the tests that damage it."""
    return finished_run.out


@pytest.fixture
def resume(finished_run) -> list[str]:
    """The finished run's command as a resume, less the directory."""
    return [*finished_run.command, "--resume", "--out"]


def _copy(finished, tmp_path) -> pathlib.Path:
    out = tmp_path / "run"
    shutil.copytree(finished, out)
    return out


# -- outside environments ----------------------------------------------------------------------------


def test_a_failure_mid_run_names_experiment_and_trial_and_keeps_the_traceback(factories, tmp_path):
    out = tmp_path / "out"
    code, lines = run(
        "reproduce", "--env", f"{factories}:fails_later", "--algorithms", "s-ac",
        "--experiments", "1", "--trials", "6", "--jobs", "1", "--no-optimal", "--no-progress",
        "--out", out,
    )  # fmt: skip
    assert code == EXIT_ENVIRONMENT and len(lines) == 1, lines
    assert "environment failure: env" in lines[0]
    assert "its step raised RuntimeError: the robot lost power (at user_envs.py:" in lines[0]
    assert "; s-ac experiment 0, trial 4" in lines[0]
    assert lines[0].endswith(f"(traceback in {out / 'error.log'})")
    assert 'raise RuntimeError("the robot lost power")' in (out / "error.log").read_text()


@pytest.mark.parametrize(
    "factory, options, code, message",
    [
        ("huge_reward", [], EXIT_ENVIRONMENT, "its rewards are beyond what a learner can take"),
        ("string_reward", [], EXIT_ENVIRONMENT, "gave the reward '1.0', not a number (a str)"),
        (
            "fails_later",
            ["--control-timestep", "1e-300"],
            EXIT_BAD_INPUT,
            "argument --control-timestep: expected a finite number >= 1e-06, got '1e-300'",
        ),
        (
            "wide",
            ["--learner-state", '{"keys": ["x"]}'],
            EXIT_BAD_INPUT,
            "e+897 GB per experiment",  # a tiling of 1000 dimensions, beyond a float's range
        ),
    ],
)
def test_an_environments_absurd_numbers_are_named_with_the_culprits_exit_status(
    factories, tmp_path, factory, options, code, message
):
    status, lines = run(
        "reproduce", "--env", f"{factories}:{factory}", *options, "--algorithms", "s-ac",
        "--experiments", "1", "--trials", "2", "--jobs", "1", "--no-optimal", "--no-progress",
        "--out", tmp_path / "out",
    )  # fmt: skip
    assert status == code and len(lines) == 1, lines
    assert message in lines[0] and "internal error" not in lines[0]


def test_a_factory_that_exits_is_a_failure_not_a_success(factories, tmp_path):
    code, lines = run("reproduce", "--env", f"{factories}:exits", "--out", tmp_path / "out")
    assert code == EXIT_ENVIRONMENT and len(lines) == 1
    assert "its factory called sys.exit(0)" in lines[0]
    assert not (tmp_path / "out").exists()  # nothing made
    log = pathlib.Path(lines[0].rpartition("traceback in ")[2].rstrip(")"))
    assert log.is_relative_to(tmp_path / "cache" / "errors") and "SystemExit" in log.read_text()


# -- result files ------------------------------------------------------------------------------------


def _write(text):
    return lambda path: path.write_text(text)


def _as_directory(path):
    path.unlink()
    path.mkdir()


def _as_device(path):
    path.unlink()
    path.symlink_to("/dev/zero")


@pytest.mark.parametrize(
    "name, damage, message",
    [
        ("wall_times.json", _write("[]"), "wall_times.json is damaged (TypeError"),
        ("wall_times.json", _write('{"parts": [{"wall_s": "x"}]}'), "wall_times.json is damaged"),
        ("wall_times.json", _as_directory, "wall_times.json cannot be read"),
        ("config.json", None, "config.json is damaged (protocol.algorithms is 5, not a list)"),
        ("config.json", _as_device, "is a device, pipe or socket, not a regular file"),
        ("config.json", _write("[" * 100_000), "config.json is damaged (not JSON: nested too deep"),
        ("curves/s-ac/exp_000.npz", _as_directory, "exp_000.npz is a directory where a file is"),
        (".lock", lambda path: path.mkdir(), ".lock cannot be the directory's lock"),
        ("summary.json", _as_directory, "summary.json is a directory where a file is expected"),
    ],
)
def test_a_resume_on_damaged_files_is_one_line(finished, resume, tmp_path, name, damage, message):
    out = _copy(finished, tmp_path)
    path = out / name
    if damage is None:
        config = json.loads(path.read_text())
        config["protocol"]["algorithms"] = 5
        path.write_text(json.dumps(config))
    else:
        damage(path)
    code, lines = run(*resume, out)
    assert code == EXIT_BAD_INPUT and message in lines[-1], lines
    assert not any("Traceback" in line for line in lines)


@pytest.mark.parametrize(
    "summary, message",
    [
        ([], "summary.json is damaged: a list, not a run's summary"),
        ({"trial_seconds": 1.0}, "summary.json is damaged: it holds no learner's row"),
        ({"trial_seconds": 1.0, "s-ac": {"experiments": 2}}, "'s-ac' lacks 'final_return_mean'"),
        ({"trial_seconds": 1.0, "s-ac": []}, "'s-ac' is a list, not a learner's row"),
    ],
)
def test_compare_on_a_damaged_summary_is_one_line(finished, tmp_path, summary, message):
    out = _copy(finished, tmp_path)
    (out / "summary.json").write_text(json.dumps(summary))
    code, lines = run("compare", out, "--out", tmp_path / "cmp")
    assert code == EXIT_BAD_INPUT and len(lines) == 1 and message in lines[0], lines


# -- snapshots ---------------------------------------------------------------------------------------


def _snapshot(finished) -> pathlib.Path:
    return finished / "snapshots" / "s-ac" / "exp_000" / "trial_0001.npz"


def _bad_snapshots(finished, tmp_path) -> dict[str, tuple[pathlib.Path, str]]:
    """name -> (a file that is no snapshot, what the line says)."""
    source = _snapshot(finished)
    with np.load(source) as data:
        arrays = dict(data)
    meta = json.loads(str(arrays["meta"]))
    found = {}

    def save(name, message, **changes):
        path = tmp_path / f"{name}.npz"
        np.savez(path, **{**arrays, **changes})
        found[name] = (path, message)

    save("meta_not_json", "JSONDecodeError", meta="{{{")
    save("meta_nested", "RecursionError", meta="[" * 100_000 + "]" * 100_000)
    save("no_algorithm", "unknown algorithm None", meta=json.dumps({**meta, "algorithm": None}))
    save("space_wrong_kind", "must be a mapping", meta=json.dumps({**meta, "state_space": 5}))
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"\x00\x01 not a file of arrays")
    found["garbage"] = (garbage, "not a readable rmac-mj snapshot")
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(source.read_bytes()[:300])
    found["truncated"] = (truncated, "not a zip")
    with zipfile.ZipFile(tmp_path / "empty_zip.npz", "w"):
        pass
    found["empty_zip"] = (tmp_path / "empty_zip.npz", "no 'meta' entry")
    return found


def test_render_and_policy_refuse_every_bad_snapshot_in_one_line(finished, tmp_path):
    for path, message in _bad_snapshots(finished, tmp_path).values():
        for command in (["render", path, "--out", tmp_path / "x.mp4"], ["policy", path]):
            code, lines = run(*command)
            assert code == EXIT_BAD_INPUT and len(lines) == 1 and message in lines[0], lines
            assert str(path) in lines[0]


# -- every command -----------------------------------------------------------------------------------


def _bad_inputs(finished, tmp_path, factories) -> dict[str, list[list]]:
    """A handful of bad inputs of every command of ``rmac-mj --help``."""
    snapshots = _bad_snapshots(finished, tmp_path)
    a_file = tmp_path / "a_file"
    a_file.write_text("not a directory")
    broken_summary = _copy(finished, tmp_path)
    (broken_summary / "summary.json").write_text("[]")
    bad_toml = tmp_path / "bad.toml"
    bad_toml.write_text("this is = = not toml")
    syntax = tmp_path / "syntax.py"
    syntax.write_text("def f(:\n")
    exits = f"{factories}:exits"
    return {
        "reproduce": [
            ["--trials", "0"],
            ["--env", exits, "--out", tmp_path / "r1"],
            ["--env", f"{syntax}:f", "--out", tmp_path / "r2"],
            ["--out", a_file / "sub"],
            ["--set", "s-ac.gamma=2", "--algorithms", "s-ac", "--out", tmp_path / "r3"],
        ],
        "sweep": [
            [tmp_path / "missing.toml", "--out", tmp_path / "s1"],
            [bad_toml, "--out", tmp_path / "s2"],
            [tmp_path, "--out", tmp_path / "s3"],
        ],
        "panel": [
            ["--out", tmp_path / "p1", "--experiments", "0"],
            ["--out", tmp_path / "p2", "--tasks", "nosuch"],
            ["--out", a_file / "sub"],
        ],
        "compare": [
            [tmp_path / "missing"],
            [broken_summary],
            [a_file],
        ],
        "policy": [[snapshots[name][0]] for name in ("garbage", "truncated", "no_algorithm")]
        + [[tmp_path / "missing.npz"]],
        "optimal": [["--domain", "nosuch"], ["--task", "nosuch"], ["--env", exits]],
        "render": [
            [snapshots["garbage"][0], "--out", tmp_path / "v.mp4"],
            [snapshots["meta_not_json"][0], "--out", tmp_path / "v.mp4"],
            ["--progression", tmp_path / "missing", "--out", tmp_path / "v.mp4"],
            ["--out", tmp_path / "v.mp4"],
        ],
        "bench": [["--domain", "nosuch"], ["--env", exits], ["--env", "nonsense"]],
    }


@pytest.mark.slow
def test_every_command_refuses_bad_inputs_in_one_line(finished, tmp_path, factories):
    commands = build_parser()._subparsers._group_actions[0].choices
    bad = _bad_inputs(finished, tmp_path, factories)
    assert set(bad) == set(commands)  # a new command gets its bad inputs here
    here = os.getcwd()
    os.chdir(tmp_path)
    try:
        for command, cases in bad.items():
            for args in cases:
                code, lines = run(command, *args)
                assert code in (EXIT_BAD_INPUT, EXIT_ENVIRONMENT), (command, args, code, lines)
                assert len(lines) == 1, (command, args, lines)
                assert "Traceback" not in lines[0]
    finally:
        os.chdir(here)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--learner-state", "[" * 60_000 + "]" * 60_000], "argument --learner-state: expected"),
        (["--set", "s-ac.gamma=" + "[" * 60_000 + "]" * 60_000], "its value is nested too deep"),
    ],
)
def test_a_deeply_nested_json_option_is_one_line(tmp_path, args, message):
    code, lines = run("reproduce", *args, "--out", tmp_path / "out")
    assert code == EXIT_BAD_INPUT and len(lines) == 1 and message in lines[0], lines
    assert len(lines[0]) < 500


@pytest.mark.slow
def test_a_scheduler_address_of_an_unknown_scheme_is_one_line():
    pytest.importorskip("distributed", reason="needs the [distributed] extra")
    from rmac_mj.experiments import BackendError, connect_dask

    with pytest.raises(BackendError, match="is not a scheduler address"):
        connect_dask("foo://localhost:1", timeout=1)

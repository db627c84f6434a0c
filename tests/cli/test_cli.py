"""The command line: bad arguments give one clear line and a non-zero exit, not a traceback; sizes
that scale a loop or an allocation are refused in one line, in well under a second, naming the
limit and its reason (the learners' memories against the machine's).

The commands run in this process (``rmac_mj.cli.main``), as a user's shell runs them but without
paying a Python start-up each; ``python -m`` itself is tested once, and the refusals of what would
not fit the memory in an interpreter whose address space is capped.
"""

import contextlib
import dataclasses
import io
import json
import os
import pathlib
import shutil
import subprocess
import sys
import textwrap
import time

import pytest

from rmac_mj import constraints
from rmac_mj.cli import build_parser, main, runs
from rmac_mj.errors import UserInputError


@dataclasses.dataclass
class Result:
    returncode: int
    stdout: str
    stderr: str


def rmac_mj(*args, cwd=None) -> Result:
    """``rmac-mj ARGS`` in this process (in ``cwd``): its exit status and what it printed."""
    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(list(args))
            except SystemExit as exit:  # argparse's own errors, --help, --version
                code = exit.code
    finally:
        os.chdir(here)
    return Result(code, out.getvalue(), err.getvalue())


@pytest.mark.parametrize(
    "args, message",
    [
        (["reproduce", "--experiments", "-2"], "expected an integer in [1, 10000]"),
        (["reproduce", "--trials", "zero"], "expected an integer in [1, 1000000]"),
        (["reproduce", "--algorithms", "rmac,dqn", "--out", "{tmp}/x"], "unknown algorithm 'dqn'"),
        (["reproduce", "--out", "{tmp}/file/sub"], "cannot write"),
        (["policy", "{tmp}/missing.npz"], "no snapshot"),
        (["compare", "{tmp}"], "no summary.json"),
        (["render", "--out", "{tmp}/x.mp4"], "exactly one of"),
        (["reproduce", "--domain", "cartpole", "--out", "{tmp}/x"], "unknown domain 'cartpole'"),
        (["reproduce", "--task", "spin", "--out", "{tmp}/x"], "unknown task 'spin'"),
        (
            ["bench", "--domain", "cartpole"],
            "unknown domain 'cartpole'; available: dc_pendulum, "
            "two_link_arm; dm-control has 'cartpole', an outside "
            "environment: env dm_control:cartpole/",
        ),
        (["policy", "{tmp}/missing.npz", "--dims", "1"], "two state dimensions"),
        (
            ["render", "--progression", "{tmp}", "--task", "swingup", "--out", "{tmp}/x.mp4"],
            "single SNAPSHOT",
        ),
    ],
)
def test_bad_arguments_give_one_line(tmp_path, args, message):
    (tmp_path / "file").write_text("not a directory")
    result = rmac_mj(*[a.replace("{tmp}", str(tmp_path)) for a in args])
    assert result.returncode == 2
    assert message in result.stderr
    assert "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_reproduce_and_compare_and_policy(finished_run, tmp_path):
    out = finished_run.out
    assert "s-ac" in finished_run.stdout and "final return" in finished_run.stdout
    result = rmac_mj("compare", str(out), str(out), "--out", str(tmp_path / "cmp"))
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "cmp.png").is_file()
    result = rmac_mj(
        "policy",
        str(out / "snapshots/s-ac/exp_000/trial_0003.npz"),
        "--out",
        str(tmp_path / "policy"),
    )
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "policy.png").is_file()


def test_set_overrides_parse_into_nested_agent_configs():
    from rmac_mj.cli.arguments import UsageError
    from rmac_mj.cli.runs import parse_overrides

    assert parse_overrides(
        ["rmac.exploration.sigma=0.5", "s-ac.rate_split=actor", "s-ac.tile_high=[null, 60]"]
    ) == {
        "rmac": {"exploration": {"sigma": 0.5}},
        "s-ac": {"rate_split": "actor", "tile_high": [None, 60]},
    }
    for bad in ("rmac", "rmac=1", "sigma=0.5", "rmac..x=1"):
        with pytest.raises(UsageError, match="ALGO.FIELD=VALUE"):
            parse_overrides([bad])


def test_set_addresses_a_memory_by_dotted_keys_and_keeps_its_other_settings():
    from rmac_mj.agents import MLACConfig, config_from_dict
    from rmac_mj.cli.runs import parse_overrides

    overrides = parse_overrides(
        ["mlac.process.capacity=300", "mlac.process.replacement=oldest", "mlac.critic.clip=false"]
    )
    assert overrides == {
        "mlac": {"process": {"capacity": 300, "replacement": "oldest"}, "critic": {"clip": False}}
    }
    config = config_from_dict(MLACConfig, overrides["mlac"])
    assert (config.process.capacity, config.process.replacement) == (300, "oldest")
    assert config.process.redundancy == "misfit" and config.actor == MLACConfig().actor
    assert not config.critic.clip


@pytest.mark.parametrize(
    "assignment, hint",
    [
        ("rmac.critic_capacity=2000", "rmac.critic.capacity"),
        ("mlac.actor_neighbours=5", "mlac.actor.neighbours"),
        ("rmac.reference.neighbour=5", "rmac.reference.neighbours"),
    ],
)
def test_a_flat_memory_name_is_one_line_naming_the_dotted_key(tmp_path, capsys, assignment, hint):
    out = tmp_path / "x"
    assert main(["reproduce", "--set", assignment, "--no-progress", "--out", str(out)]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    key = assignment.partition("=")[0]
    assert line.startswith(f"rmac-mj: error: --set {key}: ") and line.endswith(
        f"(did you mean {hint!r}?)"
    )
    assert not out.exists()


def test_unknown_hyperparameter_is_one_line(tmp_path):
    result = rmac_mj(
        "reproduce", "--algorithms", "s-ac", "--out", str(tmp_path / "x"), "--set", "s-ac.bogus=1"
    )
    assert result.returncode == 2 and "StandardACConfig has no parameter 'bogus'" in result.stderr


def test_a_bug_keeps_its_traceback(tmp_path, monkeypatch, capsys):
    """Only bad user input is a plain one line; a ValueError from inside the code is a bug: its line
    says so and where its traceback went, the log holds it, and --debug prints it."""
    from rmac_mj.experiments import runner

    def broken(*args, **kwargs):
        raise ValueError("deep inside a learner")

    monkeypatch.setattr(runner, "run_protocol", broken)
    monkeypatch.setenv("RMAC_MJ_CACHE_DIR", str(tmp_path / "cache"))
    assert main(["reproduce", "--out", str(tmp_path / "x"), "--no-progress"]) == 1
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "a bug of rmac-mj: ValueError: deep inside a learner" in line
    log = line.rpartition("traceback in ")[2].partition(";")[0]
    assert 'raise ValueError("deep inside a learner")' in open(log).read()
    assert main(["--debug", "reproduce", "--out", str(tmp_path / "y"), "--no-progress"]) == 1
    assert "Traceback (most recent call last)" in capsys.readouterr().err


def test_bad_hyperparameter_value_is_one_line(tmp_path):
    result = rmac_mj(
        "reproduce", "--algorithms", "rmac", "--out", str(tmp_path / "x"), "--set", "rmac.gamma=1.5"
    )
    assert (
        result.returncode == 2
        and "RMACConfig.gamma must be a number in [0, 1), or None, got 1.5" in result.stderr
    )
    assert len(result.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_version_and_python_dash_m():
    from rmac_mj import __version__

    result = subprocess.run(
        [sys.executable, "-m", "rmac_mj.cli", "--version"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0 and result.stdout.strip() == f"rmac-mj {__version__}"
    result = subprocess.run(
        [sys.executable, "-m", "rmac_mj", "--help"], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0 and "usage: rmac-mj" in result.stdout
    assert "``" not in result.stdout  # no raw reST markup


def test_no_arguments_prints_the_usage_and_the_commands():
    result = rmac_mj()
    assert result.returncode == 0 and result.stdout.startswith("usage: rmac-mj")
    for command in ("reproduce", "compare", "policy", "optimal", "render", "bench"):
        assert f"\n    {command} " in result.stdout or f"\n    {command}\n" in result.stdout, (
            command
        )


def test_every_option_has_help_and_the_help_shows_defaults():
    import argparse

    from rmac_mj.cli import build_parser

    parser = build_parser()
    subparsers = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, command in subparsers.choices.items():
        for action in command._actions:
            assert action.help, f"{name} {action.option_strings or action.dest} has no help"
        text = command.format_help()
        assert "``" not in text
    reproduce = subparsers.choices["reproduce"].format_help()
    assert "(default: results/reproduce)" in " ".join(reproduce.split())
    assert "(default: 0)" in reproduce  # --seed: a default of 0 is still shown


def test_the_run_commands_options_are_the_protocols_and_alike_in_every_command():
    import argparse

    from rmac_mj.cli import build_parser
    from rmac_mj.experiments import Protocol

    parser = build_parser()
    subparsers = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    options = {
        name: {action.dest: action for action in subparsers.choices[name]._actions}
        for name in ("reproduce", "sweep", "panel")
    }
    given = parser.parse_args(["reproduce"])
    for field in ("experiments", "trials", "steps", "seed", "evaluate_every", "evaluate_starts"):
        assert getattr(given, field) == getattr(Protocol(), field), field  # the field's default
    for dest in ("jobs", "resume", "no_progress", "out", "experiments", "trials", "seed"):
        declared = [(o[dest].option_strings, o[dest].type, o[dest].metavar, o[dest].nargs)
                    for o in options.values() if dest in o]  # fmt: skip
        assert len(declared) >= 2 and len(set(map(repr, declared))) == 1, (dest, declared)
    # A value the Protocol refuses is refused while parsing, in the words of its constraint.
    for args, expected in (
        (["--steps", "0"], "argument --steps: expected an integer >= 1, got '0'"),
        (["--evaluate-starts", "1001"], "expected an integer in [0, 1000] (every evaluation"),
        (["--control-timestep", "nan"], "expected a finite number >= 1e-06, got 'nan'"),
    ):
        result = rmac_mj("reproduce", *args)
        assert result.returncode == 2 and expected in result.stderr, result.stderr


def test_set_without_algorithms_runs_only_the_learners_it_names(capsys):
    import argparse

    from rmac_mj.cli.runs import algorithms_to_run

    assert algorithms_to_run(argparse.Namespace(algorithms=None), {"rmac": {"gamma": 0.9}}) == (
        "rmac",
    )
    assert "running it alone" in capsys.readouterr().err
    assert algorithms_to_run(argparse.Namespace(algorithms="rmac,s-ac"), {"rmac": {}}) == (
        "rmac",
        "s-ac",
    )
    assert algorithms_to_run(argparse.Namespace(algorithms=None), {}) == ("rmac", "s-ac")


def _fake_run(directory, seed, agent_configs=None, task=None, trial_seconds=3.0):
    import json

    import numpy as np

    from rmac_mj.evaluation import summarise

    rng = np.random.default_rng(seed)
    directory.mkdir(parents=True)
    summary = {
        "trial_seconds": trial_seconds,
        "optimal_return": None,
        "protocol": {
            "experiments": 3,
            "trials": 60,
            "seed": seed,
            "agent_configs": agent_configs or {},
            **(task or {}),
        },
        "rmac": summarise(-1000 + rng.normal(0, 50, (3, 60)), trial_seconds=3.0).as_dict(),
    }
    (directory / "summary.json").write_text(json.dumps(summary))


@pytest.mark.slow
def test_compare_shows_same_named_directories_apart(tmp_path):
    _fake_run(tmp_path / "a" / "run", 0)
    _fake_run(tmp_path / "b" / "run", 1, {"rmac": {"exploration": {"sigma": 0.5}}})
    result = rmac_mj("compare", "a/run", "b/run", "--out", "cmp", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "== a/run: 3 experiments of 60 trials, seed 0; default hyperparameters" in result.stdout
    assert (
        "== b/run: 3 experiments of 60 trials, seed 1; --set rmac.exploration.sigma=0.5"
        in result.stdout
    )
    assert (tmp_path / "cmp.png").is_file()


@pytest.mark.slow
def test_compare_draws_next_to_the_first_run_by_default(tmp_path):
    _fake_run(tmp_path / "a" / "run", 0)
    _fake_run(tmp_path / "b" / "run", 1)
    result = rmac_mj("compare", "a/run", "b/run", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "a",
        "b",
    ]  # nothing in the working directory
    for name in ("compare.png", "compare.pdf", "compare_profiles.png", "compare_profiles.pdf"):
        assert (tmp_path / "a" / "run" / name).is_file(), name


PENDULUM = {"domain": "dc_pendulum", "task": "swingup", "env": None, "task_kwargs": {}}


@pytest.mark.parametrize(
    "other, trial_seconds, shown",
    [
        ({"domain": None, "task": None, "env": "wheel.py:make"}, 1.0, "b: wheel.py:make, 1 s"),
        ({**PENDULUM, "task_kwargs": {"time_limit": 6.0}}, 6.0, 'swingup {"time_limit": 6.0}'),
        ({**PENDULUM, "task": "balance"}, 3.0, "b: dc_pendulum/balance, 3 s trials"),
    ],
)
@pytest.mark.parametrize("x_axis", ["minutes", "env-steps"])
def test_compare_refuses_runs_of_different_tasks(tmp_path, other, trial_seconds, shown, x_axis):
    _fake_run(tmp_path / "a", 0, task=PENDULUM)
    _fake_run(tmp_path / "b", 1, task=other, trial_seconds=trial_seconds)
    result = rmac_mj("compare", "a", "b", "--x-axis", x_axis, "--out", "cmp", cwd=tmp_path)
    assert result.returncode == 2, result
    assert "the runs are of different tasks (a: dc_pendulum/swingup, 3 s trials; " in result.stderr
    assert shown in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b"]  # nothing drawn


def test_compare_into_an_existing_folder_writes_inside_it(tmp_path):
    _fake_run(tmp_path / "a", 0, task=PENDULUM)
    _fake_run(tmp_path / "b", 1, task=PENDULUM)
    (tmp_path / "figures").mkdir()
    result = rmac_mj("compare", "a", "b", "--out", "figures", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b", "figures"]  # no figures.png
    for name in ("compare.png", "compare.pdf", "compare_profiles.png", "compare_profiles.pdf"):
        assert (tmp_path / "figures" / name).is_file(), name


def test_shortest_distinct_suffixes():
    import pathlib

    from rmac_mj.cli.views import shortest_distinct_suffixes

    assert shortest_distinct_suffixes([pathlib.Path("/r/a/run"), pathlib.Path("/r/b/run")]) == [
        "a/run",
        "b/run",
    ]
    assert shortest_distinct_suffixes([pathlib.Path("/r/ten"), pathlib.Path("/s/oldest")]) == [
        "ten",
        "oldest",
    ]
    assert shortest_distinct_suffixes([pathlib.Path("/x/run"), pathlib.Path("/y/x/run")]) == [
        "/x/run",
        "y/x/run",
    ]


@pytest.mark.parametrize(
    "command",
    [
        ["reproduce", "--algorithms", "s-ac", "--experiments", "1", "--trials", "1"],
        ["sweep", "docs/studies/exploration.toml"],
        ["panel", "--algorithms", "s-ac", "--trials", "1"],
    ],
)
@pytest.mark.parametrize("exists", [False, True])
def test_a_resume_of_nothing_says_so(tmp_path, command, exists):
    out = tmp_path / "typo"
    if exists:
        out.mkdir()
    here = pathlib.Path(__file__).parents[2]
    result = rmac_mj(*command, "--no-progress", "--resume", "--out", str(out), cwd=here)
    assert result.returncode == 2, result
    assert f"--resume: {out} holds nothing to resume (it " in result.stderr
    assert ("has no" if exists else "does not exist") in result.stderr
    assert sorted(tmp_path.iterdir()) == ([out] if exists else [])  # nothing started
    assert not exists or not any(out.iterdir())


def test_an_interrupt_before_any_result_says_nothing_is_saved(tmp_path, monkeypatch):
    from rmac_mj.experiments import runner

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "run_protocol", interrupted)
    result = rmac_mj("reproduce", "--out", str(tmp_path / "x"), "--no-progress")
    assert result.returncode == 130
    assert "nothing is saved" in result.stderr and "are saved" not in result.stderr
    assert "--resume" not in result.stderr  # nothing begun: there is nothing to resume


@pytest.mark.slow
def test_a_resume_takes_its_settings_from_the_directory(tmp_path, capsys):
    out = tmp_path / "run"
    args = [
        "reproduce",
        "--algorithms",
        "s-ac",
        "--experiments",
        "2",
        "--trials",
        "3",
        "--seed",
        "5",
        "--evaluate-every",
        "3",
        "--set",
        "s-ac.alpha_a=0.02",
        "--jobs",
        "1",
        "--no-optimal",
        "--no-progress",
        "--out",
        str(out),
    ]
    assert main(args) == 0
    whole = json.loads((out / "summary.json").read_text())
    (out / "curves" / "s-ac" / "exp_001.npz").unlink()  # as if interrupted before the last one
    (out / "summary.json").unlink()
    # The bare command: --no-optimal too comes from the directory (no reference computed, minutes
    # on a cold cache, and no reference in a summary whose uninterrupted run had none).
    assert main(["reproduce", "--resume", "--out", str(out), "--no-progress"]) == 0
    resumed = json.loads((out / "summary.json").read_text())
    assert whole["optimal_return"] is None and resumed["optimal_return"] is None
    assert resumed["s-ac"].keys() == whole["s-ac"].keys()
    assert resumed["protocol"] == whole["protocol"]
    assert resumed["s-ac"]["mean_return_per_trial"] == whole["s-ac"]["mean_return_per_trial"]
    capsys.readouterr()
    # Options given explicitly must agree with the directory's; what differs is named.
    assert main(["reproduce", "--resume", "--out", str(out), "--trials", "4", "--no-optimal"]) == 2
    error = capsys.readouterr().err
    assert "trials: 3 in the directory, 4 now" in error and len(error.strip().splitlines()) == 1
    assert main(["reproduce", "--resume", "--out", str(out), "--set", "s-ac.alpha_a=0.05"]) == 2
    assert "agent_configs.s-ac.alpha_a: 0.02 in the directory, 0.05 now" in capsys.readouterr().err
    # A finished run grows by more experiments (the settings from the directory, the count given).
    assert (
        main(["reproduce", "--resume", "--out", str(out), "--experiments", "3", "--no-progress"])
        == 0
    )
    grown = json.loads((out / "summary.json").read_text())
    assert grown["s-ac"]["experiments"] == 3 and grown["protocol"]["seed"] == 5
    assert grown["protocol"]["agent_configs"] == whole["protocol"]["agent_configs"]
    assert grown["optimal_return"] is None


@pytest.mark.slow
def test_running_a_finished_run_again_prints_its_summary(finished_run, tmp_path, capsys):
    out = tmp_path / "run"
    shutil.copytree(finished_run.out, out)
    args = [*finished_run.command, "--out", str(out)]
    first = finished_run.stdout
    stamp = (out / "summary.json").stat().st_mtime_ns
    assert main(args) == 0
    captured = capsys.readouterr()
    assert "already holds this run, finished" in captured.err
    assert first.split("wall time")[0].strip() in captured.out  # the same table
    assert (out / "summary.json").stat().st_mtime_ns == stamp  # nothing was run or rewritten
    assert main([*args[:-1], str(out), "--seed", "1"]) == 2  # another run: refused, naming it
    assert "seed: 0 in the directory, 1 now" in capsys.readouterr().err
    # A summary damaged since: one line saying how to write it again, and that command does.
    summary = (out / "summary.json").read_text()
    (out / "summary.json").write_text(summary[:40])
    assert main(args) == 2
    error = capsys.readouterr().err
    assert "summary.json: not a JSON document" in error and "already holds" not in error
    assert f"rmac-mj reproduce --resume --out {out} --no-optimal writes it again" in error
    assert len(error.strip().splitlines()) == 1
    assert main([*args, "--resume"]) == 0
    assert json.loads((out / "summary.json").read_text())["s-ac"] == json.loads(summary)["s-ac"]


def test_policy_maps_keep_the_labels_the_run_declared():
    from rmac_mj.cli.views import _declared_labels
    from rmac_mj.tasks import LearnerStateSpec

    inferred = LearnerStateSpec(
        keys=("atan2(observation[1], observation[0])", "observation[2]"),
        low=(-3.2, -10.0),
        high=(3.2, 10.0),
        periodic=(True, False),
        labels=("atan2(observation[1],observation[0]) [rad]", "observation[2]"),
        input_weights=(1.0, 0.3),
        action_input_weights=(1.0,),
        action_labels=("u[0]",),
    )
    meta = {
        "environment": {
            "env": "my_task.py:make",
            "learner_state": {
                "keys": list(inferred.keys),
                "labels": ["angle phi [rad]", "speed [rad/s]"],
                "action_labels": ["torque [N m]"],
            },
        }
    }
    named = _declared_labels(inferred, meta)
    assert named.labels == ("angle phi [rad]", "speed [rad/s]") and named.action_labels == (
        "torque [N m]",
    )
    other = {"environment": {"learner_state": {"keys": ["observation[0]"], "labels": ["x"]}}}
    assert _declared_labels(inferred, other) == inferred  # another state: nothing borrowed
    assert _declared_labels(inferred, {"domain": "dc_pendulum"}) == inferred


def test_a_run_budgeted_in_steps_reads_in_steps_and_compare_writes_two_figures(tmp_path):
    """Issue 39: with --steps the progress counts the steps taken of the steps asked (not the
    --trials cap), the table carries the greedy return at the last evaluation and says what its
    columns average over, compare's header says the trials and steps that ran, and compare --out
    x.png writes the curves and the profiles to two names."""
    out = tmp_path / "run"
    result = rmac_mj(
        "reproduce", "--algorithms", "s-ac", "--experiments", "2", "--steps", "600",
        "--trials", "600", "--evaluate-every", "2", "--jobs", "1", "--out", str(out),
        "--no-optimal",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    progress = [line for line in result.stderr.splitlines() if line.startswith("[")]
    assert progress and all("/1200 env steps" in line for line in progress), progress
    assert "1200/1200 env steps, 12 trials (2/2 experiments)" in progress[-1]
    assert "trials/s" not in result.stderr and "/1200 trials" not in result.stderr
    header = result.stdout.splitlines()[0]
    assert "greedy at end" in header and "95% CI]" not in header  # 2 experiments: no interval
    for said in (
        "each experiment: 600 env steps asked (at most 600 trials); ran: s-ac 6 trials, 600 steps",
        "final return: each experiment's mean over its last 6 trials, all it ran (the window is "
        "50 trials; this run is shorter)",
        "greedy at end: the greedy evaluation (no exploration, no learning) after trial 6",
    ):
        assert said in result.stdout
    summary = json.loads((out / "summary.json").read_text())
    greedy = f"{summary['s-ac']['greedy_return_last_mean']:.0f}"
    assert f" {greedy} " in result.stdout.splitlines()[2]  # the column's figure, from the summary

    figures = tmp_path / "figures"
    result = rmac_mj("compare", str(out), "--out", str(figures / "pend-compare.png"))
    assert result.returncode == 0, result.stderr
    assert "2 experiments of 600 env steps (at most 600 trials; ran: s-ac 6 trials, 600 " in (
        result.stdout
    )
    assert sorted(p.name for p in figures.iterdir()) == [
        "pend-compare.pdf",
        "pend-compare.png",
        "pend-compare_profiles.pdf",
        "pend-compare_profiles.png",
    ]
    assert rmac_mj("compare", str(out), "--out", f"{tmp_path / 'folder'}/").returncode == 0
    assert sorted(p.name for p in (tmp_path / "folder").iterdir()) == [
        "compare.pdf",
        "compare.png",
        "compare_profiles.pdf",
        "compare_profiles.png",
    ]
    refused = rmac_mj("compare", str(out), "--out", str(tmp_path / "x.svg"))
    assert refused.returncode == 2 and "ending in .png or .pdf" in refused.stderr


def test_the_table_carries_the_greedy_return_with_its_interval_at_five_experiments():
    import numpy as np

    from rmac_mj.evaluation import summarise, summary_table

    rng = np.random.default_rng(0)
    returns = -1000 + rng.normal(0, 50, (5, 60))
    greedy = -400 + rng.normal(0, 20, (5, 3))
    row = summarise(returns, greedy, greedy_trials=(20, 40, 60), trial_seconds=3.0)
    table = summary_table({"trial_seconds": 3.0, "s-ac": row.as_dict()}).splitlines()
    assert "greedy at end [95% CI]" in table[0] and "IQM [95% CI]" in table[0]
    low, high = row.greedy_return_last_ci95
    assert f"{row.greedy_return_last_mean:.0f} [{low:.0f}, {high:.0f}]" in table[2]
    assert "final return: each experiment's mean over its last 50 trials; then" in table[3]
    assert (
        "greedy at end: the greedy evaluation (no exploration, no learning) after trial 60"
        in (table[4])
    )
    without = summary_table(
        {"trial_seconds": 3.0, "s-ac": summarise(returns, trial_seconds=3.0).as_dict()}
    )
    assert "greedy" not in without  # a run that did not evaluate has no such column


def test_bench_cold_compiles_a_learner_from_an_empty_cache():
    from rmac_mj.bench import cold_start

    row = cold_start.learner_compile("s-ac")  # a fresh process and cache: compiled, not loaded
    assert row["algorithm"] == "s-ac" and row["kernels"] >= 1 and row["compile_cpu_s"] > 0
    assert any(name.startswith("agents.standard_ac.") for name, _, _ in row["per_kernel"])
    text = cold_start.format_table({"cpus": 2, "load_before": 0.5, "learners": [row]})
    assert text.splitlines()[2].split()[0] == "s-ac" and "agents.standard_ac." in text


# -- sizes -------------------------------------------------------------------------------------------

#: The longest a refusal before anything runs may take (well under a second unloaded).
PROMPT_SECONDS = 2.0


def _refused_in_one_line(*args: str) -> str:
    started = time.perf_counter()
    result = rmac_mj(*args)
    took = time.perf_counter() - started
    assert result.returncode == 2, result
    assert "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert took < PROMPT_SECONDS, f"{args} took {took:.1f} s to be refused"
    return result.stderr


@pytest.mark.parametrize(
    "option, value, limit",
    [
        ("--trials", "1000000000000", constraints.TRIALS),
        ("--experiments", "1000000000", constraints.EXPERIMENTS),
        ("--evaluate-starts", "1000000000", constraints.EVALUATE_STARTS),
        ("--prior-trials", "1000000000", constraints.PRIOR_TRIALS),
        ("--action-repeat", "1000000000", constraints.ACTION_REPEAT),
        ("--trial-steps", "1000000000000", constraints.TRIAL_STEPS),
        ("--trials", "0", constraints.TRIALS),
        ("--trials", "-1", constraints.TRIALS),
        ("--trials", "nan", constraints.TRIALS),
        ("--trials", "1e12", constraints.TRIALS),
        ("--experiments", "many", constraints.EXPERIMENTS),
    ],
)
def test_reproduce_refuses_a_size_beyond_its_limit_saying_the_limit_and_why(
    tmp_path, option, value, limit
):
    error = _refused_in_one_line("reproduce", f"{option}={value}", "--out", str(tmp_path / "x"))
    assert f"argument {option}" in error and f", {limit.value}]" in error
    assert limit.reason in error and repr(value) in error


@pytest.mark.parametrize("value", ["100000", "1", "0", "nan", "fine"])
def test_policy_refuses_a_resolution_beyond_its_limit_before_loading_anything(tmp_path, value):
    error = _refused_in_one_line("policy", str(tmp_path / "missing.npz"), f"--resolution={value}")
    assert "argument --resolution" in error and constraints.MAP_RESOLUTION.reason in error


def test_panel_refuses_a_size_beyond_its_limit(tmp_path):
    error = _refused_in_one_line("panel", "--out", str(tmp_path / "p"), "--trials", "10000000000")
    assert constraints.TRIALS.reason in error


def test_a_config_file_sizes_the_protocol_by_the_same_limits(tmp_path):
    config = tmp_path / "big.toml"
    config.write_text('[protocol]\nalgorithms = ["s-ac"]\nexperiments = 1000000000\n')
    error = _refused_in_one_line("reproduce", "--config", str(config), "--out", str(tmp_path / "x"))
    assert "experiments" in error and constraints.EXPERIMENTS.reason in error


def _limited(code: str, gigabytes: int = 4) -> subprocess.CompletedProcess:
    """``code`` in a fresh interpreter whose address space is capped at ``gigabytes``: a check that
    failed would end in a MemoryError there, never in the machine's memory."""
    script = (
        "import resource\n"
        f"resource.setrlimit(resource.RLIMIT_AS, ({gigabytes} * 2**30, {gigabytes} * 2**30))\n"
        + textwrap.dedent(code)
    )
    return subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )


@pytest.mark.slow
@pytest.mark.parametrize(
    "assignment",
    [
        "s-ac.tile_coding.num_tilings=1000000000",
        "s-ac.tile_coding.tiles=100000",
        's-ac.planning={"steps": 30, "model_capacity": 1000000000}',
    ],
)
def test_a_learner_too_large_for_the_memory_is_refused_before_it_is_built(tmp_path, assignment):
    result = _limited(
        f"""
        import sys
        from rmac_mj.cli import main
        sys.exit(main(["reproduce", "--set", {assignment!r}, "--experiments", "1", "--trials",
                       "1", "--no-optimal", "--no-progress", "--out", {str(tmp_path / "x")!r}]))
        """
    )
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2, result.stderr
    assert "needs about" in lines[-1] and "more than this machine's 4.3 GB" in lines[-1]
    assert "Traceback" not in result.stderr and "MemoryError" not in result.stderr


@pytest.mark.slow
def test_compare_says_which_learner_a_summary_lacks(tmp_path):
    run = tmp_path / "run"
    _fake_run(run, 0)
    summary = json.loads((run / "summary.json").read_text())
    summary["protocol"]["algorithms"] = ["rmac", "s-ac"]  # s-ac ran but its results are gone
    (run / "summary.json").write_text(json.dumps(summary))
    result = rmac_mj("compare", str(run), "--out", str(tmp_path / "cmp"))
    assert result.returncode == 0, result.stderr
    said = [line for line in result.stderr.splitlines() if "s-ac" in line]
    assert len(said) == 1 and str(run) in said[0] and "no results for s-ac" in said[0]
    del summary["rmac"]
    (run / "summary.json").write_text(json.dumps(summary))
    error = _refused_in_one_line("compare", str(run), "--out", str(tmp_path / "cmp2"))
    assert "none of its learners (rmac, s-ac)" in error


def _settings(argv: list[str]):
    return runs.settings_from_files(argv, build_parser().parse_args(argv))


@pytest.mark.slow
def test_the_command_lines_env_completes_a_config_file(tmp_path):
    config = tmp_path / "outside.toml"
    config.write_text('[protocol]\nalgorithms = ["s-ac"]\ntrial_steps = 50\n')
    env = "dm_control:pendulum/swingup"
    args = _settings(["reproduce", "--config", str(config), "--env", env])
    assert args.env == env and args.trial_steps == 50
    with pytest.raises(
        UserInputError, match=r"trial_steps \(--trial-steps\) describes an outside environment"
    ):
        _settings(["reproduce", "--config", str(config)])  # no environment anywhere
    # the file names the environment and the command line sets its trial length: accepted
    config.write_text(f'[protocol]\nalgorithms = ["s-ac"]\nenv = "{env}"\ntrial_steps = 50\n')
    args = _settings(["reproduce", "--config", str(config), "--trial-steps", "20"])
    assert args.env == env and args.trial_steps == 20


@pytest.mark.parametrize(
    "option, named",
    [
        ("--width=30000", "width must be an integer in [1, 640]"),
        ("--height=100000", "height must be an integer in [1, 480]"),
        ("--frames-per-step=2", "frames_per_step must be a positive divisor of the 3"),
    ],
)
def test_render_refuses_a_frame_size_in_one_line(tmp_path, option, named):
    from rmac_mj import tasks
    from rmac_mj.agents import make_agent
    from rmac_mj.results import save_snapshot
    from rmac_mj.rollout import action_space_of, state_space_of

    env = tasks.load("dc_pendulum", "swingup")
    states, actions = state_space_of(env), action_space_of(env)
    agent = make_agent("s-ac", states, actions, seed=0)
    snapshot = tmp_path / "trial_0001.npz"
    save_snapshot(
        snapshot, agent, states, actions, domain="dc_pendulum", task="swingup", task_kwargs={},
        experiment=0, seed=0, trial=1,
    )  # fmt: skip
    error = _refused_in_one_line("render", str(snapshot), "--out", str(tmp_path / "v.mp4"), option)
    assert named in error


def test_neighbours_beyond_the_capacity_the_task_sets_are_one_line(tmp_path):
    # critic.capacity is left to the task's units; the memory estimate resolves it, and refuses
    error = _refused_in_one_line(
        "reproduce", "--algorithms", "rmac", "--set", "rmac.critic.neighbours=1000000000",
        "--out", str(tmp_path / "x"),
    )  # fmt: skip
    assert "rmac on dc_pendulum/swingup: RMACConfig.critic.neighbours must be an integer" in error

"""Sizes that scale a loop or an allocation are refused by the command line in one line, in well
under a second, naming the limit and its reason; the learners' memories against the machine's;
compare and --config where the command line completes what a file lacks."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import time

import pytest
from test_cli import _fake_run, rmac_mj

from rmac_mj import constraints
from rmac_mj.cli import build_parser, runs
from rmac_mj.errors import UserInputError

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
    # critic_capacity is left to the task's units; the memory estimate resolves it, and refuses
    error = _refused_in_one_line(
        "reproduce", "--algorithms", "rmac", "--set", "rmac.critic_neighbours=1000000000",
        "--out", str(tmp_path / "x"),
    )  # fmt: skip
    assert "rmac on dc_pendulum/swingup: RMACConfig.critic_neighbours must be an integer" in error

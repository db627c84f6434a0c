"""The panel: its tasks' budgets are the issue's, in environment steps; one command runs them."""

import dataclasses

import numpy as np
import pytest

from rmac_mj.cli import main
from rmac_mj.experiments import panel
from rmac_mj.rollout import steps_per_trial


@pytest.mark.slow
@pytest.mark.parametrize(
    "name, env_steps",
    [
        ("pendulum_v1", 3_000),
        ("cartpole_balance", 5_000),
        ("cartpole_swingup", 50_000),
        ("pendulum_swingup", 100_000),
    ],
)
def test_each_goal_is_read_at_the_issues_budget_in_environment_steps(name, env_steps):
    task = panel.TASKS_BY_NAME[name]
    protocol = task.make_protocol(["s-ac"], 1, 0)
    env = protocol.make_environment(0)
    assert steps_per_trial(env) * protocol.action_repeat * task.goal_trial == env_steps
    assert task.goal_trial in range(
        protocol.evaluate_every, protocol.trials + 1, protocol.evaluate_every
    )  # the goal is read at an evaluation


@pytest.mark.slow
def test_the_panel_command_runs_every_task_into_its_own_directory(tmp_path, capsys):
    out = tmp_path / "panel"
    assert (
        main(
            [
                "panel",
                "--out",
                str(out),
                "--algorithms",
                "s-ac",
                "--experiments",
                "1",
                "--tasks",
                "dc_pendulum,pendulum_v1",
                "--trials",
                "2",
                "--jobs",
                "1",
                "--no-progress",
            ]
        )
        == 0
    )
    assert sorted(p.name for p in out.iterdir()) == ["dc_pendulum", "pendulum_v1"]
    assert (out / "pendulum_v1" / "summary.json").is_file()
    task = dataclasses.replace(panel.TASKS_BY_NAME["pendulum_v1"], goal_trial=2, goal=-1e9)
    (row,) = panel.panel_rows(task, [out / "pendulum_v1"])
    assert row["learner"] == "s-ac" and row["reached"] == 1 and row["env_steps"] == 400
    assert np.isfinite(row["greedy"]["iqm"])
    # the CPU of the experiment over the 400 control steps it learned from (Pendulum-v1: repeat 1)
    assert row["ms_per_control_step"] == pytest.approx(1000 * row["cpu_s_per_experiment"] / 400)
    assert "| s-ac | 1 |" in panel.format_rows(task, [row])


def test_an_unknown_task_is_refused_naming_the_panels(capsys):
    assert main(["panel", "--out", "x", "--tasks", "cartpole"]) == 2
    assert "unknown panel task 'cartpole'" in capsys.readouterr().err

"""The experiments layer on a task that is not the pendulum: the test-only ``toy`` domain (n = 4
state dimensions, one periodic; m = 2 actions; trials of 10 steps of 0.02 s), registered in
``rmac_mj.tasks`` by the ``toy`` fixture (tests/conftest.py). Nothing in the layer knows it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rmac_mj import tasks
from rmac_mj.agents import make_agent
from rmac_mj.bench import (
    env_step_us,
    format_table,
    learner_step_us,
    llr_query_insert_us,
    physics_step_us,
    step_costs,
)
from rmac_mj.evaluation import summary_table
from rmac_mj.experiments import Protocol, RunOptions, run_protocol
from rmac_mj.figures import policy_slice
from rmac_mj.results import ResultStore, load_snapshot
from rmac_mj.rollout import (
    action_space_of,
    n_sub_steps,
    run_trial,
    state_of,
    state_space_of,
    steps_per_trial,
    trial_seconds,
)
from rmac_mj.videos import draw_overlay, render_episode
from rmac_mj.videos.render import short_label  # the overlay's own label parsing

TINY = dict(
    domain="toy",
    task="settle",
    task_kwargs={"start_noise": 0.0},
    experiments=2,
    trials=3,
    snapshot_trials=(1,),
    evaluate_every=1,
)


def test_spaces_and_trial_length_come_from_the_task(toy):
    env = tasks.load("toy", "settle")
    space, actions = state_space_of(env), action_space_of(env)
    assert space.dim == 4 and list(space.periodic) == [True, False, False, False]
    np.testing.assert_array_equal(space.low, [-np.pi, -1.0, -20.0, -5.0])
    np.testing.assert_array_equal(space.input_weights, [1.0, 1.0, 0.1, 0.2])
    np.testing.assert_array_equal(actions.low, [-1.0, -2.0])
    np.testing.assert_array_equal(actions.input_weights, [1.0, 0.5])
    assert steps_per_trial(env) == 10 and n_sub_steps(env) == 2
    assert trial_seconds(env) == pytest.approx(0.2)
    x = state_of(env.reset().observation, env.task.learner_state)
    assert x.shape == (4,) and x[2] == x[3] == 0.0  # [theta, s, omega, v]: position, then velocity


def test_rmac_has_four_vertices_and_weightings_from_the_task(toy):
    env = tasks.load("toy", "settle", task_kwargs={"random": 0})
    agent = make_agent("rmac", state_space_of(env), action_space_of(env), seed=0)
    assert {tuple(v) for v in agent.vertices} == {(1, 2), (1, -2), (-1, 2), (-1, -2)}
    assert agent.config.critic.weights == agent.config.reference.weights == (1.0, 1.0, 0.1, 0.2)
    assert agent.config.process.weights == (1.0, 1.0, 0.1, 0.2, 1.0, 0.5)
    returns = [run_trial(env, agent) for _ in range(3)]
    assert all(np.isfinite(returns)) and agent.process.n_samples_ == 30
    u = agent.greedy_action(state_of(env.reset().observation, env.task.learner_state))
    assert u.shape == (2,) and np.all(np.abs(u) <= [1, 2])


def test_sac_tiles_the_four_dimensional_box(toy):
    env = tasks.load("toy", "settle", task_kwargs={"random": 0})
    agent = make_agent("s-ac", state_space_of(env), action_space_of(env), seed=0)
    # 7 tiles per dimension: the periodic angle 7, the three bounded dimensions 7 + 1 (see tile_coding).
    assert agent.coder.num_features == 16 * 7 * 8 * 8 * 8 and agent.actor_.shape[1] == 2
    first = run_trial(env, agent)
    assert np.isfinite(first) and np.any(agent.actor_ != 0)


@pytest.mark.slow
def test_runner_summary_and_figure_use_the_tasks_trial_length(toy, tmp_path, monkeypatch):
    from rmac_mj.solvers import optimum

    monkeypatch.setattr(optimum, "run_optimum", lambda protocol, log=None: -1.0)
    protocol = Protocol(**TINY)
    summary = run_protocol(protocol, tmp_path, RunOptions(jobs=1, progress=False, references=True))
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    assert on_disk["trial_seconds"] == pytest.approx(0.2)
    for algorithm in ("rmac", "s-ac"):
        row = summary[algorithm]
        assert row["trials"] == 3 and row["first_10min_trials"] == 3  # 3 trials end within 10 min
        curve = np.asarray(row["mean_return_per_trial"])
        final = curve.mean()
        first = int(np.argmax(np.abs(curve - final) <= 0.1 * abs(final))) + 1
        assert row["minutes_to_90pct"] == pytest.approx(first * 0.2 / 60)
        assert row["stuck_below"] == -2.0 and row["stuck_experiments"] == 2  # the toy costs more
        assert len(row["greedy_return_per_eval"]) == 3
    assert (tmp_path / "fig2_learning_curves.png").is_file()
    assert "one trial = 0.2 s" in summary_table(summary)
    agent, meta = load_snapshot(ResultStore(tmp_path).snapshot_path("rmac", 1, 3))
    assert (meta["domain"], meta["task"]) == ("toy", "settle") and agent.vertices.shape == (4, 2)
    env = protocol.make_environment()
    outcome_greedy = np.load(ResultStore(tmp_path).curve_path("rmac", 1))["greedy_returns"][-1]
    assert run_trial(env, agent, learn=False) == pytest.approx(outcome_greedy, abs=1e-9)


def test_the_runner_asks_the_task_for_what_it_declares(toy, tmp_path):
    """A new task declares its demonstrators and plot hints in its own module (toy_domain.KNOWLEDGE)
    and the experiments use them without naming it; it declares no reference, so none is computed."""
    protocol = Protocol(
        domain="toy",
        task="settle",
        algorithms=("rmac",),
        experiments=1,
        trials=2,
        prior="demo",
        prior_trials=2,
    )
    summary = run_protocol(
        protocol, tmp_path, RunOptions(jobs=1, progress=False, figures=False, references=True)
    )
    assert summary["plot_hints"] == {"return_margin": 0.5}
    assert summary["optimal_return"] is None and summary["exploration_floor"] is None
    curves = ResultStore(tmp_path).load_curves("rmac", 1)
    assert curves.demonstration_returns.shape == (1, 2)  # two trials of the toy's own demonstrator
    with pytest.raises(
        ValueError, match="no demonstrator 'expert' for toy/settle; available: demo"
    ):
        Protocol(domain="toy", task="settle", algorithms=("rmac",), prior="expert")


def test_protocol_refuses_an_unknown_task(toy):
    with pytest.raises(ValueError, match="unknown domain"):
        Protocol(domain="cartpole")
    with pytest.raises(ValueError, match="unknown task 'swingup' of domain 'toy'"):
        Protocol(domain="toy", task="swingup")


class Recorder:
    """A stand-in agent for policy maps: u = [x_i, x_j] of the plotted dims, V = sum(x)."""

    def __init__(self, dims):
        self.dims, self.states = dims, []
        self.action_space = action_space_of(tasks.load("toy", "settle"))

    def begin_greedy_trial(self):
        pass

    def greedy_action(self, x):
        self.states.append(np.array(x))
        return np.array([x[self.dims[0]], x[self.dims[1]]])

    def value(self, x):
        return float(np.sum(x))


def test_policy_maps_slice_through_the_anchor_over_the_tasks_box(toy):
    env = tasks.load("toy", "settle")
    learner_state = env.task.learner_state
    anchor = np.array([0.5, 0.25, 1.5, -0.5])
    agent = Recorder((1, 3))
    xs, ys, actions, values = policy_slice(
        agent, learner_state.low, learner_state.high, anchor, dims=(1, 3), resolution=(5, 4)
    )
    np.testing.assert_allclose(xs, np.linspace(-1, 1, 5))
    np.testing.assert_allclose(ys, np.linspace(-5, 5, 4))
    assert actions.shape == (4, 5, 2) and values.shape == (4, 5)
    states = np.array(agent.states)
    np.testing.assert_array_equal(states[:, [0, 2]], np.tile(anchor[[0, 2]], (20, 1)))
    np.testing.assert_allclose(actions[..., 0], np.tile(xs, (4, 1)))  # x axis: dims[0]
    np.testing.assert_allclose(actions[..., 1], np.tile(ys[:, None], (1, 5)))
    with pytest.raises(ValueError, match="dims"):
        policy_slice(agent, learner_state.low, learner_state.high, anchor, dims=(2, 2))


@pytest.mark.slow
def test_episode_render_records_the_tasks_state_and_action(toy):
    env = tasks.load("toy", "settle", task_kwargs={"start_noise": 0.0})  # every episode alike
    policy = lambda x: np.array([5.0, -0.5])  # noqa: E731 - the torque saturates at 1 N m
    coarse = render_episode(env, policy=policy, width=64, height=48, overlay=False)
    fine = render_episode(env, policy=policy, width=64, height=48, frames_per_step=2, overlay=False)
    assert coarse.states.shape == (11, 4) and coarse.actions.shape == (11, 2)
    np.testing.assert_array_equal(coarse.actions[1:], np.tile([1.0, -0.5], (10, 1)))
    assert fine.states.shape == (21, 4) and fine.fps == pytest.approx(100.0)
    np.testing.assert_array_equal(fine.states[::2], coarse.states)
    assert coarse.state_labels == env.task.learner_state.labels
    assert coarse.total_return == pytest.approx(run_trial(env, _PolicyAgent(policy), learn=False))
    text = draw_overlay(coarse)
    assert np.any(text != coarse.frames)
    assert short_label("cart speed v [m/s]") == ("v", "m/s")


class _PolicyAgent:
    def __init__(self, policy):
        self.policy = policy

    def begin_greedy_trial(self):
        pass

    def greedy_action(self, x):
        return self.policy(x)


def test_bench_measures_the_tasks_own_control_step(toy):
    on = {"domain": "toy", "task": "settle"}
    for value in (
        physics_step_us(20, 1, **on),
        env_step_us(20, 1, **on),
        llr_query_insert_us(20, 1, **on),
        learner_step_us("rmac", 1, warmup_trials=2, **on),
        learner_step_us("s-ac", 1, warmup_trials=2, **on),
    ):
        assert np.isfinite(value) and value > 0
    costs = step_costs(20, 1, **on)
    assert costs["physics_step_us"] > 0 and costs["env_step_us"] > 0
    report = {
        **costs,
        "llr_query_insert_us": 0.1,
        "sac_step_us": 0.1,
        "rmac_step_us": 0.1,
        "mlac_step_us": 0.1,
        "env_overhead_us": 0.1,
        "outside_physics_learner_us": 0.2,
        **on,
        "experiment_s": {},
        "steps_per_trial": 10,
        "protocol_projected_min": 1.0,
        "run": {
            "experiments_per_learner": 1,
            "trials": 1,
            "workers": 1,
            "steps": 20,
            "physics_s": 0.1,
            "wall_s": 1.0,
            "x_physics": 10.0,
            "cpu_s": None,
            "in_experiments_s": 0.5,
            "in_experiments_x_physics": 5.0,
        },
        "machine": {"cores": 1, "cpu": "x", "python": "3", "mujoco": "3"},
        "control_timestep_s": 0.02,
        "n_sub_steps": 2,
        "state_dim": 4,
    }
    table = format_table(report)
    assert (
        "(2 x mj_step)" in table and "toy/settle: control step 0.02 s" in table and "n=4" in table
    )


@pytest.mark.slow
def test_cli_reproduce_policy_and_render_on_the_toy(toy, tmp_path, capsys):
    from rmac_mj.cli import main

    out = tmp_path / "run"
    assert (
        main(
            [
                "reproduce",
                "--domain",
                "toy",
                "--task",
                "settle",
                "--experiments",
                "1",
                "--trials",
                "2",
                "--jobs",
                "1",
                "--no-optimal",
                "--no-progress",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert json.loads((out / "summary.json").read_text())["trial_seconds"] == pytest.approx(0.2)
    snapshot = out / "snapshots/rmac/exp_000/trial_0002.npz"
    assert (
        main(
            [
                "policy",
                str(snapshot),
                "--dims",
                "2,1",
                "--xlim=-2,2",
                "--resolution",
                "11",
                "--out",
                str(tmp_path / "pol"),
            ]
        )
        == 0
    )
    assert (tmp_path / "pol.png").is_file()
    assert main(["policy", str(snapshot), "--dims", "0,4"]) == 2
    assert "--dims" in capsys.readouterr().err
    assert (
        main(
            [
                "render",
                str(snapshot),
                "--out",
                str(tmp_path / "ep.gif"),
                "--width",
                "64",
                "--height",
                "48",
                "--frames-per-step",
                "2",
            ]
        )
        == 0
    )
    assert (tmp_path / "ep.gif").is_file()
    # The toy's agent cannot act on the pendulum: its state has 4 dimensions, the pendulum's 2.
    assert (
        main(
            [
                "render",
                str(snapshot),
                "--out",
                str(tmp_path / "x.gif"),
                "--domain",
                "dc_pendulum",
                "--task",
                "swingup",
            ]
        )
        == 2
    )
    assert "2 state and 1 action dimensions" in capsys.readouterr().err

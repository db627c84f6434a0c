"""An experiment stopped between two trials continues from its checkpoint exactly as if it had not
stopped; and a budget in environment steps ends experiments where the steps say."""

import dataclasses
import json
import pathlib

import numpy as np
import pytest

from rmac_mj.experiments import ExperimentSpec, Protocol, RunOptions, run_experiment, runner
from rmac_mj.experiments import checkpoint as checkpoints
from rmac_mj.results import ResultStore

SLIDER = f"{pathlib.Path(__file__).parents[1] / 'envs' / 'test_envs.py'}:make_slider"


class Stop(Exception):
    """Stands for a kill between two trials."""


def stopping_after(trial: int):
    def on_trial(algorithm, index, done, value, env_steps):
        if done == trial:
            raise Stop

    return on_trial


def assert_same_result(a, b):
    np.testing.assert_array_equal(a.returns, b.returns)
    np.testing.assert_array_equal(a.env_steps, b.env_steps)
    np.testing.assert_array_equal(a.greedy_trials, b.greedy_trials)
    np.testing.assert_array_equal(a.greedy_returns, b.greedy_returns)
    assert a.snapshots.keys() == b.snapshots.keys()
    for trial in a.snapshots:
        for key, value in a.snapshots[trial].items():
            assert value.tobytes() == b.snapshots[trial][key].tobytes(), (trial, key)


@pytest.mark.slow
@pytest.mark.parametrize(
    "algorithm, where",
    [
        ("s-ac", {}),
        ("rmac", {}),
        # Gymnasium's Pendulum-v1 starts anywhere: its np_random must come back too
        (
            "s-ac",
            {
                "env": "gymnasium:Pendulum-v1",
                "trial_steps": 20,
                "evaluate_starts": 0,
                "learner_state": {"action_cost": [0.001]},
            },
        ),
    ],
)
def test_a_stopped_experiment_continues_from_its_checkpoint_bit_for_bit(tmp_path, algorithm, where):
    protocol = Protocol(
        algorithms=(algorithm,),
        experiments=1,
        trials=6,
        snapshot_trials=(2, 5),
        evaluate_every=2,
        **where,
    )
    whole = run_experiment(ExperimentSpec(protocol, algorithm, 0))
    spec = ExperimentSpec(protocol, algorithm, 0, stream_to=str(tmp_path), checkpoint_seconds=0.0)
    with pytest.raises(Stop):
        run_experiment(spec, on_trial=stopping_after(3))
    store = ResultStore(tmp_path)
    assert store.checkpointed(algorithm) == {0: 3}  # written after every trial at 0 s
    assert store.snapshot_path(algorithm, 0, 2).is_file()  # the snapshot it had taken is kept
    continued = run_experiment(spec)
    assert_same_result(whole, continued)
    log = store.progress_path(algorithm, 0).read_text().splitlines()
    assert [line.split(",")[0] for line in log[1:]] == ["1", "2", "3", "4", "5", "6"]


def test_a_checkpoint_of_another_protocol_or_damaged_is_not_used(tmp_path):
    protocol = Protocol(algorithms=("s-ac",), experiments=1, trials=4, snapshot_trials=())
    spec = ExperimentSpec(protocol, "s-ac", 0, stream_to=str(tmp_path), checkpoint_seconds=0.0)
    with pytest.raises(Stop):
        run_experiment(spec, on_trial=stopping_after(2))
    path = ResultStore(tmp_path).checkpoint_path("s-ac", 0)
    other = Protocol(algorithms=("s-ac",), experiments=1, trials=4, snapshot_trials=(), seed=1)
    assert checkpoints.read(path, checkpoints.protocol_digest(other.as_dict())) is None
    # a resume that adds experiments keeps the checkpoints of the first ones
    grown = Protocol(algorithms=("s-ac",), experiments=3, trials=4, snapshot_trials=())
    assert checkpoints.read(path, checkpoints.protocol_digest(grown.as_dict())) is not None
    path.write_bytes(b"not an npz")
    whole = run_experiment(ExperimentSpec(protocol, "s-ac", 0))
    np.testing.assert_array_equal(run_experiment(spec).returns, whole.returns)  # from trial 1


@pytest.mark.slow
def test_a_saved_experiment_leaves_no_checkpoint_and_the_run_resumes_from_one(
    tmp_path, monkeypatch
):
    protocol = Protocol(algorithms=("s-ac",), experiments=1, trials=5, snapshot_trials=(2,))
    whole = runner.run_protocol(
        protocol, tmp_path / "whole", RunOptions(jobs=1, progress=False, figures=False)
    )

    def stop_at_3(item, on_trial=None):  # the worker dies after trial 3 (a kill, a lost machine)
        tag, spec = item
        with pytest.raises(Stop):
            run_experiment(dataclasses.replace(spec, checkpoint_seconds=0.0), stopping_after(3))
        raise KeyboardInterrupt

    out = tmp_path / "stopped"
    monkeypatch.setattr(runner, "run_tagged", stop_at_3)
    with pytest.raises(KeyboardInterrupt):
        runner.run_protocol(protocol, out, RunOptions(jobs=1, progress=False, figures=False))
    monkeypatch.undo()
    assert ResultStore(out).checkpointed("s-ac") == {0: 3} and not ResultStore(out).finished("s-ac")
    summary = runner.run_protocol(
        protocol, out, RunOptions(jobs=1, resume=True, progress=False, figures=False)
    )
    assert summary["s-ac"]["mean_return_per_trial"] == whole["s-ac"]["mean_return_per_trial"]
    assert not ResultStore(out).checkpoint_path("s-ac", 0).exists()


def test_a_budget_in_environment_steps_ends_each_experiment_where_its_steps_reach_it(tmp_path):
    # the slider ends an episode when it leaves its rail: trials of different lengths
    protocol = Protocol(
        env=SLIDER,
        trial_steps=30,
        control_timestep=0.1,
        action_repeat=2,
        algorithms=("s-ac",),
        experiments=3,
        trials=1000,
        steps=150,
        evaluate_every=1,
        snapshot_trials=(1,),
    )
    summary = runner.run_protocol(
        protocol, tmp_path, RunOptions(jobs=1, progress=False, figures=False)
    )
    store = ResultStore(tmp_path)
    curves = store.load_curves("s-ac", 3)
    for row, steps in zip(curves.returns, curves.env_steps):
        ran = int(np.isfinite(row).sum())
        assert steps[ran - 1] >= 150 and (
            ran == 1 or steps[ran - 2] < 150
        )  # the last runs to its end
        assert np.all(np.diff(steps[:ran]) <= 2 * 30)  # a trial: at most 30 steps of 2
    row = summary["s-ac"]
    assert row["env_steps_per_experiment"] == [int(s[np.isfinite(s)][-1]) for s in curves.env_steps]
    assert row["trials_per_experiment"] == list(curves.trials_run)
    # the times are the steps that ran, not trials of 30 x 2 x 0.1 s
    ran_minutes = np.array(row["env_steps_per_experiment"]) * 0.1 / 60.0
    np.testing.assert_allclose(row["simulated_minutes_per_experiment"], ran_minutes)
    assert row["cpu_s_per_simulated_minute"] == pytest.approx(
        row["experiment_cpu_s_mean"] / ran_minutes.mean()
    )
    lines = store.returns_path.read_text().splitlines()
    assert lines[0].endswith(",env_steps") and len(lines) == 1 + sum(curves.trials_run)
    # a resume trusts the saved experiments as they are (their lengths differ)
    again = runner.run_protocol(
        protocol, tmp_path, RunOptions(jobs=1, resume=True, progress=False, figures=False)
    )
    assert again["s-ac"]["env_steps_per_experiment"] == row["env_steps_per_experiment"]


def test_a_directory_written_before_env_steps_were_counted_still_resumes_and_summarises(tmp_path):
    protocol = Protocol(algorithms=("s-ac",), experiments=2, trials=3, snapshot_trials=())
    runner.run_protocol(protocol, tmp_path, RunOptions(jobs=1, progress=False, figures=False))
    store = ResultStore(tmp_path)
    for index in range(2):  # as an older version wrote them: no env_steps, no steps field
        path = store.curve_path("s-ac", index)
        with np.load(path) as data:
            arrays = {k: data[k] for k in data.files if k != "env_steps"}
        np.savez(path, **arrays)
    config = json.loads(store.config_path.read_text())
    del config["protocol"]["steps"]
    store.config_path.write_text(json.dumps(config))
    assert store.holds_finished(protocol)
    summary = runner.run_protocol(
        protocol, tmp_path, RunOptions(jobs=1, resume=True, progress=False, figures=False)
    )
    assert (
        summary["s-ac"]["minutes_to_90pct"] is not None
        and "env_steps_per_trial" not in summary["s-ac"]
    )
    assert store.returns_path.read_text().splitlines()[1].endswith(",")  # steps not known


def test_fig2_reads_against_environment_steps_and_refuses_a_summary_without_them(tmp_path):
    from rmac_mj.figures import learning_curves_figure

    protocol = Protocol(
        env=SLIDER,
        trial_steps=30,
        control_timestep=0.1,
        algorithms=("s-ac",),
        experiments=2,
        trials=1000,
        steps=60,
        evaluate_every=1,
        snapshot_trials=(),
    )
    summary = runner.run_protocol(
        protocol, tmp_path, RunOptions(jobs=1, progress=False, figures=False)
    )
    figure = learning_curves_figure({"run": summary}, x_axis="env_steps")
    line = figure.axes[0].get_lines()[0]
    np.testing.assert_array_equal(line.get_xdata(), summary["s-ac"]["env_steps_per_trial"])
    assert figure.axes[0].get_xlabel() == "environment steps"
    older = {
        **summary,
        "s-ac": {
            k: v
            for k, v in summary["s-ac"].items()
            if not k.startswith(("env_steps", "greedy_eval_env"))
        },
    }
    with pytest.raises(ValueError, match="holds no environment steps"):
        learning_curves_figure({"run": older}, x_axis="env_steps")
    learning_curves_figure({"run": older})  # against minutes, as before

"""Figures: Fig. 2's time axis is each summary's own trial length (old summaries still plot); Fig. 2 is
readable for small runs (axes follow the curves, legends, smoothing, notes); policy maps on shared
scales with the greedy trajectory."""

import numpy as np
import pytest

from rmac_mj.evaluation import summarise, summary_table
from rmac_mj.figures import MapView, greedy_trajectory, plots, policies_figure


def old_summary(trial_seconds: float, trials: int = 4) -> dict:
    """A summary.json as the first version wrote it (no first_10min_trials, no stuck_below)."""
    curve = np.linspace(-3000.0, -1000.0, trials)
    row = {
        "experiments": 2,
        "trials": trials,
        "mean_return_per_trial": curve.tolist(),
        "ci95_low_per_trial": (curve - 50).tolist(),
        "ci95_high_per_trial": (curve + 50).tolist(),
        "final_return_mean": -1000.0,
        "final_return_ci95": [-1050.0, -950.0],
        "final_return_per_experiment": [-1000.0, -1000.0],
        "minutes_to_90pct": 0.2,
        "mean_return_first_10min": -2000.0,
        "stuck_experiments": 0,
        "greedy_eval_trials": [2, 4],
        "greedy_return_per_eval": [-1500.0, -900.0],
    }
    return {
        "paper_protocol": False,
        "optimal_return": -748.1,
        "trial_seconds": trial_seconds,
        "protocol": {},
        "rmac": row,
    }


@pytest.fixture
def drawn(monkeypatch):
    """The figures plot_learning_curves draws, kept instead of written."""
    figures = []
    monkeypatch.setattr(
        plots, "save_figure", lambda fig, stem, formats=("png", "pdf"): figures.append(fig)
    )
    return figures


def test_each_summary_uses_its_own_trial_length(drawn):
    plots.plot_learning_curves(
        {"pendulum": old_summary(3.0), "arm": old_summary(0.05 * 60 / 2)}, "unused"
    )
    ax = drawn[0].axes[0]
    curves = [line for line in ax.get_lines() if line.get_label().endswith("(mean of 2)")]
    assert [line.get_label() for line in curves] == [
        "pendulum: RMAC (mean of 2)",
        "arm: RMAC (mean of 2)",
    ]
    np.testing.assert_allclose(curves[0].get_xdata(), np.arange(1, 5) * 3.0 / 60)
    np.testing.assert_allclose(curves[1].get_xdata(), np.arange(1, 5) * 1.5 / 60)
    assert ax.get_xlabel() == "time [min] (simulated)"  # two trial lengths: none is named


def test_one_summary_names_its_trial_length_and_an_old_one_still_tabulates(drawn):
    summary = old_summary(0.2)
    plots.plot_learning_curves({"toy": summary}, "unused", optimal_return=summary["optimal_return"])
    assert drawn[0].axes[0].get_xlabel() == "time [min] (simulated; one trial = 0.2 s)"
    greedy = [line for line in drawn[0].axes[0].get_lines() if "greedy" in line.get_label()]
    np.testing.assert_allclose(greedy[0].get_xdata(), np.array([2, 4]) * 0.2 / 60)
    assert "one trial = 0.2 s" in summary_table(summary)


def test_a_summary_without_trial_length_is_refused_by_name(drawn):
    summary = old_summary(3.0)
    del summary["trial_seconds"]
    with pytest.raises(ValueError, match="trial_seconds"):
        plots.plot_learning_curves({"x": summary}, "unused")


def _summary(n_experiments, seed=0, level=-1000.0, **protocol):
    rng = np.random.default_rng(seed)
    trials = np.arange(1, 101)
    curves = level - 3000.0 * np.exp(-trials / 20.0) + rng.normal(0, 40, (n_experiments, 100))
    curves[0] -= 20000.0 * (
        n_experiments < 5
    )  # one bad experiment: a huge interval when n is small
    return {
        "trial_seconds": 3.0,
        "protocol": protocol,
        "rmac": summarise(curves, trial_seconds=3.0).as_dict(),
        "s-ac": summarise(curves - 50.0, trial_seconds=3.0).as_dict(),
    }


def test_axes_follow_the_curves_not_the_bands():
    summary = _summary(2)
    fig = plots.learning_curves_figure({"run": summary})
    means = np.concatenate([summary[a]["mean_return_per_trial"] for a in ("rmac", "s-ac")])
    low, high = fig.axes[0].get_ylim()
    span = means.max() - means.min()
    assert (
        means.min() - 0.1 * span <= low < means.min()
        and means.max() < high <= means.max() + 0.1 * span
    )
    assert high < 0  # the band reaches far above 0; every reward is negative
    assert summary["rmac"]["ci95_high_per_trial"][50] > 0


@pytest.mark.slow
def test_every_panel_has_a_legend_and_a_trial_axis():
    fig = plots.learning_curves_figure({"run": _summary(6)}, optimal_return=-748.0)
    panels = [
        ax for ax in fig.axes if ax.get_label() != "<colorbar>" and ax.get_legend() is not None
    ]
    assert len(panels) == 2
    secondary = [child for ax in panels for child in ax.child_axes]
    assert len(secondary) == 2 and all(s.get_xlabel().startswith("trial") for s in secondary)
    # minute 1 is trial 20 (3 s trials): the trial axis spans 20 times the minutes
    fig.canvas.draw()
    np.testing.assert_allclose(secondary[0].get_xlim(), 20.0 * np.array(panels[0].get_xlim()))


def test_smoothing_is_a_running_mean_stated_in_the_legend():
    np.testing.assert_allclose(plots.running_mean([1, 2, 3, 4, 5], 3), [1.5, 2, 3, 4, 4.5])
    np.testing.assert_allclose(plots.running_mean([1, 2, 3], 1), [1, 2, 3])
    fig = plots.learning_curves_figure({"run": _summary(6)}, smooth=5)
    for ax in fig.axes[:2]:
        assert ax.get_legend().get_title().get_text() == "running mean over 5 trials"
    line = fig.axes[0].get_lines()[0]
    np.testing.assert_allclose(
        line.get_ydata(), plots.running_mean(_summary(6)["rmac"]["mean_return_per_trial"], 5)
    )
    with pytest.raises(ValueError, match="smooth"):
        plots.learning_curves_figure({"run": _summary(6)}, smooth=0)


@pytest.mark.slow
def test_the_detail_legend_covers_none_of_the_curves():
    fig = plots.learning_curves_figure({"run": _summary(6)}, optimal_return=-1000.0)
    fig.canvas.draw()
    detail = fig.axes[1]
    legend = detail.get_legend().get_window_extent()
    panel = detail.get_window_extent()
    assert legend.x0 >= panel.x1  # beside the panel, not over the curves' ends


@pytest.mark.slow
def test_profiles_of_too_few_experiments_draw_no_bands_and_say_why():
    def profile(n):
        rng = np.random.default_rng(0)
        fig = plots.performance_profiles_figure(
            {("", "rmac"): rng.normal(-900, 30, n), ("", "s-ac"): rng.normal(-950, 30, n)}
        )
        return fig, [t.get_text() for t in fig.texts]

    few, notes = profile(2)
    assert len(few.axes[0].collections) == 0 or all(
        len(c.get_paths()) == 0 or not np.isfinite(c.get_paths()[0].vertices).all()
        for c in few.axes[0].collections
    )
    assert any(text.startswith("2 experiments: too few for bands") for text in notes)
    enough, notes = profile(6)
    assert notes == [] and len(enough.axes[0].collections) == 2


def test_few_experiments_are_flagged_in_the_figure():
    def notes(n):
        fig = plots.learning_curves_figure({"run": _summary(n)})
        return [t.get_text() for t in fig.texts]

    assert any("4 experiments per learner" in text for text in notes(4))
    assert notes(5) == []


def test_compare_keeps_a_colour_per_learner_and_a_line_style_per_run():
    fig = plots.learning_curves_figure({"a/run": _summary(6), "b/run": _summary(6, seed=1)})
    lines = {line.get_label(): line for line in fig.axes[0].get_lines()}
    a, b = lines["a/run: RMAC (mean of 6)"], lines["b/run: RMAC (mean of 6)"]
    assert a.get_color() == b.get_color() and a.get_linestyle() != b.get_linestyle()
    assert lines["a/run: S-AC (mean of 6)"].get_color() != a.get_color()
    assert lines["a/run: S-AC (mean of 6)"].get_linestyle() == a.get_linestyle()


class _MapAgent:
    """A stand-in with a given value function: V(x) = scale * cos(phi), u = clip(phi)."""

    def __init__(self, scale):
        from rmac_mj.agents import ActionSpace

        self.scale = scale
        self.action_space = ActionSpace(low=[-3.0], high=[3.0])

    def policy(self, states):
        return np.clip(states[:, :1], -3, 3)

    def value(self, x):
        return self.scale * np.cos(x[0])


def _pendulum():
    from rmac_mj import tasks
    from rmac_mj.rollout import learner_state_of

    env = tasks.load("dc_pendulum", "swingup", task_kwargs={"time_limit": 0.3})
    return env, learner_state_of(env)


def test_side_by_side_policies_share_their_colour_scales():
    _, learner_state = _pendulum()
    fig = policies_figure(
        [(_MapAgent(10.0), {"algorithm": "rmac"}), (_MapAgent(1000.0), {"algorithm": "s-ac"})],
        learner_state,
        MapView(anchor=[np.pi, 0.0], resolution=9),
    )
    images = [ax.images[0] for ax in fig.axes if ax.images]
    assert len(images) == 4
    policy_limits = {image.get_clim() for image in images if image.get_cmap().name == "RdBu_r"}
    value_limits = {image.get_clim() for image in images if image.get_cmap().name == "viridis"}
    assert policy_limits == {(-3.0, 3.0)} and value_limits == {(-1000.0, 1000.0)}
    titles = [ax.get_title() for ax in fig.axes]
    assert any("$V(x)$" in title for title in titles) and any(
        r"$\pi(x)$" in title for title in titles
    )


def test_the_greedy_trajectory_is_drawn_from_the_start_state():
    from scripted import energy_pump_agent  # tests/ is on sys.path

    env, learner_state = _pendulum()
    states, total = greedy_trajectory(env, energy_pump_agent())
    assert states.shape == (11, 2) and total < 0
    np.testing.assert_allclose(states[0], [-np.pi, 0.0])
    agent = _MapAgent(1.0)
    agent.begin_greedy_trial = lambda: None
    agent.greedy_action = lambda x: np.array([3.0])
    fig = policies_figure(
        [(agent, {"algorithm": "rmac"})],
        learner_state,
        MapView(anchor=[np.pi, 0.0], resolution=5),
        envs=[env],
    )
    lines = [
        line
        for line in fig.axes[0].get_lines()
        if "greedy trial from $x_0$" in str(line.get_label())
    ]
    assert len(lines) == 1


@pytest.mark.slow
def test_the_readme_figure_is_redrawn_from_a_run_by_its_script(tmp_path):
    import importlib.util
    import json
    import pathlib

    path = pathlib.Path(__file__).resolve().parents[2] / "scripts" / "readme_figures.py"
    spec = importlib.util.spec_from_file_location("readme_figures", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    run = tmp_path / "paper"
    run.mkdir()
    summary = {**_summary(6), "optimal_return": -748.0, "exploration_floor": -870.0}
    (run / "summary.json").write_text(json.dumps(summary))
    assert script.main([str(run), "--draw-only", "--figure", str(tmp_path / "fig2.png")]) == 0
    assert (tmp_path / "fig2.png").stat().st_size > 10_000 and not (tmp_path / "fig2.pdf").exists()

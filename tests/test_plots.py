"""Fig. 2 from summaries: the time axis is each summary's own trial length; old summaries still plot."""

import numpy as np
import pytest

from rmac_mj.experiments import plots, runner


def old_summary(trial_seconds: float, trials: int = 4) -> dict:
    """A summary.json as the first version wrote it (no first_10min_trials, no stuck_below)."""
    curve = np.linspace(-3000.0, -1000.0, trials)
    row = {"experiments": 2, "trials": trials, "mean_return_per_trial": curve.tolist(),
           "ci95_low_per_trial": (curve - 50).tolist(), "ci95_high_per_trial": (curve + 50).tolist(),
           "final_return_mean": -1000.0, "final_return_ci95": [-1050.0, -950.0],
           "final_return_per_experiment": [-1000.0, -1000.0], "minutes_to_90pct": 0.2,
           "mean_return_first_10min": -2000.0, "stuck_experiments": 0, "greedy_eval_trials": [2, 4],
           "greedy_return_per_eval": [-1500.0, -900.0]}
    return {"paper_protocol": False, "optimal_return": -748.1, "trial_seconds": trial_seconds,
            "protocol": {}, "rmac": row}


@pytest.fixture
def drawn(monkeypatch):
    """The figures plot_learning_curves draws, kept instead of written."""
    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, stem, formats=("png", "pdf"): figures.append(fig))
    return figures


def test_each_summary_uses_its_own_trial_length(drawn):
    plots.plot_learning_curves({"pendulum": old_summary(3.0), "arm": old_summary(0.05 * 60 / 2)},
                               "unused")
    ax = drawn[0].axes[0]
    curves = [line for line in ax.get_lines() if line.get_label().endswith("(mean of 2)")]
    assert [line.get_label() for line in curves] == ["pendulum: RMAC (mean of 2)",
                                                     "arm: RMAC (mean of 2)"]
    np.testing.assert_allclose(curves[0].get_xdata(), np.arange(1, 5) * 3.0 / 60)
    np.testing.assert_allclose(curves[1].get_xdata(), np.arange(1, 5) * 1.5 / 60)
    assert ax.get_xlabel() == "time [min] (simulated)"  # two trial lengths: none is named


def test_one_summary_names_its_trial_length_and_an_old_one_still_tabulates(drawn):
    summary = old_summary(0.2)
    plots.plot_learning_curves({"toy": summary}, "unused", optimal_return=summary["optimal_return"])
    assert drawn[0].axes[0].get_xlabel() == "time [min] (simulated; one trial = 0.2 s)"
    greedy = [line for line in drawn[0].axes[0].get_lines() if "greedy" in line.get_label()]
    np.testing.assert_allclose(greedy[0].get_xdata(), np.array([2, 4]) * 0.2 / 60)
    assert "one trial = 0.2 s" in runner.summary_table(summary)


def test_a_summary_without_trial_length_is_refused_by_name(drawn):
    summary = old_summary(3.0)
    del summary["trial_seconds"]
    with pytest.raises(ValueError, match="trial_seconds"):
        plots.plot_learning_curves({"x": summary}, "unused")

"""Learning-curve metrics against hand-computed values, the end-of-run report; atomic writes."""

import json

import numpy as np
import pytest

from rmac_mj.evaluation import (
    LearnerSummary,
    compare_final_returns,
    confidence_interval,
    first_reaching,
    minutes_to_within,
    report,
    stuck_threshold,
    summarise,
    trials_in,
    within_optimal,
)
from rmac_mj.results import write_atomic, write_json, write_npz


def test_confidence_interval_by_hand():
    samples = np.array([[1.0, 10.0], [2.0, 10.0], [3.0, 10.0], [6.0, 10.0]])
    mean, low, high = confidence_interval(samples)
    # column 0: mean 3, sample std sqrt(14/3), t(0.975, 3) = 3.182446305284263
    half = 3.182446305284263 * np.sqrt(14 / 3) / 2
    np.testing.assert_allclose(mean, [3.0, 10.0])
    np.testing.assert_allclose(low, [3.0 - half, 10.0])
    np.testing.assert_allclose(high, [3.0 + half, 10.0])


def test_confidence_interval_of_one_sample_is_undefined():
    mean, low, high = confidence_interval(np.array([[4.0, 5.0]]))
    np.testing.assert_array_equal(mean, [4.0, 5.0])
    assert np.all(np.isnan(low)) and np.all(np.isnan(high))


def test_minutes_to_within_ten_percent_of_final_level():
    curve = np.concatenate([np.full(20, -3000.0), np.full(10, -1150.0), np.full(70, -1000.0)])
    # final level -1000; -1150 is 15% away, so the first trial within 10% is trial 31 (1.55 min)
    assert minutes_to_within(curve, trial_seconds=3.0) == pytest.approx(31 * 3 / 60)
    # The trial length is the task's: trials of 0.2 s put trial 31 at 6.2 s.
    assert minutes_to_within(curve, trial_seconds=0.2) == pytest.approx(31 * 0.2 / 60)
    with pytest.raises(ValueError, match="trial_seconds"):
        minutes_to_within(curve, trial_seconds=0.0)


def test_summary_keys_shapes_and_stuck_count():
    rng = np.random.default_rng(0)
    returns = np.vstack([np.linspace(-3000, -1000, 300), np.linspace(-3000, -1800, 300)])
    returns = returns + rng.normal(0, 1, returns.shape)
    greedy = np.array([[-2000.0, -900.0], [-2500.0, -1700.0]])
    summary = summarise(returns, greedy, [100, 200], optimal_return=-800.0, trial_seconds=3.0)
    assert summary.experiments == 2 and summary.trials == 300
    for key in ("mean_return_per_trial", "ci95_low_per_trial", "ci95_high_per_trial"):
        assert len(getattr(summary, key)) == 300
    assert summary.stuck_below == -1600.0 and summary.stuck_experiments == 1
    finals = returns[:, -50:].mean(axis=1)
    assert summary.final_return_mean == pytest.approx(finals.mean())
    assert summary.gap_to_optimal == pytest.approx(-800.0 - finals.mean())
    assert summary.mean_return_first_10min == pytest.approx(returns[:, :200].mean())
    assert summary.first_10min_trials == 200
    assert summary.greedy_return_per_eval == pytest.approx([-2250.0, -1300.0])
    json.dumps(summary.as_dict(), allow_nan=False)  # valid JSON, no NaN


def test_greedy_trial_within_reaches_the_levels_of_issue_23():
    # -748 is the swing-up's near-optimal return: within 20% is -897.6, within 10% -822.8
    assert within_optimal(-748.0, 0.2) == pytest.approx(-897.6)
    assert within_optimal(-748.0, 0.1) == pytest.approx(-822.8)
    greedy = np.array([[-1000.0, -870.0, -850.0, -700.0], [-900.0, -860.0, -800.0, -940.0]])
    trials = [2, 4, 6, 8]
    # mean greedy -950, -865, -825, -820: -897.6 first at trial 4, -822.8 first at trial 8 (the
    # single experiment above -822.8 at trial 6 does not count: the mean does)
    assert first_reaching(greedy.mean(axis=0), trials, -897.6) == 4
    assert first_reaching(greedy.mean(axis=0), trials, -822.8) == 8
    assert first_reaching(greedy.mean(axis=0), trials, -825.0) == 6  # at the level counts
    assert first_reaching(greedy.mean(axis=0), trials, -800.0) is None
    summary = summarise(
        np.full((2, 8), -1000.0), greedy, trials, optimal_return=-748.0, trial_seconds=3.0
    )
    assert summary.greedy_trial_within_20pct == 4 and summary.greedy_trial_within_10pct == 8
    assert (
        "greedy_trial_within_10pct"
        not in summarise(np.full((2, 8), -1000.0), greedy, trials, trial_seconds=3.0).as_dict()
    )


def test_first_minutes_and_stuck_follow_the_task_and_the_reference():
    returns = np.tile(np.arange(1.0, 401.0), (2, 1)) * -1.0
    # 6 s trials: the first 10 minutes are 100 trials; 0.05 s x 60 = 3 s trials: 200.
    six = summarise(returns, trial_seconds=6.0)
    assert six.first_10min_trials == 100
    assert six.mean_return_first_10min == pytest.approx(-50.5)
    assert trials_in(10, 0.05 * 60) == 200 and trials_in(10, 0.03 * 100) == 200
    assert six.minutes_to_90pct == pytest.approx(
        minutes_to_within(returns[0], window=50, trial_seconds=6.0)
    )
    assert six.stuck_below is None and six.stuck_experiments is None  # no reference
    assert stuck_threshold(-748.0) == -1496.0 and stuck_threshold(10.0) == 0.0


def test_write_atomic_leaves_nothing_behind_on_failure(tmp_path):
    target = tmp_path / "file.json"
    write_json(target, {"a": 1})

    def fail(handle):
        handle.write(b"half")
        raise RuntimeError("killed")

    with pytest.raises(RuntimeError):
        write_atomic(target, fail)
    assert json.loads(target.read_text()) == {"a": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["file.json"]


def test_result_files_honour_the_umask(tmp_path):
    """Atomic writes must not leave results private (mkstemp's 0600) on a shared machine."""
    import os
    import stat

    old = os.umask(0o022)
    try:
        paths = [
            write_json(tmp_path / "a.json", {"x": 1}),
            write_npz(tmp_path / "b.npz", x=np.zeros(2)),
        ]
    finally:
        os.umask(old)
    for path in paths:
        mode = stat.S_IMODE(path.stat().st_mode)
        assert mode == 0o644, oct(mode)  # group- and other-readable, like open(path, "w")
    old = os.umask(0o077)
    try:
        private = write_json(tmp_path / "c.json", {"x": 1})
    finally:
        os.umask(old)
    assert stat.S_IMODE(private.stat().st_mode) == 0o600


def _welch_p_by_hand(x, y):
    from scipy import stats

    vx, vy = np.var(x, ddof=1) / len(x), np.var(y, ddof=1) / len(y)
    t = (np.mean(x) - np.mean(y)) / np.sqrt(vx + vy)
    dof = (vx + vy) ** 2 / (vx**2 / (len(x) - 1) + vy**2 / (len(y) - 1))
    return 2 * stats.t.sf(abs(t), dof)


def test_final_returns_are_compared_with_welchs_t_test():
    rng = np.random.default_rng(1)
    rmac, sac = (
        -950 + rng.normal(0, 10, 8),
        -990 + rng.normal(0, 60, 12),
    )  # unequal spreads and sizes
    (test,) = compare_final_returns({"rmac": rmac, "s-ac": sac})
    assert test["p_value"] == pytest.approx(_welch_p_by_hand(rmac, sac), rel=1e-9)
    assert test["p_value"] < 0.05 and test["better"] == "rmac"
    assert "rmac better than s-ac" in report.describe_test(test)
    close = compare_final_returns(
        {"rmac": [-943.0, -990.0, -1010.0, -960.0], "s-ac": [-950.0, -930.0, -1000.0, -940.0]}
    )[0]
    assert close["p_value"] > 0.05 and close["better"] is None
    assert "not significant (p = " in report.describe_test(close)
    single = compare_final_returns({"rmac": [-900.0], "s-ac": [-950.0, -940.0]})[0]
    assert single["p_value"] is None and "no test possible" in report.describe_test(single)
    assert compare_final_returns({"rmac": rmac}) == []


def test_summary_table_states_significance_and_warns_of_few_experiments():
    summary_table = report.summary_table

    rng = np.random.default_rng(2)

    def summary(n):
        return {
            "rmac": summarise(-950 + rng.normal(0, 30, (n, 60)), trial_seconds=3.0).as_dict(),
            "s-ac": summarise(-990 + rng.normal(0, 30, (n, 60)), trial_seconds=3.0).as_dict(),
        }

    small, large = summary_table(summary(4)), summary_table(summary(5))
    assert "final returns" in small and "Welch" in small
    assert "4 experiments per learner" in small and "per learner" not in large


def test_a_summary_row_is_written_and_read_back_as_it_was():
    rng = np.random.default_rng(3)
    returns = -1000 + rng.normal(0, 50, (5, 40))
    greedy = np.array([[-2000.0, -900.0]] * 5)
    steps = np.cumsum(np.full((5, 40), 100.0), axis=1)
    plain = summarise(returns, trial_seconds=3.0)
    full = summarise(
        returns,
        greedy,
        [20, 40],
        optimal_return=-100.0,  # never reached: the trials within 20% and 10% are None
        trial_seconds=3.0,
        wall_times=np.ones(5),
        cpu_times=np.ones(5),
        env_steps=steps,
        env_step_seconds=0.03,
    )
    for summary in (plain, full):
        assert LearnerSummary.from_dict(json.loads(json.dumps(summary.as_dict()))) == summary
    row = full.as_dict()
    assert row["greedy_trial_within_10pct"] is None and row["greedy_trial_within_20pct"] is None
    assert row["env_steps_per_experiment"] == [4000] * 5 and "exploration_floor" not in row
    # without evaluations, a reference or steps, their fields are not in the row at all
    assert not {"greedy_eval_trials", "greedy_trial_within_10pct", "gap_to_optimal"} & set(
        plain.as_dict()
    )
    assert "env_steps_per_trial" not in plain.as_dict()
    # a row written before a field existed reads it as None; what it holds beyond them is left out
    old = {k: v for k, v in plain.as_dict().items() if k != "final_window"}
    read = LearnerSummary.from_dict({**old, "retired_key": 1})
    assert read.final_window is None and read.final_return_mean == plain.final_return_mean

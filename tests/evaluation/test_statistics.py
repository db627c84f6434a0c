"""IQM, stratified-bootstrap intervals, probability of improvement and performance profiles, on
samples whose answers are known by hand."""

import numpy as np
import pytest

from rmac_mj.evaluation import (
    iqm,
    iqm_interval,
    pairwise_improvement,
    performance_profile,
    probability_of_improvement,
)
from rmac_mj.experiments import RunOptions


def test_iqm_is_the_mean_of_the_middle_half_and_ignores_outliers():
    assert iqm([0, 0, 1, 2, 3, 4, 100, 100]) == 2.5  # mean of 1, 2, 3, 4
    ten = np.arange(1.0, 11.0)
    assert iqm(ten) == 5.5  # 2 cut from each end: mean of 3..8
    wild = ten.copy()
    wild[0], wild[-1] = -1e9, 1e9
    assert iqm(wild) == 5.5


def test_bootstrap_interval_of_a_two_point_sample_is_its_range():
    """{0, 1}: a resample's mean is 0, 0.5 or 1 with probabilities 1/4, 1/2, 1/4, so the central 95%
    runs from 0 to 1 (with n = 2 the IQM trims nothing)."""
    estimate = iqm_interval([0.0, 1.0])
    assert (estimate.value, estimate.low, estimate.high) == (0.5, 0.0, 1.0)


def test_constant_scores_have_a_zero_width_interval():
    estimate = iqm_interval(np.full(10, -950.0))
    assert estimate.value == estimate.low == estimate.high == -950.0


def test_the_bootstrap_resamples_within_each_task():
    """Task A scores 0 five times, task B 1 five times: every stratified resample holds five of each,
    whose IQM is exactly 0.5; pooling the tasks before resampling would give a wide interval."""
    estimate = iqm_interval([np.zeros(5), np.ones(5)])
    assert (estimate.value, estimate.low, estimate.high) == (0.5, 0.5, 0.5)
    pooled = iqm_interval(np.r_[np.zeros(5), np.ones(5)])
    assert pooled.low < 0.4 and pooled.high > 0.6


def test_intervals_are_reproducible_and_cover_the_estimate():
    rng = np.random.default_rng(1)
    sample = rng.normal(-1000.0, 50.0, size=10)
    first, second = iqm_interval(sample), iqm_interval(sample)
    assert first == second
    assert first.low < first.value < first.high
    narrower = iqm_interval(sample, confidence=0.5)
    assert first.low < narrower.low < narrower.high < first.high


def test_probability_of_improvement_known_answers():
    x = np.arange(10.0)
    same = probability_of_improvement(x, x)
    assert same.value == 0.5 and same.low < 0.5 < same.high
    better = probability_of_improvement(x + 100.0, x)
    assert (better.value, better.low, better.high) == (1.0, 1.0, 1.0)
    assert probability_of_improvement(x, x + 100.0).value == 0.0
    # pairs of (1, 2) against (2, 0): 1 > 2 no, 1 > 0 yes, 2 = 2 half, 2 > 0 yes: 2.5 of 4
    assert probability_of_improvement([1.0, 2.0], [2.0, 0.0]).value == 0.625
    # over tasks: the mean of the tasks' probabilities
    assert probability_of_improvement([x + 100, x], [x, x]).value == 0.75


def test_pairwise_improvement_names_every_pair_once():
    table = pairwise_improvement(
        {"a": np.arange(5.0), "b": np.arange(5.0) + 10, "c": np.arange(5.0)}
    )
    assert list(table) == ["a > b", "a > c", "b > c"]
    assert table["a > b"] == {"value": 0.0, "ci95": [0.0, 0.0], "experiments": [5, 5]}
    assert table["a > c"]["value"] == 0.5


def test_performance_profile_is_the_fraction_above_each_threshold():
    fraction, low, high = performance_profile(np.arange(1.0, 11.0), [0.0, 5.0, 10.0])
    np.testing.assert_array_equal(fraction, [1.0, 0.5, 0.0])
    assert (low[0], high[0], low[2], high[2]) == (1.0, 1.0, 0.0, 0.0)  # nothing to resample there
    assert low[1] < 0.5 < high[1]


def test_one_experiment_gives_an_estimate_without_an_interval():
    estimate = iqm_interval([3.0])
    assert estimate.value == 3.0 and np.isnan(estimate.low)
    assert estimate.as_dict() == {"value": 3.0, "ci95": [None, None]}


@pytest.mark.parametrize("bad", [[], [1.0, np.nan], [[1.0, 2.0], []]])
def test_bad_scores_are_refused(bad):
    with pytest.raises(ValueError, match="scores"):
        iqm_interval(bad)


# -- in the results: summary.json, the end-of-run table, compare ----------------------------------


def test_summary_has_the_iqm_of_final_and_first_returns_and_the_cpu_per_simulated_minute():
    from rmac_mj.evaluation import summarise

    # 5 experiments of 100 three-second trials (5 simulated minutes); experiment i returns -100 i
    # in every trial, so its final and first-5-minute returns are -100 i.
    returns = -100.0 * np.arange(5)[:, None] * np.ones((1, 100))
    summary = summarise(returns, trial_seconds=3.0, cpu_times=np.full(5, 30.0))
    assert summary.final_return_iqm == -200.0  # the middle three of 0, -100, ..., -400
    low, high = summary.final_return_iqm_ci95
    assert low < -200.0 < high
    assert summary.first_5min_iqm == -200.0 and len(summary.first_5min_iqm_ci95) == 2
    assert summary.cpu_s_per_simulated_minute == 6.0  # 30 s of CPU for 5 simulated minutes


@pytest.mark.slow
def test_reproduce_and_compare_report_the_probability_of_improvement(tmp_path, capsys):
    from rmac_mj.cli import main
    from rmac_mj.experiments import Protocol, run_protocol

    for seed in (0, 1):
        protocol = Protocol(
            algorithms=("s-ac", "rmac"), experiments=2, trials=3, seed=seed, snapshot_trials=()
        )
        summary = run_protocol(
            protocol,
            tmp_path / f"seed{seed}",
            RunOptions(jobs=1, progress=False, figures=seed == 1),
        )
    pair = summary["probability_of_improvement"]["s-ac > rmac"]
    # 2 experiments each: withheld, saying why, not 1.00 [1.00, 1.00]
    assert pair["value"] is None and pair["ci95"] == [None, None] and pair["experiments"] == [2, 2]
    assert pair["withheld"].startswith("2 and 2 experiments: too few")
    assert (tmp_path / "seed1" / "performance_profiles.png").is_file()
    assert (
        main(
            [
                "compare",
                str(tmp_path / "seed0"),
                str(tmp_path / "seed1"),
                "--out",
                str(tmp_path / "both"),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "P(s-ac > rmac), the probability of improvement, withheld: 2 and 2 experiments" in out
    assert "P(seed0: rmac > seed1: rmac), the probability of improvement, withheld" in out  # across
    assert "P(s-ac > rmac) = " not in out and "[1.00, 1.00]" not in out
    assert (tmp_path / "both_profiles.png").is_file()


def test_the_probability_of_improvement_is_given_from_five_experiments_each():
    from rmac_mj.evaluation import describe_improvement, improvement

    table = improvement({"a": [1.0, 2.0, 3.0, 4.0, 5.0], "b": [0.0] * 5, "c": [9.0] * 4})
    assert table["a > b"]["value"] == 1.0 and table["a > b"]["ci95"] == [1.0, 1.0]
    assert "withheld" not in table["a > b"]
    assert table["a > c"]["value"] is None and table["a > c"]["withheld"].startswith("5 and 4 ")
    assert describe_improvement("a > b", table["a > b"]).endswith(
        "probability of improvement: a better"
    )
    # a summary written before the rule holds numbers from 2 experiments: they are not shown
    old = {"value": 1.0, "ci95": [1.0, 1.0], "experiments": [2, 2]}
    assert "withheld: 2 and 2 experiments" in describe_improvement("a > b", old)


def test_intervals_of_too_few_experiments_are_withheld_with_the_reason():
    from rmac_mj.evaluation import summarise, summary_table

    rng = np.random.default_rng(0)
    few = summarise(
        -1000 + rng.normal(0, 500, (2, 300)), np.full((2, 1), -900.0), [300], trial_seconds=3.0
    )
    for key in (
        "final_return_ci95",
        "final_return_iqm_ci95",
        "first_5min_ci95",
        "first_5min_iqm_ci95",
        "greedy_return_last_ci95",
    ):
        assert getattr(few, key) == [None, None], key
    assert few.final_return_mean is not None and few.final_return_iqm is not None
    assert few.intervals_withheld.startswith("2 experiments: too few for a 95% interval")
    enough = summarise(-1000 + rng.normal(0, 500, (5, 300)), trial_seconds=3.0)
    assert enough.intervals_withheld is None and None not in enough.final_return_ci95
    table = summary_table({"rmac": few.as_dict(), "trial_seconds": 3.0}, ["rmac"])
    row = table.splitlines()[2]
    assert "n/a" in row and "[" not in row  # no interval printed from 2 experiments


def test_a_window_longer_than_the_run_is_empty():
    from rmac_mj.evaluation import summarise, summary_table

    short = summarise(np.full((5, 20), -1048.5), trial_seconds=3.0)  # one simulated minute
    assert short.mean_return_first_10min is None and short.mean_return_first_5min is None
    assert short.first_5min_ci95 == [None, None] and short.first_5min_iqm is None
    assert short.final_return_mean == -1048.5
    table = summary_table({"rmac": short.as_dict(), "trial_seconds": 3.0}, ["rmac"])
    assert "-1048.5" in table.splitlines()[2] and table.splitlines()[2].count("-1048.5") == 1
    assert "first 10 min: n/a, the run is shorter than 10 simulated minutes" in table
    long = summarise(np.full((5, 200), -900.0), trial_seconds=3.0)  # exactly 10 minutes
    assert long.mean_return_first_10min == -900.0 and long.mean_return_first_5min == -900.0

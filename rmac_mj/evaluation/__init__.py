"""What the numbers are: the learning-curve metrics of ``summary.json`` (:func:`summarise`, a
:class:`LearnerSummary` per learner: the mean with a Student-t interval, Welch's t-test),
statistics across experiments and tasks (interquartile means, bootstrap intervals, improvement
probabilities, performance profiles), and the tables people read (:func:`summary_table`).
"""

from rmac_mj.evaluation.metrics import (
    EARLY_MINUTES,
    FEW_EXPERIMENTS,
    FINAL_WINDOW,
    FIRST_MINUTES,
    GREEDY_WITHIN,
    SIGNIFICANCE_LEVEL,
    LearnerSummary,
    compare_final_returns,
    confidence_interval,
    early_returns,
    final_returns,
    first_reaching,
    improvement,
    minutes_to_within,
    stuck_threshold,
    summarise,
    trials_in,
    within_optimal,
)
from rmac_mj.evaluation.report import (
    across_runs,
    describe_improvement,
    describe_test,
    few_experiments_note,
    summary_table,
)
from rmac_mj.evaluation.statistics import (
    Estimate,
    iqm,
    iqm_interval,
    pairwise_improvement,
    performance_profile,
    probability_of_improvement,
)

__all__ = [
    # Metrics of learning curves (summary.json)
    "EARLY_MINUTES",
    "FEW_EXPERIMENTS",
    "FINAL_WINDOW",
    "FIRST_MINUTES",
    "GREEDY_WITHIN",
    "SIGNIFICANCE_LEVEL",
    "LearnerSummary",
    "compare_final_returns",
    "confidence_interval",
    "early_returns",
    "final_returns",
    "first_reaching",
    "improvement",
    "minutes_to_within",
    "stuck_threshold",
    "summarise",
    "trials_in",
    "within_optimal",
    # Statistics across experiments and tasks
    "Estimate",
    "iqm",
    "iqm_interval",
    "pairwise_improvement",
    "performance_profile",
    "probability_of_improvement",
    # The printed report
    "across_runs",
    "describe_improvement",
    "describe_test",
    "few_experiments_note",
    "summary_table",
]

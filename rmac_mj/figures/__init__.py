"""Figures drawn from saved results, never by retraining: learning curves (the paper's Fig. 2) and
performance profiles from ``summary.json``, policy and critic maps of snapshots (Figs. 3 and 4).
``*_figure`` functions return a matplotlib figure, ``plot_*`` functions write it as PNG and PDF.
"""

from rmac_mj.figures.plots import (
    X_AXES,
    learning_curves_figure,
    performance_profiles_figure,
    plot_learning_curves,
    plot_performance_profiles,
    running_mean,
    save_figure,
)
from rmac_mj.figures.policy_plots import (
    MapView,
    greedy_trajectory,
    plot_policies,
    plot_policy,
    policies_figure,
    policy_actions,
    policy_slice,
)

__all__ = [
    # Learning curves and performance profiles
    "X_AXES",
    "learning_curves_figure",
    "performance_profiles_figure",
    "plot_learning_curves",
    "plot_performance_profiles",
    "running_mean",
    "save_figure",
    # Policy and critic maps of snapshots
    "MapView",
    "greedy_trajectory",
    "plot_policies",
    "plot_policy",
    "policies_figure",
    "policy_actions",
    "policy_slice",
]

"""Figures of the paper: learning curves (Fig. 2) and learned policies and critics (Figs. 3, 4).

Figures are drawn from saved results (``summary.json``, snapshots), never by retraining.
"""

from __future__ import annotations

import os
import pathlib
from typing import Any

import matplotlib

matplotlib.use("Agg")  # files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rmac_mj.experiments.results import FEW_EXPERIMENTS, FINAL_WINDOW, TRIAL_SECONDS  # noqa: E402

_LABELS = {"rmac": "RMAC", "s-ac": "S-AC"}
#: Colour per learner (in every figure); in a comparison of runs the line style tells the runs apart.
_COLOURS = {"rmac": "tab:blue", "s-ac": "tab:orange"}
_RUN_STYLES = ("-", "--", ":", "-.", (0, (5, 1, 1, 1)), (0, (1, 3)))


def _save(fig, stem: str | os.PathLike, formats=("png", "pdf")) -> list[pathlib.Path]:
    stem = pathlib.Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = []
    for fmt in formats:
        path = stem.with_suffix(f".{fmt}")
        fig.savefig(path, dpi=150, bbox_inches="tight")
        paths.append(path)
    plt.close(fig)
    return paths


def running_mean(values, window: int) -> np.ndarray:
    """Centred running mean over ``window`` trials (fewer at the ends); shape kept. NaN stays NaN."""
    values = np.asarray(values, dtype=float)
    if window <= 1 or values.size == 0:
        return values
    sums = np.concatenate([[0.0], np.cumsum(values)])
    index = np.arange(values.size)
    low = np.maximum(index - (window - 1) // 2, 0)
    high = np.minimum(index + window // 2 + 1, values.size)
    return (sums[high] - sums[low]) / (high - low)


def _learners(summary: dict[str, Any]) -> list[str]:
    return [k for k in summary if isinstance(summary[k], dict) and "mean_return_per_trial" in summary[k]]


def _padded(low: float, high: float, fraction: float = 0.05, minimum: float = 10.0):
    margin = max(minimum, fraction * (high - low))
    return low - margin, high + margin


def learning_curves_figure(summaries: dict[str, dict[str, Any]], optimal_return: float | None = None,
                           detail_ylim: tuple[float, float] | None = None, smooth: int = 1):
    """The figure of :func:`plot_learning_curves` (see it), not yet saved."""
    if not isinstance(smooth, (int, np.integer)) or smooth < 1:
        raise ValueError(f"smooth must be a positive integer (trials), got {smooth!r}")
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8), constrained_layout=True)
    colours = dict(_COLOURS)
    palette = [c for c in plt.rcParams["axes.prop_cycle"].by_key()["color"]
               if c not in colours.values()]
    several = len(summaries) > 1
    drawn, ends, fewest = [], [], None
    for ax in axes:
        for run, (label, summary) in enumerate(summaries.items()):
            trial_seconds = float(summary.get("trial_seconds", TRIAL_SECONDS))
            for algorithm in _learners(summary):
                row = summary[algorithm]
                mean = running_mean(row["mean_return_per_trial"], smooth)
                low = running_mean([np.nan if v is None else v for v in row["ci95_low_per_trial"]], smooth)
                high = running_mean([np.nan if v is None else v for v in row["ci95_high_per_trial"]],
                                    smooth)
                minutes = np.arange(1, mean.size + 1) * trial_seconds / 60.0
                name = _LABELS.get(algorithm, algorithm)
                if algorithm not in colours:
                    colours[algorithm] = palette[len(colours) % len(palette)]
                style = {"color": colours[algorithm], "linestyle": _RUN_STYLES[run % len(_RUN_STYLES)]}
                if several:
                    name = f"{label}: {name}"
                ax.plot(minutes, mean, label=f"{name} (mean of {row['experiments']})",
                        linewidth=1.3, **style)
                ax.fill_between(minutes, low, high, color=style["color"],
                                alpha=0.15 if several else 0.25, linewidth=0)
                drawn.append(mean)
                ends.append(mean[-FINAL_WINDOW:])
                if row.get("greedy_eval_trials"):
                    eval_minutes = np.asarray(row["greedy_eval_trials"]) * trial_seconds / 60.0
                    ax.plot(eval_minutes, row["greedy_return_per_eval"], marker=".", linewidth=0.8,
                            alpha=0.8, label=f"{name}, greedy trial", **style)
                    drawn.append(np.asarray(row["greedy_return_per_eval"], dtype=float))
                fewest = row["experiments"] if fewest is None else min(fewest, row["experiments"])
        if optimal_return is not None:
            ax.axhline(optimal_return, color="black", linewidth=1.0, linestyle="-.",
                       label=f"near-optimal ({optimal_return:.0f})")
        ax.set_xlabel("time [min] (simulated)")
        ax.set_ylabel("sum of rewards per trial")
        ax.grid(alpha=0.3)
        ax.set_xlim(left=0)
        seconds = float(next(iter(summaries.values())).get("trial_seconds", TRIAL_SECONDS))
        trials_axis = ax.secondary_xaxis("top", functions=(lambda m, s=seconds: m * 60.0 / s,
                                                           lambda t, s=seconds: t * s / 60.0))
        trials_axis.set_xlabel(f"trial ({seconds:g} s each)")
    # The axes follow the curves, not the bands: with few experiments a 95% band spans thousands.
    values = np.concatenate([d[np.isfinite(d)] for d in drawn] +
                            [np.array([optimal_return] if optimal_return is not None else [])])
    if values.size:
        axes[0].set_ylim(*_padded(values.min(), values.max()))
    axes[0].set_title("Learning curves, mean and 95% confidence interval")
    if detail_ylim is None:  # the range of the curves' last trials, and the optimum
        last = np.concatenate(ends + [np.array([optimal_return] if optimal_return is not None else [])])
        last = last[np.isfinite(last)]
        if last.size:
            detail_ylim = _padded(last.min(), last.max(), fraction=0.1, minimum=25.0)
    if detail_ylim is not None:
        axes[1].set_ylim(*detail_ylim)
    axes[1].set_title("Detail: the levels reached")
    legend_title = f"running mean over {smooth} trials" if smooth > 1 else None
    for ax in axes:
        ax.legend(loc="lower right", fontsize="small", title=legend_title, title_fontsize="small")
    if fewest is not None and fewest < FEW_EXPERIMENTS:
        fig.text(0.5, -0.01, f"{fewest} experiment{'s' if fewest != 1 else ''} per learner: too few "
                 f"to rank the learners; 95% intervals from fewer than {FEW_EXPERIMENTS} mean little "
                 "(bands clipped to the plot)", ha="center", va="top", fontsize="small",
                 color="firebrick")
    return fig


def plot_learning_curves(summaries: dict[str, dict[str, Any]], stem: str | os.PathLike,
                         optimal_return: float | None = None,
                         detail_ylim: tuple[float, float] | None = None,
                         smooth: int = 1) -> list[pathlib.Path]:
    """Fig. 2: sum of rewards per trial against simulated minutes (trials on the top axis), mean and
    95% confidence band.

    Two panels: the whole range (the paper's view, with S-AC's early dip) and a detail of the levels
    reached, where the learners' differences are a few percent. The y axes follow the mean curves (the
    bands are clipped to them), each panel has a legend, and a note says when fewer than
    ``FEW_EXPERIMENTS`` experiments make the bands meaningless.

    Args:
      summaries: label -> summary document (``summary.json``) holding one entry per algorithm.
        With one summary the legend names only the learners; with several, "label: learner", each
        learner keeping its colour and each run its line style.
      stem: output path without suffix; a .png and a .pdf are written.
      optimal_return: drawn as a horizontal line (the near-optimal reference).
      detail_ylim: y range of the detail panel; default the range of the (smoothed) mean curves over
        their last ``FINAL_WINDOW`` trials, and the optimum.
      smooth: running mean over this many trials (centred) of the mean and of the band's bounds (the
        smoothed bounds are conservative: the interval of a mean over trials is narrower); stated in
        the legends. 1 draws the raw per-trial values.
    """
    fig = learning_curves_figure(summaries, optimal_return, detail_ylim, smooth)
    return _save(fig, stem)


def policy_actions(agent, states: np.ndarray) -> np.ndarray:
    """The greedy action in each of ``states`` (shape (q, n)), each evaluated on its own: shape (q, m).

    Agents with a batch ``policy(states)`` (RMAC: u = f^-1(x, R(x)) linearised at u = 0) use it; for
    the others each state is a fresh greedy trial's first action. Either way an action does not depend
    on which states were evaluated before it.
    """
    states = np.asarray(states, dtype=float)
    if hasattr(agent, "policy"):
        return np.asarray(agent.policy(states)).reshape(len(states), -1)
    actions = []
    for x in states:
        agent.begin_greedy_trial()
        actions.append(np.asarray(agent.greedy_action(x)).reshape(-1))
    return np.array(actions)


def policy_grid(agent, n_angle: int = 101, n_velocity: int = 101, max_speed: float = 30.0):
    """Policy and critic of ``agent`` on a (phi, phi_dot) grid (see :func:`policy_actions`).

    Returns:
      (angles (n_angle,), velocities (n_velocity,), actions (n_velocity, n_angle),
      values (n_velocity, n_angle)).
    """
    angles = np.linspace(-np.pi, np.pi, n_angle)
    velocities = np.linspace(-max_speed, max_speed, n_velocity)
    grid_v, grid_a = np.meshgrid(velocities, angles, indexing="ij")
    states = np.column_stack([grid_a.ravel(), grid_v.ravel()])
    actions = policy_actions(agent, states)[:, 0]
    values = np.array([agent.value(x) for x in states])
    shape = (n_velocity, n_angle)
    return angles, velocities, actions.reshape(shape), values.reshape(shape)


def greedy_trajectory(agent, meta: dict[str, Any]) -> tuple[np.ndarray, float]:
    """A greedy trial (no exploration, no learning) of ``agent`` on the task of its snapshot ``meta``
    from the task's start state: the states, ndarray of shape (T, n), and the trial's return."""
    from rmac_mj import tasks
    from rmac_mj.experiments.episode import state_of

    env = tasks.load(meta["domain"], meta["task"], task_kwargs=meta.get("task_kwargs") or None)
    timestep = env.reset()
    agent.begin_greedy_trial()
    states, total = [state_of(timestep.observation)], 0.0
    while not timestep.last():
        timestep = env.step(agent.greedy_action(states[-1]))
        total += float(timestep.reward)
        states.append(state_of(timestep.observation))
    return np.array(states), total


def _draw_trajectory(ax, states: np.ndarray, label: str | None) -> None:
    """The (phi, phi_dot) path, broken where phi wraps from pi to -pi."""
    phi, phi_dot = states[:, 0], states[:, 1]
    breaks = np.nonzero(np.abs(np.diff(phi)) > np.pi)[0] + 1
    for part, (p, v) in enumerate(zip(np.split(phi, breaks), np.split(phi_dot, breaks))):
        ax.plot(p, v, color="white", linewidth=2.6, alpha=0.8)
        ax.plot(p, v, color="black", linewidth=1.1, label=label if part == 0 else None)
    ax.plot(phi[0], phi_dot[0], "o", color="black", markerfacecolor="white", markersize=6)
    ax.plot(phi[-1], phi_dot[-1], "X", color="black", markerfacecolor="white", markersize=7)


def plot_policies(snapshots: list[tuple[Any, dict[str, Any]]], stem: str | os.PathLike,
                  max_speed: float = 30.0, resolution: int = 101,
                  trajectory: bool = True) -> list[pathlib.Path]:
    """Figs. 3 and 4 for one or more agents: the policy and the critic's value function as heat maps,
    one row per agent, each column on one colour scale shared by all rows, so that learners compare.

    For S-AC the policy is the actor pi(x); for RMAC it is the composition u = f^-1(x, R(x)) of the
    inverse process model and the reference model, both evaluated greedily (no exploration). With
    ``trajectory``, each map also shows the agent's greedy trial from the start state (circle) to its
    end (cross).

    Args:
      snapshots: (agent, meta) pairs, as :func:`rmac_mj.experiments.snapshots.load_snapshot` returns.
      stem: output path without suffix; a .png and a .pdf are written.
    """
    return _save(policies_figure(snapshots, max_speed, resolution, trajectory), stem)


def policies_figure(snapshots: list[tuple[Any, dict[str, Any]]], max_speed: float = 30.0,
                    resolution: int = 101, trajectory: bool = True):
    """The figure of :func:`plot_policies` (see it), not yet saved."""
    grids = [policy_grid(agent, resolution, resolution, max_speed) for agent, _ in snapshots]
    values = np.concatenate([grid[3].ravel() for grid in grids])
    value_range = (float(values.min()), float(values.max()))
    rows = len(snapshots)
    fig, axes = plt.subplots(rows, 2, figsize=(11.5, 4.2 * rows), constrained_layout=True,
                             squeeze=False)
    for (agent, meta), (angles, velocities, actions, critic), (ax_policy, ax_value) in zip(
            snapshots, grids, axes):
        algorithm = meta.get("algorithm", "")
        name = _LABELS.get(algorithm, algorithm)
        bounds = meta.get("action_space", {"low": [-3.0], "high": [3.0]})
        extent = (angles[0], angles[-1], velocities[0], velocities[-1])
        policy_image = ax_policy.imshow(actions, origin="lower", extent=extent, aspect="auto",
                                        cmap="RdBu_r", vmin=bounds["low"][0], vmax=bounds["high"][0])
        value_image = ax_value.imshow(critic, origin="lower", extent=extent, aspect="auto",
                                      cmap="viridis", vmin=value_range[0], vmax=value_range[1])
        policy_name = r"policy $u = f^{-1}(x, R(x))$" if algorithm == "rmac" else r"actor $\pi(x)$"
        after = f", after {meta['trial']} trials" if meta.get("trial") is not None else ""
        ax_policy.set_title(f"{name} {policy_name}{after}")
        ax_value.set_title(f"{name} critic $V(x)${after}")
        if trajectory:
            states, total = greedy_trajectory(agent, meta)
            for ax in (ax_policy, ax_value):
                _draw_trajectory(ax, states, f"greedy trial from $x_0$ (return {total:.0f})")
                ax.set_xlim(extent[0], extent[1])
                ax.set_ylim(extent[2], extent[3])
            ax_policy.legend(loc="lower left", fontsize="small")
        for ax in (ax_policy, ax_value):
            ax.set_xlabel(r"angle $\varphi$ [rad] (0 = upright)")
            ax.set_ylabel(r"angular velocity $\dot\varphi$ [rad/s]")
    fig.colorbar(policy_image, ax=axes[:, 0], label="$u$ [V]")
    fig.colorbar(value_image, ax=axes[:, 1],
                 label="$V(x)$" + (" (one scale for all rows)" if rows > 1 else ""))
    experiments = {meta.get("experiment") for _, meta in snapshots}
    if len(experiments) == 1 and None not in experiments:
        fig.suptitle(f"experiment {experiments.pop()}")
    return fig


def plot_policy(agent, meta: dict[str, Any], stem: str | os.PathLike, max_speed: float = 30.0,
                resolution: int = 101) -> list[pathlib.Path]:
    """Figs. 3 and 4 for one agent (see :func:`plot_policies`)."""
    return plot_policies([(agent, meta)], stem, max_speed=max_speed, resolution=resolution)

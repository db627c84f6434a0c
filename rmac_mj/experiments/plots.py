"""Figures of the paper: learning curves (Fig. 2) and learned policies and critics (Figs. 3, 4).

Figures are drawn from saved results (``summary.json``, snapshots), never by retraining. Nothing here
knows a particular task: the trial length comes from the summary, axis ranges and labels from the
task's ``learner_state`` and the action bounds, learner names from the agents.
"""

from __future__ import annotations

import os
import pathlib
from typing import Any, Sequence

import matplotlib

matplotlib.use("Agg")  # files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rmac_mj.agents import display_name  # noqa: E402

_STYLES = {"rmac": {"color": "tab:blue", "linestyle": "-"},
           "s-ac": {"color": "tab:orange", "linestyle": "--"}}


def _trial_seconds(label: str, summary: dict[str, Any]) -> float:
    seconds = summary.get("trial_seconds")
    if not (isinstance(seconds, (int, float)) and np.isfinite(seconds) and seconds > 0):
        raise ValueError(f"summary {label!r} has no valid trial_seconds (simulated seconds per "
                         f"trial), got {seconds!r}")
    return float(seconds)


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


def plot_learning_curves(summaries: dict[str, dict[str, Any]], stem: str | os.PathLike,
                         optimal_return: float | None = None,
                         detail_ylim: tuple[float, float] | None = None) -> list[pathlib.Path]:
    """Fig. 2: sum of rewards per trial against simulated minutes, mean and 95% confidence band.

    Two panels: the whole range (the paper's view, with S-AC's early dip) and a detail of the levels
    reached, where the learners' differences are a few percent.

    Args:
      summaries: label -> summary document (``summary.json``) holding one entry per algorithm and
        ``trial_seconds``, the task's trial length, which sets the time axis. With one summary the
        legend names only the learners; with several, "label: learner".
      stem: output path without suffix; a .png and a .pdf are written.
      optimal_return: drawn as a horizontal line (the near-optimal reference).
      detail_ylim: y range of the detail panel; default from the final levels and the optimum.
    """
    seconds = {label: _trial_seconds(label, summary) for label, summary in summaries.items()}
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.6), constrained_layout=True)
    palette = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    finals = []
    for ax in axes:
        colour_index = 0
        for label, summary in summaries.items():
            for algorithm in [k for k in summary if isinstance(summary[k], dict) and
                              "mean_return_per_trial" in summary[k]]:
                row = summary[algorithm]
                mean = np.asarray(row["mean_return_per_trial"], dtype=float)
                low = np.asarray([np.nan if v is None else v for v in row["ci95_low_per_trial"]])
                high = np.asarray([np.nan if v is None else v for v in row["ci95_high_per_trial"]])
                minutes = np.arange(1, mean.size + 1) * seconds[label] / 60.0
                name = display_name(algorithm)
                if len(summaries) == 1:
                    style = dict(_STYLES.get(algorithm, {}))
                else:
                    name = f"{label}: {name}"
                    style = {"color": palette[colour_index % len(palette)]}
                    colour_index += 1
                ax.plot(minutes, mean, label=f"{name} (mean of {row['experiments']})",
                        linewidth=1.3, **style)
                ax.fill_between(minutes, low, high, color=style["color"], alpha=0.25, linewidth=0)
                if row.get("greedy_eval_trials"):
                    eval_minutes = np.asarray(row["greedy_eval_trials"]) * seconds[label] / 60.0
                    ax.plot(eval_minutes, row["greedy_return_per_eval"], color=style["color"],
                            linestyle=":", marker=".", linewidth=1.0, label=f"{name}, greedy trial")
                finals.append(row["final_return_mean"])
        if optimal_return is not None:
            ax.axhline(optimal_return, color="black", linewidth=1.0, linestyle="-.",
                       label=f"near-optimal ({optimal_return:.0f})")
        lengths = sorted(set(seconds.values()))
        ax.set_xlabel("time [min] (simulated" + (f"; one trial = {lengths[0]:g} s)" if len(lengths) == 1
                                                 else ")"))
        ax.set_ylabel("sum of rewards per trial")
        ax.grid(alpha=0.3)
    axes[0].set_title("Learning curves, mean and 95% confidence interval")
    axes[0].legend(loc="lower right", fontsize="small")
    if detail_ylim is None:
        top = max(finals + ([optimal_return] if optimal_return is not None else []))
        bottom = min(finals)
        margin = max(25.0, 0.1 * (top - bottom))
        detail_ylim = (bottom - (top - bottom) - margin, top + margin)
    axes[1].set_ylim(*detail_ylim)
    axes[1].set_title("Detail: the levels reached")
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


def policy_slice(agent, low: Sequence[float], high: Sequence[float], anchor: Sequence[float],
                 dims: tuple[int, int] = (0, 1), resolution: tuple[int, int] = (101, 101)):
    """Policy and critic of ``agent`` on a grid over two state dimensions (see :func:`policy_actions`).

    The grid spans ``[low[i], high[i]]`` along ``i, j = dims``; every other dimension is held at its
    value in ``anchor`` (e.g. the start state), so for n > 2 the maps are a slice through it.

    Args:
      low, high, anchor: sequences of length n (the state's dimension).
      dims: the two state dimensions on the horizontal and the vertical axis.
      resolution: grid points along dims[0] and dims[1].
    Returns:
      (xs (r0,), ys (r1,), actions (r1, r0, m), values (r1, r0)).
    """
    anchor = np.asarray(anchor, dtype=float).reshape(-1)
    n = anchor.shape[0]
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    if low.shape != (n,) or high.shape != (n,):
        raise ValueError(f"low and high must have the anchor's {n} entries, got {low.shape} and "
                         f"{high.shape}")
    i, j = _check_dims(dims, n)
    xs = np.linspace(low[i], high[i], resolution[0])
    ys = np.linspace(low[j], high[j], resolution[1])
    grid_y, grid_x = np.meshgrid(ys, xs, indexing="ij")
    states = np.repeat(anchor[None, :], grid_x.size, axis=0)
    states[:, i], states[:, j] = grid_x.ravel(), grid_y.ravel()
    actions = policy_actions(agent, states)
    values = np.array([agent.value(x) for x in states])
    shape = (len(ys), len(xs))
    return xs, ys, actions.reshape(*shape, -1), values.reshape(shape)


def _check_dims(dims, n: int) -> tuple[int, int]:
    try:
        i, j = (int(d) for d in dims)
    except (TypeError, ValueError):
        raise ValueError(f"dims must be two state dimensions, got {dims!r}") from None
    if not (0 <= i < n and 0 <= j < n and i != j):
        raise ValueError(f"dims must be two different state dimensions in [0, {n}), got {dims!r}")
    return i, j


def plot_policy(agent, meta: dict[str, Any], stem: str | os.PathLike, learner_state,
                anchor: Sequence[float], dims: tuple[int, int] = (0, 1),
                limits: dict[int, tuple[float, float]] | None = None,
                resolution: int = 101) -> list[pathlib.Path]:
    """Figs. 3 and 4: the policy (one map per action dimension) and the critic as heat maps.

    For S-AC the policy is the actor pi(x); for RMAC it is the composition u = f^-1(x, R(x)) of the
    inverse process model and the reference model, both evaluated greedily (no exploration).

    Args:
      meta: the snapshot's meta document (algorithm, trial, experiment).
      learner_state: the task's ``LearnerState``: the axes' ranges (its box) and labels, the actions'
        labels.
      anchor: a state of shape (n,) through which the maps slice when n > 2 (e.g. the start state).
      dims: the state dimensions on the horizontal and vertical axes.
      limits: per state dimension, a (low, high) range overriding the task's box.
    """
    n = len(learner_state.low)
    i, j = _check_dims(dims, n)
    low, high = np.array(learner_state.low), np.array(learner_state.high)
    for d, (lo, hi) in (limits or {}).items():
        if not (0 <= d < n and np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise ValueError(f"limits[{d}] must be a finite (low, high) with low < high for a state "
                             f"dimension in [0, {n}), got {(lo, hi)!r}")
        low[d], high[d] = lo, hi
    xs, ys, actions, values = policy_slice(agent, low, high, anchor, (i, j), (resolution, resolution))
    algorithm = meta.get("algorithm", "")
    name = display_name(algorithm)
    policy_name = "u = f^-1(x, R(x))" if algorithm == "rmac" else "actor pi(x)"
    m = actions.shape[-1]
    a_low, a_high = agent.action_space.low, agent.action_space.high
    action_labels = list(learner_state.action_labels) if len(learner_state.action_labels) == m else [
        f"u{k + 1}" for k in range(m)]
    fig, axes = plt.subplots(1, m + 1, figsize=(5.5 * (m + 1), 4.2), constrained_layout=True)
    extent = (xs[0], xs[-1], ys[0], ys[-1])
    for k in range(m):
        image = axes[k].imshow(actions[..., k], origin="lower", extent=extent, aspect="auto",
                               cmap="RdBu_r", vmin=a_low[k], vmax=a_high[k])
        fig.colorbar(image, ax=axes[k], label=action_labels[k])
        axes[k].set_title(f"{name} policy {policy_name}" + (f", {action_labels[k]}" if m > 1 else ""))
    image = axes[m].imshow(values, origin="lower", extent=extent, aspect="auto", cmap="viridis")
    fig.colorbar(image, ax=axes[m], label="V(x)")
    axes[m].set_title(f"{name} critic V(x)")
    for ax in axes:
        ax.set_xlabel(learner_state.labels[i])
        ax.set_ylabel(learner_state.labels[j])
    title = []
    trial = meta.get("trial")
    if trial is not None:
        title.append(f"after {trial} trials (experiment {meta.get('experiment', '?')})")
    others = [d for d in range(n) if d not in (i, j)]
    if others:
        title.append("slice at " + ", ".join(f"{learner_state.labels[d]} = {anchor[d]:.3g}"
                                              for d in others))
    if title:
        fig.suptitle("; ".join(title))
    return _save(fig, stem)

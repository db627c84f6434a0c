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

from rmac_mj.experiments.results import TRIAL_SECONDS  # noqa: E402

_LABELS = {"rmac": "RMAC", "s-ac": "S-AC"}
_STYLES = {"rmac": {"color": "tab:blue", "linestyle": "-"},
           "s-ac": {"color": "tab:orange", "linestyle": "--"}}


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
                         detail_ylim: tuple[float, float] | None = None,
                         exploration_floor: float | None = None) -> list[pathlib.Path]:
    """Fig. 2: sum of rewards per trial against simulated minutes, mean and 95% confidence band.

    Two panels: the whole range (the paper's view, with S-AC's early dip) and a detail of the levels
    reached, where the learners' differences are a few percent.

    Args:
      summaries: label -> summary document (``summary.json``) holding one entry per algorithm.
        With one summary the legend names only the learners; with several, "label: learner".
      stem: output path without suffix; a .png and a .pdf are written.
      optimal_return: drawn as a horizontal line (the near-optimal reference).
      exploration_floor: drawn as a second line: the near-optimal policy's return while exploring
        as the learners do, the level an exploring learning curve is judged against.
      detail_ylim: y range of the detail panel; default from the final levels and the optimum.
    """
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
                minutes = np.arange(1, mean.size + 1) * TRIAL_SECONDS / 60.0
                name = _LABELS.get(algorithm, algorithm)
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
                    eval_minutes = np.asarray(row["greedy_eval_trials"]) * TRIAL_SECONDS / 60.0
                    ax.plot(eval_minutes, row["greedy_return_per_eval"], color=style["color"],
                            linestyle=":", marker=".", linewidth=1.0, label=f"{name}, greedy trial")
                finals.append(row["final_return_mean"])
        if optimal_return is not None:
            ax.axhline(optimal_return, color="black", linewidth=1.0, linestyle="-.",
                       label=f"near-optimal ({optimal_return:.0f})")
        if exploration_floor is not None:
            ax.axhline(exploration_floor, color="grey", linewidth=1.0, linestyle=":",
                       label=f"near-optimal, exploring ({exploration_floor:.0f})")
        ax.set_xlabel("time [min] (simulated; one trial = 3 s)")
        ax.set_ylabel("sum of rewards per trial")
        ax.grid(alpha=0.3)
    axes[0].set_title("Learning curves, mean and 95% confidence interval")
    axes[0].legend(loc="lower right", fontsize="small")
    if detail_ylim is None:
        top = max(finals + ([optimal_return] if optimal_return is not None else []))
        bottom = min(finals + ([exploration_floor] if exploration_floor is not None else []))
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


def plot_policy(agent, meta: dict[str, Any], stem: str | os.PathLike, max_speed: float = 30.0,
                resolution: int = 101) -> list[pathlib.Path]:
    """Figs. 3 and 4: the policy and the critic's value function as heat maps.

    For S-AC the policy is the actor pi(x); for RMAC it is the composition u = f^-1(x, R(x)) of the
    inverse process model and the reference model, both evaluated greedily (no exploration).
    """
    angles, velocities, actions, values = policy_grid(agent, resolution, resolution, max_speed)
    algorithm = meta.get("algorithm", "")
    name = _LABELS.get(algorithm, algorithm)
    policy_name = "u = f^-1(x, R(x))" if algorithm == "rmac" else "actor pi(x)"
    fig, (ax_policy, ax_value) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    extent = (angles[0], angles[-1], velocities[0], velocities[-1])
    image = ax_policy.imshow(actions, origin="lower", extent=extent, aspect="auto", cmap="RdBu_r",
                             vmin=-3, vmax=3)
    fig.colorbar(image, ax=ax_policy, label="u [V]")
    ax_policy.set_title(f"{name} policy {policy_name}")
    image = ax_value.imshow(values, origin="lower", extent=extent, aspect="auto", cmap="viridis")
    fig.colorbar(image, ax=ax_value, label="V(x)")
    ax_value.set_title(f"{name} critic V(x)")
    for ax in (ax_policy, ax_value):
        ax.set_xlabel("angle phi [rad] (0 = upright)")
        ax.set_ylabel("angular velocity [rad/s]")
    trial = meta.get("trial")
    if trial is not None:
        fig.suptitle(f"after {trial} trials (experiment {meta.get('experiment', '?')})")
    return _save(fig, stem)

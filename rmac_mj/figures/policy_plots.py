"""Figures of learned policies and critics (the paper's Figs. 3 and 4), drawn from snapshots.

Nothing here knows a particular task: axis ranges and labels come from the task's ``learner_state``
and the action bounds, learner names from the agents.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
from collections.abc import Sequence
from typing import Any

import matplotlib

matplotlib.use("Agg")  # files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rmac_mj import constraints  # noqa: E402
from rmac_mj.agents import display_name  # noqa: E402
from rmac_mj.figures.plots import save_figure  # noqa: E402


@dataclasses.dataclass(frozen=True)
class MapView:
    """What the policy and critic maps show: the state they slice through, the two dimensions on
    their axes and those dimensions' ranges, and how finely a grid samples them.

    Attributes:
      anchor: a state of shape (n,) through which the maps slice when n > 2 (e.g. the start state).
      dims: the state dimensions on the horizontal and vertical axes.
      limits: per state dimension, a (low, high) range overriding the task's box.
      resolution: grid points along each axis (checked against ``constraints.MAP_RESOLUTION``
        before a grid of resolution**2 states is allocated).
    """

    anchor: Sequence[float]
    dims: tuple[int, int] = (0, 1)
    limits: dict[int, tuple[float, float]] | None = None
    resolution: int = 101

    def __post_init__(self) -> None:
        constraints.check(
            "MapView",
            {"resolution": [constraints.MAP_RESOLUTION.constraint()]},
            {"resolution": self.resolution},
        )


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


def policy_slice(
    agent,
    low: Sequence[float],
    high: Sequence[float],
    anchor: Sequence[float],
    dims: tuple[int, int] = (0, 1),
    resolution: tuple[int, int] = (101, 101),
):
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
        raise ValueError(
            f"low and high must have the anchor's {n} entries, got {low.shape} and {high.shape}"
        )
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


def greedy_trajectory(env, agent) -> tuple[np.ndarray, float]:
    """A greedy trial (no exploration, no learning) of ``agent`` on ``env`` from the task's start
    state: the learner's states, ndarray of shape (T, n), and the trial's return."""
    from rmac_mj.rollout import learner_state_of, state_of

    keys = learner_state_of(env).keys
    timestep = env.reset()
    agent.begin_greedy_trial()
    states, total = [state_of(timestep.observation, keys)], 0.0
    while not timestep.last():
        timestep = env.step(agent.greedy_action(states[-1]))
        total += float(timestep.reward)
        states.append(state_of(timestep.observation, keys))
    return np.array(states), total


def _draw_trajectory(
    ax, states: np.ndarray, dims: tuple[int, int], learner_state, label: str | None
) -> None:
    """The path of ``states`` over the dims (i, j), broken where a periodic dimension wraps."""
    i, j = dims
    x, y = states[:, i], states[:, j]
    jumps = np.zeros(len(states) - 1, dtype=bool)
    for d in dims:
        if learner_state.periodic[d]:
            period = learner_state.high[d] - learner_state.low[d]
            jumps |= np.abs(np.diff(states[:, d])) > period / 2
    breaks = np.nonzero(jumps)[0] + 1
    for part, (px, py) in enumerate(zip(np.split(x, breaks), np.split(y, breaks))):
        ax.plot(px, py, color="white", linewidth=2.6, alpha=0.8)
        ax.plot(px, py, color="black", linewidth=1.1, label=label if part == 0 else None)
    ax.plot(x[0], y[0], "o", color="black", markerfacecolor="white", markersize=6)
    ax.plot(x[-1], y[-1], "X", color="black", markerfacecolor="white", markersize=7)


def _map_box(learner_state, limits: dict[int, tuple[float, float]] | None):
    """The (low, high) of the maps per state dimension: the task's box, ``limits`` overriding."""
    n = len(learner_state.low)
    low, high = np.array(learner_state.low), np.array(learner_state.high)
    for d, (lo, hi) in (limits or {}).items():
        if not (0 <= d < n and np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise ValueError(
                f"limits[{d}] must be a finite (low, high) with low < high for a state "
                f"dimension in [0, {n}), got {(lo, hi)!r}"
            )
        low[d], high[d] = lo, hi
    return low, high


def _draw_maps(axes_row, agent, meta, grid, action_labels, value_range):
    """One snapshot's row: a map per action dimension and the critic's; returns their images."""
    xs, ys, actions, values = grid
    m = len(action_labels)
    algorithm = meta.get("algorithm", "")
    name = display_name(algorithm)
    policy_name = r"policy $u = f^{-1}(x, R(x))$" if algorithm == "rmac" else r"actor $\pi(x)$"
    after = f", after {meta['trial']} trials" if meta.get("trial") is not None else ""
    a_low, a_high = agent.action_space.low, agent.action_space.high
    extent = (xs[0], xs[-1], ys[0], ys[-1])
    images = []
    for k in range(m):
        images.append(
            axes_row[k].imshow(
                actions[..., k],
                origin="lower",
                extent=extent,
                aspect="auto",
                cmap="RdBu_r",
                vmin=a_low[k],
                vmax=a_high[k],
            )
        )
        axes_row[k].set_title(
            f"{name} {policy_name}" + (f", {action_labels[k]}" if m > 1 else "") + after
        )
    images.append(
        axes_row[m].imshow(
            values,
            origin="lower",
            extent=extent,
            aspect="auto",
            cmap="viridis",
            vmin=value_range[0],
            vmax=value_range[1],
        )
    )
    axes_row[m].set_title(f"{name} critic $V(x)${after}")
    return images


def _draw_greedy_trial(axes_row, env, agent, dims, learner_state, extent) -> None:
    """The agent's greedy trial in ``env`` over every map of its row, the maps' ranges kept."""
    states, total = greedy_trajectory(env, agent)
    for ax in axes_row:
        _draw_trajectory(
            ax, states, dims, learner_state, f"greedy trial from $x_0$ (return {total:.0f})"
        )
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
    axes_row[0].legend(loc="lower left", fontsize="small")


def _policies_title(snapshots, learner_state, anchor, dims) -> str | None:
    """The experiment the snapshots share and the slice's other coordinates, or None."""
    title = []
    experiments = {meta.get("experiment") for _, meta in snapshots}
    if len(experiments) == 1 and None not in experiments:
        title.append(f"experiment {experiments.pop()}")
    others = [d for d in range(len(learner_state.low)) if d not in dims]
    if others:
        title.append(
            "slice at " + ", ".join(f"{learner_state.labels[d]} = {anchor[d]:.3g}" for d in others)
        )
    return "; ".join(title) if title else None


def policies_figure(
    snapshots: Sequence[tuple[Any, dict[str, Any]]],
    learner_state,
    view: MapView,
    envs: Sequence[Any] | None = None,
):
    """The figure of :func:`plot_policies` (see it), not yet saved."""
    i, j = _check_dims(view.dims, len(learner_state.low))
    low, high = _map_box(learner_state, view.limits)
    anchor, resolution = view.anchor, view.resolution
    if envs is not None and len(envs) != len(snapshots):
        raise ValueError(
            f"envs must give one environment per snapshot ({len(snapshots)}), got {len(envs)}"
        )
    grids = [
        policy_slice(agent, low, high, anchor, (i, j), (resolution, resolution))
        for agent, _ in snapshots
    ]
    every_value = np.concatenate([grid[3].ravel() for grid in grids])
    value_range = (float(every_value.min()), float(every_value.max()))
    m = grids[0][2].shape[-1]
    action_labels = (
        list(learner_state.action_labels)
        if len(learner_state.action_labels) == m
        else [f"u{k + 1}" for k in range(m)]
    )
    rows = len(snapshots)
    fig, axes = plt.subplots(
        rows, m + 1, figsize=(5.5 * (m + 1), 4.2 * rows), constrained_layout=True, squeeze=False
    )
    for row, ((agent, meta), grid) in enumerate(zip(snapshots, grids)):
        images = _draw_maps(axes[row], agent, meta, grid, action_labels, value_range)
        if envs is not None:
            extent = (grid[0][0], grid[0][-1], grid[1][0], grid[1][-1])
            _draw_greedy_trial(axes[row], envs[row], agent, (i, j), learner_state, extent)
        for ax in axes[row]:
            ax.set_xlabel(learner_state.labels[i])
            ax.set_ylabel(learner_state.labels[j])
    for k in range(m):
        fig.colorbar(images[k], ax=axes[:, k], label=action_labels[k])
    fig.colorbar(
        images[m], ax=axes[:, m], label="$V(x)$" + (" (one scale for all rows)" if rows > 1 else "")
    )
    title = _policies_title(snapshots, learner_state, anchor, (i, j))
    if title:
        fig.suptitle(title)
    return fig


def plot_policies(
    snapshots: Sequence[tuple[Any, dict[str, Any]]],
    stem: str | os.PathLike,
    learner_state,
    view: MapView,
    envs: Sequence[Any] | None = None,
) -> list[pathlib.Path]:
    """Figs. 3 and 4 for one or more agents: the policy (one map per action dimension) and the critic
    as heat maps, one row per agent, each column on one colour scale shared by all rows, so that
    learners compare side by side.

    For S-AC the policy is the actor pi(x); for RMAC it is the composition u = f^-1(x, R(x)) of the
    inverse process model and the reference model, both evaluated greedily (no exploration).

    Args:
      snapshots: (agent, meta) pairs, as ``load_snapshot`` returns (meta: algorithm, trial, experiment).
      stem: output path without suffix; a .png and a .pdf are written.
      learner_state: the task's ``LearnerStateSpec``: the axes' ranges (its box) and labels, the actions'
        labels.
      view: the slice the maps show, its ranges and its grid.
      envs: per snapshot, the environment of its greedy trial from the start state, drawn over its
        maps (start: circle, end: cross); None draws none.
    """
    return save_figure(policies_figure(snapshots, learner_state, view, envs), stem)


def plot_policy(
    agent, meta: dict[str, Any], stem: str | os.PathLike, learner_state, view: MapView, env=None
) -> list[pathlib.Path]:
    """Figs. 3 and 4 for one agent (see :func:`plot_policies`); ``env``: draw its greedy trial."""
    envs = None if env is None else [env]
    return plot_policies([(agent, meta)], stem, learner_state, view, envs)

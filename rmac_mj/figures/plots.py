"""Figures of results from ``summary.json``: learning curves (Fig. 2), performance profiles.

Never by retraining; nothing here knows a particular task (the trial length comes from the summary,
learner names from the agents). Figs. 3 and 4 are :mod:`rmac_mj.figures.policy_plots`.
"""

from __future__ import annotations

import os
import pathlib
from typing import Any

import matplotlib

matplotlib.use("Agg")  # files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rmac_mj.agents import display_name  # noqa: E402
from rmac_mj.evaluation.metrics import (  # noqa: E402
    FEW_EXPERIMENTS,
    FINAL_WINDOW,
    LearnerSummary,
)

#: Colour per learner (in every figure); in a comparison of runs the line style tells the runs apart.
_STYLES = {
    "rmac": {"color": "tab:blue"},
    "s-ac": {"color": "tab:orange"},
    "mlac": {"color": "tab:green"},
    "sb3-sac": {"color": "tab:red"},
    "sb3-td3": {"color": "tab:purple"},
    "sb3-ppo": {"color": "tab:brown"},
    "sb3-crossq": {"color": "tab:pink"},
}
_RUN_STYLES = ("-", "--", ":", "-.", (0, (5, 1, 1, 1)), (0, (1, 3)))
#: The least margin around curves when a summary gives no plot hints (``tasks.common.PlotHints``).
_RETURN_MARGIN = 10.0


def _trial_seconds(label: str, summary: dict[str, Any]) -> float:
    seconds = summary.get("trial_seconds")
    if not (isinstance(seconds, (int, float)) and np.isfinite(seconds) and seconds > 0):
        raise ValueError(
            f"summary {label!r} has no valid trial_seconds (simulated seconds per "
            f"trial), got {seconds!r}"
        )
    return float(seconds)


def save_figure(fig, stem: str | os.PathLike, formats=("png", "pdf")) -> list[pathlib.Path]:
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
    return [
        k for k in summary if isinstance(summary[k], dict) and "mean_return_per_trial" in summary[k]
    ]


def _padded(low: float, high: float, fraction: float = 0.05, minimum: float = _RETURN_MARGIN):
    margin = max(minimum, fraction * (high - low))
    return low - margin, high + margin


#: What Fig. 2's x axis counts: simulated minutes (the paper's) or environment steps.
X_AXES = ("minutes", "env_steps")


def _x_of(
    row: LearnerSummary,
    summary: dict[str, Any],
    trials: np.ndarray,
    seconds: float,
    x_axis: str,
    key: str = "env_steps_per_trial",
) -> np.ndarray:
    """The x of the trials ``trials`` (1-based): their environment steps (the row's field ``key``),
    or the simulated minutes those steps took; where the summary does not hold the steps (written
    before they were counted), trials of the task's full length."""
    steps = getattr(row, key)
    if steps is not None and None not in steps:
        steps = np.asarray(steps, dtype=float)
        if x_axis == "env_steps":
            return steps
        if summary.get("env_step_seconds"):
            return steps * float(summary["env_step_seconds"]) / 60.0
    if x_axis == "env_steps":
        raise ValueError(
            "this summary holds no environment steps (written before they were "
            "counted): draw it against minutes"
        )
    return np.asarray(trials, dtype=float) * seconds / 60.0


def _check_curve_options(smooth: int, x_axis: str) -> None:
    if not isinstance(smooth, (int, np.integer)) or smooth < 1:
        raise ValueError(f"smooth must be a positive integer (trials), got {smooth!r}")
    if x_axis not in X_AXES:
        raise ValueError(f"x_axis must be one of {', '.join(X_AXES)}, got {x_axis!r}")


class _Colours:
    """A learner's colour: its own (:data:`_STYLES`), else the next of matplotlib's cycle that no
    learner owns, kept for the figure."""

    def __init__(self) -> None:
        self.colours = {algorithm: style["color"] for algorithm, style in _STYLES.items()}
        self.palette = [
            c
            for c in plt.rcParams["axes.prop_cycle"].by_key()["color"]
            if c not in self.colours.values()
        ]

    def __call__(self, algorithm: str) -> str:
        if algorithm not in self.colours:
            self.colours[algorithm] = self.palette[len(self.colours) % len(self.palette)]
        return self.colours[algorithm]


def _draw_learner(ax, row: LearnerSummary, name: str, style, x, smooth: int, several: bool):
    """One learner's mean curve with its band and its greedy trials on ``ax``; ``x(trials, key)``
    places trials; returns the values drawn (the mean curve first)."""
    mean = running_mean(row.mean_return_per_trial, smooth)
    low = running_mean([np.nan if v is None else v for v in row.ci95_low_per_trial], smooth)
    high = running_mean([np.nan if v is None else v for v in row.ci95_high_per_trial], smooth)
    minutes = x(np.arange(1, mean.size + 1), "env_steps_per_trial")
    ax.plot(minutes, mean, label=f"{name} (mean of {row.experiments})", linewidth=1.3, **style)
    ax.fill_between(
        minutes, low, high, color=style["color"], alpha=0.15 if several else 0.25, linewidth=0
    )
    drawn = [mean]
    if row.greedy_eval_trials:
        eval_minutes = x(np.asarray(row.greedy_eval_trials), "greedy_eval_env_steps")
        ax.plot(
            eval_minutes,
            row.greedy_return_per_eval,
            marker=".",
            linewidth=0.8,
            alpha=0.8,
            label=f"{name}, greedy trial",
            **style,
        )
        drawn.append(np.asarray(row.greedy_return_per_eval, dtype=float))
    return drawn


def _draw_runs(ax, summaries, seconds, colours: _Colours, smooth: int, x_axis: str):
    """Every learner of every run on ``ax``; returns the values drawn, the curves' last
    :data:`FINAL_WINDOW` trials, and the fewest experiments of a learner (None: no learner)."""
    several = len(summaries) > 1
    drawn, ends, fewest = [], [], None
    for run, (label, summary) in enumerate(summaries.items()):
        for algorithm in _learners(summary):
            row = LearnerSummary.from_dict(summary[algorithm])
            name = display_name(algorithm)
            style = {"color": colours(algorithm), "linestyle": _RUN_STYLES[run % len(_RUN_STYLES)]}
            if several:
                name = f"{label}: {name}"

            def x(trials, key, row=row, summary=summary, label=label):
                return _x_of(row, summary, trials, seconds[label], x_axis, key=key)

            curves = _draw_learner(ax, row, name, style, x, smooth, several)
            drawn.extend(curves)
            ends.append(curves[0][-FINAL_WINDOW:])
            fewest = row.experiments if fewest is None else min(fewest, row.experiments)
    return drawn, ends, fewest


def _draw_references(ax, optimal_return: float | None, exploration_floor: float | None) -> None:
    """The near-optimal return and the exploration floor as horizontal lines."""
    for value, colour, style, name in (
        (optimal_return, "black", "-.", "near-optimal"),
        (exploration_floor, "grey", ":", "near-optimal, exploring"),
    ):
        if value is not None:
            ax.axhline(
                value, color=colour, linewidth=1.0, linestyle=style, label=f"{name} ({value:.0f})"
            )


def _label_axes(ax, summaries, seconds: dict[str, float], x_axis: str) -> None:
    """The axes' labels and grid, and trials on the top axis where every trial is one length."""
    lengths = sorted(set(seconds.values()))
    if x_axis == "env_steps":
        ax.set_xlabel("environment steps")
    else:
        ax.set_xlabel(
            "time [min] (simulated"
            + (f"; one trial = {lengths[0]:g} s)" if len(lengths) == 1 else ")")
        )
    ax.set_ylabel("sum of rewards per trial")
    ax.grid(alpha=0.3)
    ax.set_xlim(left=0)
    uniform = all(
        abs(
            (seconds[label] if row.trial_seconds_mean is None else row.trial_seconds_mean)
            - seconds[label]
        )
        <= 1e-9 * seconds[label]
        for label, summary in summaries.items()
        for row in (LearnerSummary.from_dict(summary[a]) for a in _learners(summary))
    )
    if len(lengths) == 1 and x_axis == "minutes" and uniform:
        # trials on the top axis (with several trial lengths it would be ambiguous)
        trials_axis = ax.secondary_xaxis(
            "top",
            functions=(
                lambda m, s=lengths[0]: m * 60.0 / s,
                lambda t, s=lengths[0]: t * s / 60.0,
            ),
        )
        trials_axis.set_xlabel("trial")


def _set_ranges(axes, summaries, drawn, ends, references, detail_ylim) -> None:
    """The axes follow the curves, not the bands: with few experiments a 95% band spans
    thousands. Their least margin is the task's (its plot hints): a return difference worth
    seeing. The detail shows the range of the curves' last trials and the ``references``."""
    margin = min(
        (
            float(s.get("plot_hints", {}).get("return_margin", _RETURN_MARGIN))
            for s in summaries.values()
        ),
        default=_RETURN_MARGIN,
    )
    values = np.concatenate([d[np.isfinite(d)] for d in drawn] + [np.array(references)])
    if values.size:
        axes[0].set_ylim(*_padded(values.min(), values.max(), minimum=margin))
    if detail_ylim is None:
        last = np.concatenate(ends + [np.array(references)])
        last = last[np.isfinite(last)]
        if last.size:
            detail_ylim = _padded(last.min(), last.max(), fraction=0.1, minimum=2.5 * margin)
    if detail_ylim is not None:
        axes[1].set_ylim(*detail_ylim)


def _legends(axes, smooth: int) -> None:
    legend_title = f"running mean over {smooth} trials" if smooth > 1 else None
    axes[0].legend(loc="lower right", fontsize="small", title=legend_title, title_fontsize="small")
    # The detail's curves fill it up to its right edge (the levels reached): its legend goes beside it.
    axes[1].legend(
        loc="upper left",
        bbox_to_anchor=(1.02, 1.0),
        borderaxespad=0.0,
        fontsize="small",
        title=legend_title,
        title_fontsize="small",
    )


def _few_experiments_note(fig, fewest: int | None) -> None:
    if fewest is not None and fewest < FEW_EXPERIMENTS:
        fig.text(
            0.5,
            -0.01,
            f"{fewest} experiment{'s' if fewest != 1 else ''} per learner: too few "
            f"to rank the learners; 95% intervals from fewer than {FEW_EXPERIMENTS} mean little "
            "(bands clipped to the plot)",
            ha="center",
            va="top",
            fontsize="small",
            color="firebrick",
        )


def learning_curves_figure(
    summaries: dict[str, dict[str, Any]],
    optimal_return: float | None = None,
    detail_ylim: tuple[float, float] | None = None,
    smooth: int = 1,
    exploration_floor: float | None = None,
    x_axis: str = "minutes",
):
    """The figure of :func:`plot_learning_curves` (see it), not yet saved."""
    _check_curve_options(smooth, x_axis)
    seconds = {label: _trial_seconds(label, summary) for label, summary in summaries.items()}
    fig, axes = plt.subplots(1, 2, figsize=(15, 4.8), constrained_layout=True)
    colours = _Colours()
    drawn, ends = [], []
    for ax in axes:
        on_ax, ends_on_ax, fewest = _draw_runs(ax, summaries, seconds, colours, smooth, x_axis)
        drawn.extend(on_ax)
        ends.extend(ends_on_ax)
        _draw_references(ax, optimal_return, exploration_floor)
        _label_axes(ax, summaries, seconds, x_axis)
    references = [r for r in (optimal_return, exploration_floor) if r is not None]
    _set_ranges(axes, summaries, drawn, ends, references, detail_ylim)
    axes[0].set_title("Learning curves, mean and 95% confidence interval")
    axes[1].set_title("Detail: the levels reached")
    _legends(axes, smooth)
    _few_experiments_note(fig, fewest)
    return fig


def plot_learning_curves(
    summaries: dict[str, dict[str, Any]],
    stem: str | os.PathLike,
    optimal_return: float | None = None,
    detail_ylim: tuple[float, float] | None = None,
    smooth: int = 1,
    exploration_floor: float | None = None,
    x_axis: str = "minutes",
) -> list[pathlib.Path]:
    """Fig. 2: sum of rewards per trial against simulated minutes (trials on the top axis), mean and
    95% confidence band.

    Two panels: the whole range (the paper's view, with S-AC's early dip) and a detail of the levels
    reached, where the learners' differences are a few percent. The y axes follow the mean curves (the
    bands are clipped to them), each panel has a legend (the detail's beside it, off the curves' ends),
    and a note says when fewer than
    ``FEW_EXPERIMENTS`` experiments make the bands meaningless.

    Args:
      summaries: label -> summary document (``summary.json``) holding one entry per algorithm and
        ``trial_seconds``, the task's trial length, which sets the time axis. With one summary the
        legend names only the learners; with several, "label: learner", each learner keeping its
        colour and each run its line style.
      stem: output path without suffix; a .png and a .pdf are written.
      optimal_return: drawn as a horizontal line (the near-optimal return).
      detail_ylim: y range of the detail panel; default the range of the (smoothed) mean curves over
        their last ``FINAL_WINDOW`` trials, the optimum and the exploration floor.
      smooth: running mean over this many trials (centred) of the mean and of the band's bounds (the
        smoothed bounds are conservative: the interval of a mean over trials is narrower); stated in
        the legends. 1 draws the raw per-trial values.
      exploration_floor: drawn as a second line: the near-optimal policy's return while exploring
        as the learners do, the level an exploring learning curve is judged against.
      x_axis: "minutes", simulated time from the steps that ran (the paper's axis), or "env_steps",
        the environment steps taken (equal interaction across tasks and learners).
    """
    fig = learning_curves_figure(
        summaries, optimal_return, detail_ylim, smooth, exploration_floor, x_axis
    )
    return save_figure(fig, stem)


def performance_profiles_figure(
    scores: dict[tuple[str, str], Any], what: str = "final return (mean of the last trials)"
):
    """The figure of :func:`plot_performance_profiles` (see it), not yet saved."""
    from rmac_mj.evaluation import statistics

    everything = np.concatenate([np.asarray(v, dtype=float) for v in scores.values()])
    low, high = _padded(everything.min(), everything.max())
    thresholds = np.linspace(low, high, 241)
    fig, ax = plt.subplots(figsize=(6.5, 4.2), constrained_layout=True)
    runs = list(dict.fromkeys(run for run, _ in scores))
    fewest = min(len(v) for v in scores.values())
    for (run, algorithm), values in scores.items():
        fraction, band_low, band_high = statistics.performance_profile(values, thresholds)
        if fewest < FEW_EXPERIMENTS:  # a bootstrap of so few experiments says nothing: no bands
            band_low = band_high = np.full_like(fraction, np.nan)
        colour = _STYLES.get(algorithm, {}).get("color")
        name = display_name(algorithm) + (f" ({run})" if run else "")
        (line,) = ax.plot(
            thresholds,
            fraction,
            color=colour,
            drawstyle="steps-post",
            linewidth=1.4,
            linestyle=_RUN_STYLES[runs.index(run) % len(_RUN_STYLES)],
            label=f"{name}, {len(values)} experiments",
        )
        ax.fill_between(
            thresholds,
            band_low,
            band_high,
            color=line.get_color(),
            alpha=0.15,
            step="post",
            linewidth=0,
        )
    ax.set_xlabel(f"{what}, tau")
    ax.set_ylabel("fraction of experiments above tau")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.set_title("Performance profiles, 95% stratified-bootstrap bands")
    ax.legend(loc="lower left", fontsize="small")
    if fewest < FEW_EXPERIMENTS:
        fig.text(
            0.5,
            -0.01,
            f"{fewest} experiment{'s' if fewest != 1 else ''}: too few for "
            f"bands (they need {FEW_EXPERIMENTS} or more per learner); each step is one experiment",
            ha="center",
            va="top",
            fontsize="small",
            color="firebrick",
        )
    return fig


def plot_performance_profiles(
    scores: dict[tuple[str, str], Any],
    stem: str | os.PathLike,
    what: str = "final return (mean of the last trials)",
) -> list[pathlib.Path]:
    """Performance profiles (Agarwal et al. 2021): per learner, the fraction of its experiments whose
    score exceeds each threshold tau, with pointwise 95% bootstrap bands; a profile above another
    is better over the whole distribution, not only on average.

    Args:
      scores: (run label, algorithm) -> the per-experiment scores (shape (experiments,)); an empty
        run label for a single run.
      stem: output path without suffix; a .png and a .pdf are written.
      what: the score's name on the x axis.
    """
    return save_figure(performance_profiles_figure(scores, what), stem)

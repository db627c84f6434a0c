"""A sweep's figures: each metric against each swept parameter, from ``sweep.csv``'s rows."""

from __future__ import annotations

import json
import pathlib

import matplotlib

matplotlib.use("Agg")  # files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rmac_mj.evaluation.metrics import FEW_EXPERIMENTS, FIRST_MINUTES  # noqa: E402
from rmac_mj.sweeps.sweep_file import Sweep, is_number, short_names, value_label  # noqa: E402


def _axis_values(values: list) -> tuple[list[float], list[str] | None]:
    """Positions on the x axis: the values themselves when all are numbers, else 0, 1, 2, ... with
    the values as tick labels."""
    if all(is_number(v) for v in values):
        return [float(v) for v in values], None
    return list(range(len(values))), [value_label(v) if v is not None else "-" for v in values]


def _sweep_metrics(rows: list[dict]) -> dict[str, tuple[str, str | None, str | None, str]]:
    """Metric -> (column, CI low column, CI high column, axis label) of the sweep_<metric>.png
    figures; the labels say what the rows measured (the final window, the stuck threshold)."""
    windows = sorted({row["final_window"] for row in rows})
    window = f"the last {windows[0]} trials" if len(windows) == 1 else "the last trials"
    thresholds = sorted({row["stuck_below"] for row in rows if row.get("stuck_below") is not None})
    stuck = f" (final level < {thresholds[0]:.0f})" if len(thresholds) == 1 else ""
    return {
        "final_return": (
            "final_return_mean",
            "final_return_ci95_low",
            "final_return_ci95_high",
            f"final return (mean of {window})",
        ),
        "greedy_return": (
            "greedy_return_mean",
            "greedy_return_ci95_low",
            "greedy_return_ci95_high",
            "greedy return (last evaluation)",
        ),
        "minutes_to_90pct": (
            "minutes_to_90pct",
            None,
            None,
            "simulated minutes to within 10% of the final level",
        ),
        "first_5min": (
            "mean_return_first_5min",
            "first_5min_ci95_low",
            "first_5min_ci95_high",
            f"mean return of the first {FIRST_MINUTES:g} simulated minutes",
        ),
        "stuck": ("stuck_experiments", None, None, f"stuck experiments{stuck}"),
        "gap_to_optimal": ("gap_to_optimal", None, None, "near-optimal return - final return"),
        "wall_time": ("wall_time_s", None, None, "wall time of its experiments, summed [s]"),
    }


def _choices(rows: list[dict], parameter: str) -> list:
    """The distinct values of ``parameter`` in the rows, in their first order."""
    choices = []
    for row in rows:
        if all(json.dumps(row.get(parameter)) != json.dumps(c) for c in choices):
            choices.append(row.get(parameter))
    return choices


def _series(rows: list[dict], parameter: str, parameters: list[str], choices, positions):
    """The rows as lines of a parameter's panel: line label -> [(x, row)], a line joining the
    configurations that share every other swept value (and the learner)."""
    others = [p for p in parameters if p != parameter]
    several_learners = len({r["algorithm"] for r in rows}) > 1
    series: dict[str, list] = {}
    for row in rows:
        key = ", ".join(
            [
                f"{short_names(others).get(p, p) if p != 'variant' else 'variant'}"
                f"={value_label(row.get(p))}"
                for p in others
            ]
            + ([row["algorithm"]] if several_learners else [])
        )
        x = positions[[json.dumps(c) for c in choices].index(json.dumps(row.get(parameter)))]
        series.setdefault(key, []).append((x, row))
    return series


def _column(points, column: str) -> list[float]:
    return [np.nan if r.get(column) is None else r[column] for _, r in points]


def _draw_series(ax, series, columns, logarithmic: bool, span: float) -> None:
    """Each line of ``series``, with error bars where ``columns`` (value, low, high) has them."""
    column, low_column, high_column = columns
    for number, (key, points) in enumerate(series.items()):
        points.sort(key=lambda p: p[0])
        # Lines side by side, a little apart, so that their error bars do not hide each other.
        dodge = 0.012 * span * (number - (len(series) - 1) / 2)
        xs = [x * 10**dodge if logarithmic else x + dodge for x, _ in points]
        ys = _column(points, column)
        if low_column is not None:
            low, high = _column(points, low_column), _column(points, high_column)
            errors = np.abs(np.array([np.subtract(ys, low), np.subtract(high, ys)]))
            ax.errorbar(
                xs, ys, yerr=errors, marker="o", capsize=3, linewidth=1.2, label=key or None
            )
        else:
            ax.plot(xs, ys, marker="o", linewidth=1.2, label=key or None)


def _draw_panel(ax, rows: list[dict], parameter: str, parameters: list[str], columns, label: str):
    """A metric (``columns``: value, low, high) against one swept parameter."""
    choices = _choices(rows, parameter)
    positions, ticks = _axis_values(choices)
    series = _series(rows, parameter, parameters, choices, positions)
    logarithmic = (
        ticks is None and all(p > 0 for p in positions) and max(positions) >= 10 * min(positions)
    )
    span = (
        np.log10(max(positions) / min(positions))
        if logarithmic
        else max(positions) - min(positions)
    ) or 1.0
    _draw_series(ax, series, columns, logarithmic, span)
    if ticks is not None:
        slanted = max(map(len, ticks)) > 6
        ax.set_xticks(
            positions, ticks, rotation=30 if slanted else 0, ha="right" if slanted else "center"
        )
    elif logarithmic:
        ax.set_xscale("log")
        ax.set_xticks(positions, [value_label(c) for c in choices])
    ax.set_xlabel(parameter)
    ax.set_ylabel(label)
    ax.grid(alpha=0.3)
    if any(series) and len(series) <= 12:
        ax.legend(fontsize="x-small")


def _sweep_figure(sweep: Sweep, rows: list[dict], parameters: list[str], columns, label: str):
    """One metric's figure: a panel per swept parameter, each as wide as its tick labels need."""
    widths = [max(4.8, 0.9 * len({json.dumps(row.get(p)) for row in rows})) for p in parameters]
    fig, axes = plt.subplots(
        1,
        len(parameters),
        figsize=(max(sum(widths), 6.4), 3.8),
        squeeze=False,
        constrained_layout=True,
        gridspec_kw={"width_ratios": widths},
    )
    for ax, parameter in zip(axes[0], parameters):
        _draw_panel(ax, rows, parameter, parameters, columns, label)
    fig.suptitle(f"{sweep.path.name}: {label}", fontsize="medium")
    fewest = min(row["experiments"] for row in rows)
    if fewest < FEW_EXPERIMENTS and columns[1] is not None:
        fig.text(
            0.5,
            -0.02,
            f"{fewest} experiment{'s' if fewest != 1 else ''} per configuration: "
            f"95% intervals from fewer than {FEW_EXPERIMENTS} mean little",
            ha="center",
            va="top",
            fontsize="small",
            color="firebrick",
        )
    return fig


def plot_sweep(sweep: Sweep, rows: list[dict], out: pathlib.Path) -> list[pathlib.Path]:
    """``out/sweep_<metric>.png``: each metric against each swept parameter, one panel per parameter.

    In a parameter's panel each line joins the configurations that share every other swept value
    (and the learner), drawn slightly apart; error bars are 95% confidence intervals where the
    metric has one.
    """
    parameters = sweep.parameters or ["configuration"]
    paths = []
    for metric, (column, low_column, high_column, label) in _sweep_metrics(rows).items():
        if all(row.get(column) is None for row in rows):
            continue  # e.g. no greedy evaluations, no optimum
        fig = _sweep_figure(sweep, rows, parameters, (column, low_column, high_column), label)
        path = out / f"sweep_{metric}.png"
        fig.savefig(path, dpi=120, bbox_inches="tight")
        plt.close(fig)
        paths.append(path)
    return paths

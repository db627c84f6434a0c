"""Sweeps: each configuration of a sweep file run as a ``reproduce`` directory, in one pool.

Configuration ``name`` runs into ``OUT/<name>/`` with the same seeds as the others (paired
differences); ``OUT/sweep.json`` is the index, ``OUT/sweep.csv`` one row per configuration and
learner (:data:`COLUMNS`), ``OUT/sweep_<metric>.png`` the figures.
"""

from __future__ import annotations

import json
import math
import pathlib
from typing import Any

from rmac_mj import constraints
from rmac_mj.evaluation import LearnerSummary, metrics, report
from rmac_mj.experiments import runner
from rmac_mj.results import files
from rmac_mj.results.documents import ResumeRefused, added_experiments
from rmac_mj.results.store import ResultStore
from rmac_mj.sweeps.sweep_file import Sweep

#: sweep.csv's columns after the configuration, the swept parameters and the learner.
COLUMNS = (
    "experiments",
    "final_return_mean",
    "final_return_ci95_low",
    "final_return_ci95_high",
    "greedy_trial",
    "greedy_return_mean",
    "greedy_return_ci95_low",
    "greedy_return_ci95_high",
    "minutes_to_90pct",
    "mean_return_first_5min",
    "first_5min_ci95_low",
    "first_5min_ci95_high",
    "stuck_experiments",
    "optimal_return",
    "gap_to_optimal",
    "exploration_floor",
    "wall_time_s",
)


class SweepResumeRefused(ResumeRefused):
    """The output directory holds another sweep (or an unfinished one without --resume)."""


def _prepare(out: pathlib.Path, sweep: Sweep, resume: bool) -> None:
    """Write (or, resuming, check) ``out/sweep.json``: the parsed file and the index of directories."""
    index = out / "sweep.json"
    document = {
        "sweep": sweep.as_dict(),
        "parameters": sweep.parameters,
        "configurations": [
            {"directory": c.name, "variant": c.variant, "values": files.as_jsonable(c.values)}
            for c in sweep.configurations
        ],
    }
    if index.exists():
        if not resume:
            raise SweepResumeRefused(
                f"{out} already holds a sweep; pass --resume to finish it, or choose another --out"
            )
        try:
            existing = json.loads(
                files.read_bounded(index, constraints.RESULT_DOCUMENT_BYTES, "a sweep's index")
            )
        except (OSError, ValueError, RecursionError) as error:  # unreadable, not UTF-8, not JSON
            raise SweepResumeRefused(
                f"{index} is damaged ({error}); which sweep {out} holds cannot "
                "be told: choose another --out"
            ) from None
        if not isinstance(existing, dict):
            raise SweepResumeRefused(
                f"{index} is damaged (not a sweep's index: no JSON object); choose another --out"
            )
        stored = {k: existing.get(k) for k in document}
        if stored == document:
            return
        if not (_added_experiments(stored, document) or 0) > 0:
            raise SweepResumeRefused(
                f"{out} holds a sweep of a different file or size (--experiments, --trials, "
                "--steps); refusing to mix results (use another --out; a resume may only add "
                "experiments)"
            )
        # the file adds experiments and changes nothing else: each configuration's run grows too
        before = stored["sweep"]["protocol"]["experiments"]
        grown = [*existing.get("experiments_grown_from", []), before]
        _write_index(out, sweep, {**existing, **document, "experiments_grown_from": grown})
        return
    out.mkdir(parents=True, exist_ok=True)
    _write_index(out, sweep, {**document, "provenance": files.provenance()})


def _write_index(out: pathlib.Path, sweep: Sweep, document: dict[str, Any]) -> None:
    """``out/sweep.json`` (``document``, the file's path and the sizes the command line gave over
    the file's) and ``out/sweep.toml``, the file's copy."""
    document = {**document, "source": str(sweep.path)}
    document.pop("command_line_sizes", None)  # a grown sweep's earlier start: this one's say
    if sweep.sizes:
        document["command_line_sizes"] = dict(sweep.sizes)
    files.write_json(out / "sweep.json", document)
    text = sweep.path.read_bytes()
    files.write_atomic(out / "sweep.toml", lambda handle: handle.write(text))


def _added_experiments(stored: dict[str, Any], document: dict[str, Any]) -> int | None:
    """The experiments per configuration the sweep ``document`` adds to the ``stored`` index when it
    differs in nothing else (:func:`~rmac_mj.results.documents.added_experiments`)."""
    before, now = stored.get("sweep"), document["sweep"]
    if not isinstance(before, dict):
        return None
    if {**stored, "sweep": {**before, "protocol": None}} != {
        **document,
        "sweep": {**now, "protocol": None},
    }:
        return None
    return added_experiments(before.get("protocol"), now["protocol"])


def run_sweep(
    sweep: Sweep,
    out: str | pathlib.Path,
    options: runner.RunOptions | None = None,
) -> list[dict[str, Any]]:
    """Run (or finish, with ``options.resume``) every configuration of ``sweep`` into ``out``.

    Writes ``out/sweep.json`` (the index), one result directory per configuration, ``out/sweep.csv``
    and, with ``options.figures``, ``out/sweep_<metric>.png``. Returns the csv's rows. ``options``:
    how each configuration is run (:class:`runner.RunOptions`).
    """
    options = options or runner.RunOptions()
    out = pathlib.Path(out)
    with ResultStore(
        out
    ).lock():  # one sweep at a time in a directory (each run also locks its own)
        _prepare(out, sweep, options.resume)
        runs = [(c.protocol, out / c.name) for c in sweep.configurations]
        summaries = runner.run_protocols(runs, options)
    rows = sweep_rows(sweep, summaries)
    write_csv(out / "sweep.csv", sweep, rows)
    if options.figures:
        from rmac_mj.sweeps import figure

        figure.plot_sweep(sweep, rows, out)
    return rows


def sweep_rows(sweep: Sweep, summaries: list[dict[str, Any]]) -> list[dict]:
    """One row per configuration and learner: the swept values and the metrics of :data:`COLUMNS`,
    read from each configuration's summary; also ``final_window`` and ``stuck_below`` (for labels)."""
    rows = []
    for configuration, summary in zip(sweep.configurations, summaries):
        for algorithm in configuration.protocol.algorithms:
            learner = LearnerSummary.from_dict(summary[algorithm])
            row: dict[str, Any] = {"configuration": configuration.name}
            if sweep.variants:
                row["variant"] = configuration.variant
            row.update(configuration.values)
            row["algorithm"] = algorithm
            row["experiments"] = learner.experiments
            row["final_return_mean"] = learner.final_return_mean
            row["final_return_ci95_low"], row["final_return_ci95_high"] = learner.final_return_ci95
            if learner.greedy_eval_trials:
                row["greedy_trial"] = learner.greedy_eval_trials[-1]
                row["greedy_return_mean"] = learner.greedy_return_last_mean
                (row["greedy_return_ci95_low"], row["greedy_return_ci95_high"]) = (
                    learner.greedy_return_last_ci95
                )
            row["minutes_to_90pct"] = learner.minutes_to_90pct
            row["mean_return_first_5min"] = learner.mean_return_first_5min
            row["first_5min_ci95_low"], row["first_5min_ci95_high"] = learner.first_5min_ci95
            row["stuck_experiments"] = learner.stuck_experiments
            row["optimal_return"] = summary.get("optimal_return")
            row["gap_to_optimal"] = learner.gap_to_optimal
            row["exploration_floor"] = learner.exploration_floor
            row["wall_time_s"] = learner.experiment_wall_s_total
            row["final_window"] = learner.final_window
            row["stuck_below"] = learner.stuck_below
            rows.append(
                {
                    k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                    for k, v in row.items()
                }
            )
    return rows


def _cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    return value


def write_csv(path: pathlib.Path, sweep: Sweep, rows: list[dict]) -> pathlib.Path:
    """``sweep.csv``: configuration, [variant,] one column per grid key, algorithm, :data:`COLUMNS`.
    Lists (e.g. input weights) are written as JSON; a missing value (no greedy evaluation, no
    optimum, a CI of one experiment) as an empty cell."""
    header = [
        "configuration",
        *(["variant"] if sweep.variants else []),
        *sweep.grid,
        "algorithm",
        *COLUMNS,
    ]
    return files.write_csv(
        path, header, ([_cell(row.get(column)) for column in header] for row in rows)
    )


def _interval(low: float | None, high: float | None, experiments: int) -> str | None:
    """``"[low, high]"``, or None where there is none or it is withheld (too few experiments; a
    sweep written before intervals were withheld holds them)."""
    if low is None or high is None or metrics.withheld(experiments) is not None:
        return None
    return f"[{low:.0f}, {high:.0f}]"


def format_table(sweep: Sweep, rows: list[dict]) -> str:
    """The end-of-sweep table for the terminal: one line per configuration and learner; a column
    claims a 95% interval only where some row has one, and the greedy return at the last
    evaluation is shown when the sweep evaluated."""
    width = max([len(r["configuration"]) for r in rows] + [13])
    finals = [
        _interval(r["final_return_ci95_low"], r["final_return_ci95_high"], r["experiments"])
        for r in rows
    ]
    greedies = [
        _interval(
            r.get("greedy_return_ci95_low"), r.get("greedy_return_ci95_high"), r["experiments"]
        )
        for r in rows
    ]
    evaluated = any(r.get("greedy_return_mean") is not None for r in rows)
    final_title = "final return [95% CI]" if any(finals) else "final return"
    greedy_title = "greedy at end [95% CI]" if any(greedies) else "greedy at end"
    header = (
        f"{'configuration':<{width}} {'learner':>7} {final_title:>24} "
        + (f"{greedy_title:>24} " if evaluated else "")
        + f"{'min to 90%':>10} {'first 5 min':>11} {'stuck':>5}"
    )
    lines = [header, "-" * len(header)]
    for row, final_ci, greedy_ci in zip(rows, finals, greedies):
        # n/a where the header claims an interval this row has not
        final = f"{row['final_return_mean']:.1f}" + (f" {final_ci or 'n/a'}" if any(finals) else "")
        greedy = _greedy_cell(row, greedy_ci, any(greedies)) if evaluated else ""
        first = row["mean_return_first_5min"]  # None for a run shorter than the window
        stuck = row["stuck_experiments"]  # None without a reference return to judge "stuck" by
        lines.append(
            f"{row['configuration']:<{width}} {row['algorithm']:>7} {final:>24} {greedy}"
            f"{row['minutes_to_90pct']:>10.1f} {'n/a' if first is None else f'{first:.1f}':>11} "
            f"{'' if stuck is None else stuck:>5}"
        )
    return "\n".join(lines + _table_notes(rows, evaluated))


def _greedy_cell(row: dict, interval: str | None, intervals: bool) -> str:
    """A row's greedy return at the end (its interval where the column claims ``intervals``)."""
    mean = row.get("greedy_return_mean")
    greedy = "n/a" if mean is None else f"{mean:.1f}"
    if intervals and mean is not None:
        greedy += f" {interval or 'n/a'}"
    return f"{greedy:>24} "


def _table_notes(rows: list[dict], evaluated: bool) -> list[str]:
    """The lines under the table: what its final return and greedy return are, and a note where
    the experiments are too few for intervals."""
    windows = sorted({row["final_window"] for row in rows})
    short = (
        f" (the window is {metrics.FINAL_WINDOW} trials; these runs are shorter)"
        if max(windows) < metrics.FINAL_WINDOW
        else ""
    )
    lines = [
        f"final return: mean of the last {', '.join(map(str, windows))} trials per experiment"
        f"{short}; first 5 min: of the trials within the first {metrics.FIRST_MINUTES:g} "
        "simulated minutes"
    ]
    if evaluated:
        trials = sorted({row["greedy_trial"] for row in rows if row.get("greedy_trial")})
        lines.append(
            f"greedy at end: the greedy evaluation after trial {', '.join(map(str, trials))}, the "
            "mean over the experiments"
        )
    fewest = min(row["experiments"] for row in rows)
    if fewest < metrics.FEW_EXPERIMENTS:
        lines.append(report.few_experiments_note(fewest))
    return lines

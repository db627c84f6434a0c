"""The numbers and figures of docs/baselines.md, from the result directories of its runs.

    python scripts/reports/baselines_report.py RUNS [--out docs]

RUNS holds, per task (``pendulum``, ``arm``), the ``rmac-mj reproduce`` directories ``paper`` (RMAC,
S-AC, MLAC), ``ppo`` and ``offpolicy`` (SAC, TD3) and the learning-rate check
``rates/<learner>-lr<rate>`` (the commands are in docs/baselines.md). A directory may be unfinished:
every experiment whose curves are saved counts, and the tables say how many of those planned there
are. Prints the markdown tables; draws ``baselines_fig2_<task>.png`` (Fig. 2 of every learner) and
``baselines_profiles_<task>.png`` (performance profiles of the greedy return at 10 simulated
minutes). Everything is recomputed from the saved curves with the package's metrics, statistics and
figures, so nothing is retrained.
"""

from __future__ import annotations

import argparse
import json
import pathlib

import numpy as np

from rmac_mj.agents import config_class, display_name
from rmac_mj.evaluation import (
    Estimate,
    LearnerSummary,
    final_returns,
    iqm,
    iqm_interval,
    probability_of_improvement,
    summarise,
    trials_in,
)
from rmac_mj.figures import learning_curves_figure, performance_profiles_figure, save_figure
from rmac_mj.results import Curves, ResultStore

#: Where the figures go by default: the repository's docs/, wherever the script is run from.
DOCS = pathlib.Path(__file__).resolve().parents[2] / "docs"
TASKS = ("pendulum", "arm")
#: Run directory -> its learners.
RUNS = {"paper": ("rmac", "s-ac", "mlac"), "ppo": ("sb3-ppo",), "offpolicy": ("sb3-sac", "sb3-td3")}
LEARNERS = ("rmac", "s-ac", "mlac", "sb3-sac", "sb3-td3", "sb3-ppo")
#: The budget every learner has: 10 simulated minutes (200 trials of 3 s on both tasks).
COMMON_MINUTES = 10.0
#: Trials of the running mean in Fig. 2.
SMOOTH = 10


class Task:
    """One task's runs: each learner's saved curves, how many experiments were planned, and the
    task's facts from the summaries (trial length, near-optimal return, exploring floor)."""

    def __init__(self, root: pathlib.Path):
        self.curves: dict[str, Curves] = {}
        self.planned: dict[str, int] = {}
        self.name, self.facts = "", {}
        for run, learners in RUNS.items():
            store = ResultStore(root / run)
            if not store.config_path.is_file():
                continue
            protocol = json.loads(store.config_path.read_text())["protocol"]
            self.name = f"{protocol['domain']}/{protocol['task']}"
            if store.summary_path.is_file():
                summary = store.read_summary()
                for key in ("trial_seconds", "optimal_return", "exploration_floor"):
                    if summary.get(key) is not None:
                        self.facts.setdefault(key, summary[key])
            for learner in learners:
                if store.finished(learner):
                    self.curves[learner] = store.load_curves(learner)
                    self.planned[learner] = protocol["experiments"]
        self.seconds = float(self.facts.get("trial_seconds", np.nan))

    def learners(self) -> list[str]:
        return [learner for learner in LEARNERS if learner in self.curves]

    def greedy_at(self, learner: str, minutes: float = COMMON_MINUTES) -> np.ndarray:
        """Each experiment's greedy return after the learning trial that ends at ``minutes``;
        shape (experiments,)."""
        curve = self.curves[learner]
        column = list(curve.greedy_trials).index(trials_in(minutes, self.seconds))
        return curve.greedy_returns[:, column]

    def summary(self, learner: str) -> LearnerSummary:
        curve = self.curves[learner]
        return summarise(
            curve.returns,
            curve.greedy_returns,
            curve.greedy_trials,
            self.facts.get("optimal_return"),
            trial_seconds=self.seconds,
            cpu_times=curve.cpu_times,
        )


def fmt(estimate: Estimate, digits: int = 0) -> str:
    return f"{estimate.value:.{digits}f} [{estimate.low:.{digits}f}, {estimate.high:.{digits}f}]"


def table(task: Task) -> list[str]:
    rows = [
        "| learner | experiments (of planned) | trials (simulated min) | min to within 10% of its "
        "final level | first 5 min, IQM [95% CI] | final return, IQM [95% CI] | greedy at 10 min, "
        "IQM [95% CI] | greedy at its end, IQM | stuck | CPU s per simulated min |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for learner in task.learners():
        c, s = task.curves[learner], task.summary(learner)
        n, trials = c.returns.shape
        greedy10 = iqm_interval(task.greedy_at(learner))
        first = Estimate(s.first_5min_iqm, *s.first_5min_iqm_ci95)
        final = Estimate(s.final_return_iqm, *s.final_return_iqm_ci95)
        rows.append(
            f"| {display_name(learner)} | {n} ({task.planned[learner]}) | {trials} "
            f"({trials * task.seconds / 60:g}) | {s.minutes_to_90pct:.1f} | {fmt(first)} | "
            f"{fmt(final)} | {fmt(greedy10)} | {iqm(c.greedy_returns[:, -1]):.0f} | "
            f"{s.stuck_experiments}/{n} | {s.cpu_s_per_simulated_minute:.3g} |"
        )
    return rows


def headline(loaded: dict[str, Task]) -> list[str]:
    """The README's table: per learner, over the tasks (a column each, values joined by " / "): the
    experiments x trials, the final return (IQM, interval), the greedy return at 10 simulated minutes
    (IQM), the minutes to within 10% of the final level, and the CPU cost."""
    names = " / ".join(task.name.split("/")[0] for task in loaded.values())
    rows = [
        f"| learner ({names}) | experiments x trials | final return, IQM [95% CI] | greedy at 10 "
        "min, IQM | min to within 10% of final | CPU s per simulated min |",
        "|---|---|---|---|---|---|",
    ]
    for learner in LEARNERS:
        cells: list[list[str]] = [[], [], [], [], []]
        for task in loaded.values():
            if learner not in task.curves:
                for column in cells:
                    column.append("-")
                continue
            s, (n, trials) = task.summary(learner), task.curves[learner].returns.shape
            final = Estimate(s.final_return_iqm, *s.final_return_iqm_ci95)
            for column, value in zip(
                cells,
                (
                    f"{n} x {trials}",
                    fmt(final),
                    f"{iqm(task.greedy_at(learner)):.0f}",
                    f"{s.minutes_to_90pct:.1f}",
                    f"{s.cpu_s_per_simulated_minute:.2g}",
                ),
            ):
                column.append(value)
        rows.append(
            f"| {display_name(learner)} | " + " | ".join(" / ".join(c) for c in cells) + " |"
        )
    return rows


def improvement(task: Task, scores: dict[str, np.ndarray]) -> list[str]:
    """P(row > column) of ``scores`` (learner -> per-experiment score), with 95% intervals."""
    names = list(scores)
    rows = [
        "| P(row > column) | " + " | ".join(display_name(n) for n in names) + " |",
        "|---" * (len(names) + 1) + "|",
    ]
    for a in names:
        cells = []
        for b in names:
            e = None if a == b else probability_of_improvement(scores[a], scores[b])
            cells.append("" if e is None else f"{e.value:.2f} [{e.low:.2f}, {e.high:.2f}]")
        rows.append(f"| {display_name(a)} | " + " | ".join(cells) + " |")
    return rows


def aggregate(loaded: dict[str, Task]) -> list[str]:
    """IQM over both tasks of the near-optimal return divided by the greedy return at 10 minutes (1
    is optimal, 0.5 twice the optimum's cost), tasks as the bootstrap's strata."""
    rows = [
        "| learner | both tasks: near-optimal / greedy return at 10 min, IQM [95% CI] |",
        "|---|---|",
    ]
    for learner in LEARNERS:
        strata = [
            task.facts["optimal_return"] / task.greedy_at(learner)
            for task in loaded.values()
            if learner in task.curves and "optimal_return" in task.facts
        ]
        if len(strata) == len(loaded):
            rows.append(f"| {display_name(learner)} | {fmt(iqm_interval(strata), 3)} |")
    return rows


def figures(key: str, task: Task, out: pathlib.Path) -> None:
    """Fig. 2 of every learner (the package's own figure: mean, t-interval, greedy trials) and the
    performance profiles of the greedy return at 10 simulated minutes."""
    summary = {
        "trial_seconds": task.seconds,
        **{n: task.summary(n).as_dict() for n in task.learners()},
    }
    fig = learning_curves_figure(
        {task.name: summary},
        task.facts.get("optimal_return"),
        smooth=SMOOTH,
        exploration_floor=task.facts.get("exploration_floor"),
    )
    fig.suptitle(f"{task.name}: every learner on the simulated-time axis (SAC and TD3: 10 min)")
    save_figure(fig, out / f"baselines_fig2_{key}", formats=("png",))
    scores = {("", n): task.greedy_at(n) for n in task.learners()}
    fig = performance_profiles_figure(scores, "greedy return at 10 simulated minutes")
    fig.axes[0].set_title(f"{task.name}: performance profiles, 95% stratified-bootstrap bands")
    save_figure(fig, out / f"baselines_profiles_{key}", formats=("png",))


def rates(root: pathlib.Path, task: Task) -> list[str]:
    """The learning-rate check. The default rate's row is the main run's first experiments over the
    check's trials: the same seeds, so the same experiments as a run of that length."""
    rows = [
        "| learner | learning rate | experiments x trials | learning return, last 50 trials, "
        "mean | greedy at the end, mean |",
        "|---|---|---|---|---|",
    ]
    found: dict[str, list] = {}
    for directory in sorted((root / "rates").glob("*-lr*")):
        learner, rate = directory.name.rsplit("-lr", 1)
        store = ResultStore(directory)
        if store.finished(learner):
            c = store.load_curves(learner)
            found.setdefault(learner, []).append((float(rate), c.returns, c.greedy_returns[:, -1]))
    for learner, runs in found.items():
        experiments, trials = runs[0][1].shape
        if learner in task.curves:
            main = task.curves[learner]
            last = list(main.greedy_trials).index(trials)
            runs.append(
                (
                    config_class(learner)().learning_rate,
                    main.returns[:experiments, :trials],
                    main.greedy_returns[:experiments, last],
                )
            )
        for rate, returns, greedy in sorted(runs, key=lambda run: run[0]):
            rows.append(
                f"| {display_name(learner)} | {rate:g} | {len(returns)} x {trials} | "
                f"{final_returns(returns).mean():.0f} | {greedy.mean():.0f} |"
            )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=pathlib.Path)
    parser.add_argument("--out", type=pathlib.Path, default=DOCS)
    args = parser.parse_args()
    loaded = {key: Task(args.runs / key) for key in TASKS}
    loaded = {key: task for key, task in loaded.items() if task.curves and task.facts}
    for key, task in loaded.items():
        facts = ", ".join(f"{k} {v:.2f}" for k, v in task.facts.items() if k != "trial_seconds")
        print(f"\n### {task.name} ({facts})\n")
        print("\n".join(table(task)))
        print(
            f"\nProbability of improvement, greedy return at {COMMON_MINUTES:g} simulated minutes:\n"
        )
        print("\n".join(improvement(task, {n: task.greedy_at(n) for n in task.learners()})))
        print("\nProbability of improvement, final return (each learner at its own end):\n")
        print(
            "\n".join(
                improvement(
                    task,
                    {n: final_returns(task.curves[n].returns) for n in task.learners()},
                )
            )
        )
        check = rates(args.runs / key, task)
        if len(check) > 2:
            print("\nLearning-rate check:\n")
            print("\n".join(check))
        figures(key, task, args.out)
    if len(loaded) > 1:
        print("\n" + "\n".join(aggregate(loaded)))
    print("\nThe README's headline:\n\n" + "\n".join(headline(loaded)))


if __name__ == "__main__":
    main()

"""MPC's planner with a larger population or more iterations, on the panel's protocols (docs/mpc.md).

Usage: python scripts/studies/planner_population.py OUT [--variants base,population_64,iterations_6]
       [--tasks dc_pendulum,...] [--experiments 3] [--seed 1] [--jobs N] [--report-only]

Runs `recommended` (MPC) with each variant of its planner's settings on each panel task's own
protocol (`rmac-mj panel`'s, seed 1 by default: the panel's seed 0 is not used to choose), into
OUT/<variant>/<task>/ (resumable), then prints per variant and task the greedy return at the goal's
trial (IQM over experiments, each experiment's), the experiments at the goal and the CPU per
experiment and per control step, as docs/panel.md reads them. `--report-only` prints the rows of
what OUT holds (a run of another code version is not resumed: its results are not mixed).
"""

import argparse
import dataclasses
import pathlib

from rmac_mj.experiments import panel, runner

#: The planner settings each variant changes (``MPCConfig.planner``, ``SamplingPlanner``'s fields).
VARIANTS = {
    "base": {},
    "population_64": {"population": 64},
    "iterations_6": {"iterations": 6},
}


def protocols(out: pathlib.Path, variants, tasks, experiments: int, seed: int):
    """(protocol, directory) of every variant on every task."""
    for name in variants:
        overrides = {"recommended": {"planner": VARIANTS[name]}} if VARIANTS[name] else {}
        for task in panel.tasks_named(tasks):
            protocol = task.make_protocol(["recommended"], experiments, seed=seed)
            protocol = dataclasses.replace(protocol, agent_configs=overrides)
            yield protocol, out / name / task.name


def report(out: pathlib.Path, variants, tasks) -> None:
    for name in variants:
        for task in panel.tasks_named(tasks):
            for row in panel.panel_rows(task, [out / name / task.name]):
                at = row["greedy_trials"].index(task.goal_trial)
                each = ", ".join(f"{r[at]:.1f}" for r in row["greedy_per_experiment"])
                print(
                    f"{name:14s} {task.name:17s} {row['greedy']['iqm']:8.1f} ({each}) "
                    f"at goal {row['reached']}/{row['experiments']}, "
                    f"{row['cpu_s_per_experiment']:.1f} s CPU per experiment, "
                    f"{row['ms_per_control_step']:.2f} ms per control step"
                )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=pathlib.Path)
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--tasks", default=",".join(task.name for task in panel.TASKS))
    parser.add_argument("--experiments", type=int, default=3)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--jobs", type=int, default=None)
    parser.add_argument("--report-only", action="store_true")
    args = parser.parse_args()
    variants, tasks = args.variants.split(","), args.tasks.split(",")
    unknown = sorted(set(variants) - set(VARIANTS))
    if unknown:
        parser.error(f"unknown variants {unknown}; choose from {sorted(VARIANTS)}")
    if not args.report_only:
        runs = list(protocols(args.out, variants, tasks, args.experiments, args.seed))
        runner.run_protocols(runs, runner.RunOptions(jobs=args.jobs, resume=True, figures=False))
    report(args.out, variants, tasks)


if __name__ == "__main__":
    main()

"""The options of the commands that run experiments: ``reproduce``, ``sweep``, ``panel``."""

from __future__ import annotations

import pathlib
from collections.abc import Mapping
from typing import Any

from rmac_mj import constraints
from rmac_mj.cli.arguments import (
    add_command,
    add_outside_options,
    add_task_options,
    add_trust_env,
    control_seconds,
    non_negative_int,
    positive_int,
    size_within,
)
from rmac_mj.experiments import panel as panel_tasks

#: The Protocol fields ``reproduce`` has an option for (the option's dest is the field's name);
#: ``algorithms`` and ``prior_parts`` are given comma-separated.
PROTOCOL_OPTIONS = (
    "domain",
    "task",
    "algorithms",
    "experiments",
    "trials",
    "steps",
    "seed",
    "evaluate_every",
    "prior",
    "prior_trials",
    "prior_parts",
    "env",
    "learner_state",
    "action_repeat",
    "trial_steps",
    "control_timestep",
    "evaluate_starts",
)


def add_reproduce(commands, defaults: Mapping[str, Any] | None = None) -> None:
    """``reproduce``; ``defaults`` replace its own, by dest (a ``--config`` file's settings or
    those of a directory being resumed)."""
    from rmac_mj.agents import ALGORITHMS

    reproduce = add_command(
        commands,
        "reproduce",
        "run the paper's comparison (section 6): learning curves, summary, Fig. 2, snapshots",
    )
    add_task_options(reproduce, True, "default: the paper's swing-up")
    reproduce.add_argument(
        "--experiments",
        type=size_within(constraints.EXPERIMENTS),
        default=40,
        metavar="N",
        help="learning experiments per learner (default: 40, the paper's)",
    )
    reproduce.add_argument(
        "--trials",
        type=size_within(constraints.TRIALS),
        default=600,
        metavar="N",
        help="consecutive trials per experiment (default: 600, the "
        "paper's, of 3 s); with --steps, at most this many",
    )
    reproduce.add_argument(
        "--steps",
        type=positive_int,
        default=None,
        metavar="N",
        help="a budget of environment steps per experiment (learner steps x "
        "action repeat; greedy trials not counted): trials run until it is "
        "reached, the last to its end, or until --trials",
    )
    reproduce.add_argument(
        "--algorithms",
        default=None,
        metavar="ALGO[,ALGO]",
        help=f"comma-separated learners, from {', '.join(ALGORITHMS)} (default: "
        "rmac,s-ac, the paper's; with --set, only the learners --set names)",
    )
    reproduce.add_argument("--seed", type=non_negative_int, default=0, help="root random seed")
    reproduce.add_argument(
        "--jobs",
        type=positive_int,
        default=None,
        metavar="N",
        help="worker processes (default: all cores)",
    )
    reproduce.add_argument(
        "--out",
        type=pathlib.Path,
        default=pathlib.Path("results/reproduce"),
        help="result directory",
    )
    reproduce.add_argument(
        "--resume",
        action="store_true",
        help="finish an interrupted run in --out (same settings; a larger "
        "--experiments adds experiments to it)",
    )
    reproduce.add_argument(
        "--evaluate-every",
        type=non_negative_int,
        default=0,
        metavar="N",
        help="a greedy trial after every N learning trials (0: none)",
    )
    reproduce.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="Dask scheduler address (tcp://host:8786) to run experiments on",
    )
    reproduce.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="ALGO.FIELD=VALUE",
        help="override a hyperparameter, e.g. s-ac.rate_split=actor or "
        "rmac.exploration.sigma=0.5 (JSON values; repeatable). Without "
        "--algorithms only the learners named here run: an ablation of "
        "rmac does not rerun s-ac",
    )
    reproduce.add_argument(
        "--smooth",
        type=positive_int,
        default=1,
        metavar="N",
        help="Fig. 2: running mean over N trials (1: none)",
    )
    reproduce.add_argument(
        "--prior",
        default=None,
        metavar="DEMONSTRATOR|FILE.npz",
        help="seed every learner before its first trial with prior knowledge: "
        "trials of a demonstrator the task declares (e.g. 'demo') or "
        "recorded transitions (docs/prior-knowledge.md gives the format)",
    )
    reproduce.add_argument(
        "--prior-trials",
        type=size_within(constraints.PRIOR_TRIALS),
        default=None,
        help="demonstrator trials recorded per experiment (default 5)",
    )
    reproduce.add_argument(
        "--prior-parts",
        default=None,
        metavar="PART,...",
        help="seed only these kinds of knowledge: process, reference, critic, "
        "actor (default: all a learner takes)",
    )
    add_outside_options(reproduce)
    add_trust_env(reproduce, "the directory being resumed (--resume)")
    reproduce.add_argument(
        "--trial-steps",
        type=size_within(constraints.TRIAL_STEPS),
        default=None,
        metavar="N",
        help="with --env: learner steps after which a trial is truncated "
        "(default: the environment's own time limit)",
    )
    reproduce.add_argument(
        "--control-timestep",
        type=control_seconds,
        default=None,
        metavar="S",
        help="with --env: seconds per environment step, for an environment that "
        "does not say (e.g. MountainCarContinuous-v0)",
    )
    reproduce.add_argument(
        "--evaluate-starts",
        type=size_within(constraints.EVALUATE_STARTS),
        default=0,
        metavar="N",
        help="an evaluation is the mean of greedy trials from N starts drawn "
        "once per experiment (0: one greedy trial from the task's next "
        "start); for a task that starts anywhere, e.g. Pendulum-v1",
    )
    reproduce.add_argument(
        "--no-optimal",
        action="store_true",
        help="skip the near-optimal return (dynamic programming, about a "
        "minute the first time, then cached)",
    )
    reproduce.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress display (bars on a terminal, periodic lines otherwise)",
    )
    reproduce.add_argument(
        "--config",
        type=pathlib.Path,
        default=None,
        metavar="FILE.toml",
        help="protocol and hyperparameters from a sweep-style file with single "
        "values (docs/studies/README.md); options given here override it",
    )
    if defaults:
        reproduce.set_defaults(**defaults)


#: The Protocol fields that size a run, which ``sweep`` takes over its file's [protocol] table.
SWEEP_SIZE_OPTIONS = ("experiments", "trials", "steps")


def add_sweep(commands) -> None:
    """``sweep``: every configuration of a sweep file."""
    sweep = add_command(
        commands,
        "sweep",
        "run every configuration of a sweep file, each into a result directory of its own, and "
        "tabulate them (docs/guide/sweeps.md)",
    )
    sweep.add_argument(
        "file",
        type=pathlib.Path,
        metavar="SWEEP.toml",
        help="[protocol], [grid] and [[variant]] tables (docs/studies/README.md)",
    )
    sweep.add_argument(
        "--experiments",
        type=size_within(constraints.EXPERIMENTS),
        default=None,
        metavar="N",
        help="learning experiments per learner and configuration, over the file's",
    )
    sweep.add_argument(
        "--trials",
        type=size_within(constraints.TRIALS),
        default=None,
        metavar="N",
        help="trials per experiment (with steps: at most this many), over the file's",
    )
    sweep.add_argument(
        "--steps",
        type=positive_int,
        default=None,
        metavar="N",
        help="a budget of environment steps per experiment, over the file's",
    )
    sweep.add_argument(
        "--out",
        type=pathlib.Path,
        required=True,
        help="directory of the sweep: one result directory per configuration",
    )
    sweep.add_argument(
        "--jobs",
        type=positive_int,
        default=None,
        help="worker processes shared by all configurations (default: all cores)",
    )
    sweep.add_argument(
        "--scheduler",
        default=None,
        help="Dask scheduler address (tcp://host:8786) to run experiments on",
    )
    sweep.add_argument(
        "--resume",
        action="store_true",
        help="finish an interrupted sweep in --out (a file that only raises experiments adds them)",
    )
    sweep.add_argument(
        "--no-optimal",
        action="store_true",
        help="skip the near-optimal return and exploration floor",
    )
    sweep.add_argument("--no-progress", action="store_true", help="no progress display")


def add_panel(commands) -> None:
    """``panel``: the public panel of tasks."""
    panel = add_command(
        commands,
        "panel",
        "the public panel (docs/panel.md): seven tasks nobody tuned for, every "
        "learner at equal interaction, against fixed goals",
    )
    panel.add_argument(
        "--out",
        type=pathlib.Path,
        required=True,
        help="directory of the panel: one result directory per task",
    )
    panel.add_argument(
        "--algorithms",
        default="recommended,s-ac-dyna,sb3-sac,sb3-crossq",
        metavar="ALGO[,ALGO]",
        help="comma-separated learners",
    )
    panel.add_argument(
        "--experiments",
        type=size_within(constraints.EXPERIMENTS),
        default=5,
        metavar="N",
        help="learning experiments per learner and task",
    )
    panel.add_argument(
        "--tasks",
        default=None,
        metavar="TASK[,TASK]",
        help="some of the panel's tasks (default: all): "
        + ", ".join(task.name for task in panel_tasks.TASKS),
    )
    panel.add_argument("--seed", type=non_negative_int, default=0, help="root random seed")
    panel.add_argument(
        "--jobs",
        type=positive_int,
        default=None,
        metavar="N",
        help="worker processes shared by all tasks (default: all cores)",
    )
    panel.add_argument("--resume", action="store_true", help="finish an interrupted panel in --out")
    panel.add_argument(
        "--trials",
        type=size_within(constraints.TRIALS),
        default=None,
        metavar="N",
        help="every task only N trials, evaluated after each (a smoke test, not the panel)",
    )
    panel.add_argument("--no-progress", action="store_true", help="no progress display")

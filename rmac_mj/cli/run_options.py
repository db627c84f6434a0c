"""The options of the commands that run experiments: ``reproduce``, ``sweep``, ``panel``.

Every option is declared once, in :data:`OPTIONS`, with ``reproduce``'s help; a command names the
options it has, in the order of its help, with what is its own (help, default). An option that sets
a :class:`~rmac_mj.experiments.protocol.Protocol` field has the field's name as dest, and its values'
type and range are the field's declared constraints."""

from __future__ import annotations

import argparse
import pathlib
from collections.abc import Mapping
from typing import Any

from rmac_mj.cli.arguments import (
    add_command,
    add_outside_options,
    add_task_options,
    add_trust_env,
    constrained,
    positive_int,
)
from rmac_mj.experiments import panel as panel_tasks
from rmac_mj.experiments.protocol import Protocol

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

#: The Protocol fields that size a run, which ``sweep`` takes over its file's [protocol] table.
SWEEP_SIZE_OPTIONS = ("experiments", "trials", "steps")


def protocol_value(field: str):
    """An argparse type: a value of Protocol's ``field`` (a number), refused by the field's own
    constraints (``Protocol.parameter_constraints``), as a --config file's value is."""
    allowed = [c for c in Protocol.parameter_constraints[field] if c is not None]
    number = float if "float" in Protocol.__dataclass_fields__[field].type else int
    return constrained(allowed, number)


def _field(field: str, metavar: str | None = "N") -> dict[str, Any]:
    """An option setting Protocol's ``field``: its type and default are the field's."""
    return {
        "type": protocol_value(field),
        "default": Protocol.__dataclass_fields__[field].default,
        "metavar": metavar,
    }


#: Every option of the commands that run experiments, by dest: ``add_argument``'s keywords.
OPTIONS: dict[str, dict[str, Any]] = {
    "experiments": {
        **_field("experiments"),
        "help": "learning experiments per learner (default: 40, the paper's)",
    },
    "trials": {
        **_field("trials"),
        "help": "consecutive trials per experiment (default: 600, the paper's, of 3 s); with "
        "--steps, at most this many",
    },
    "steps": {
        **_field("steps"),
        "help": "a budget of environment steps per experiment (learner steps x action repeat; "
        "greedy trials not counted): trials run until it is reached, the last to its end, or "
        "until --trials",
    },
    "algorithms": {"default": None, "metavar": "ALGO[,ALGO]"},
    "seed": {**_field("seed", None), "help": "root random seed"},
    "jobs": {
        "type": positive_int,
        "default": None,
        "metavar": "N",
        "help": "worker processes (default: all cores)",
    },
    "out": {
        "type": pathlib.Path,
        "default": pathlib.Path("results/reproduce"),
        "help": "result directory",
    },
    "resume": {
        "action": "store_true",
        "help": "finish an interrupted run in --out (same settings; a larger --experiments adds "
        "experiments to it)",
    },
    "evaluate_every": {
        **_field("evaluate_every"),
        "help": "a greedy trial after every N learning trials (0: none)",
    },
    "scheduler": {
        "default": None,
        "metavar": "ADDRESS",
        "help": "Dask scheduler address (tcp://host:8786) to run experiments on",
    },
    "set": {
        "action": "append",
        "default": [],
        "metavar": "ALGO.FIELD=VALUE",
        "help": "override a hyperparameter, e.g. s-ac.rate_split=actor or "
        "rmac.exploration.sigma=0.5 (JSON values; repeatable). Without --algorithms only the "
        "learners named here run: an ablation of rmac does not rerun s-ac",
    },
    "smooth": {
        "type": positive_int,
        "default": 1,
        "metavar": "N",
        "help": "Fig. 2: running mean over N trials (1: none)",
    },
    "prior": {
        "default": None,
        "metavar": "DEMONSTRATOR|FILE.npz",
        "help": "seed every learner before its first trial with prior knowledge: trials of a "
        "demonstrator the task declares (e.g. 'demo') or recorded transitions "
        "(docs/prior-knowledge.md gives the format)",
    },
    "prior_trials": {
        **_field("prior_trials", None),
        "default": None,  # given or not: a recorded file takes none
        "help": "demonstrator trials recorded per experiment (default 5)",
    },
    "prior_parts": {
        "default": None,
        "metavar": "PART,...",
        "help": "seed only these kinds of knowledge: process, reference, critic, actor "
        "(default: all a learner takes)",
    },
    "trial_steps": {
        **_field("trial_steps"),
        "help": "with --env: learner steps after which a trial is truncated (default: the "
        "environment's own time limit)",
    },
    "control_timestep": {
        **_field("control_timestep", "S"),
        "help": "with --env: seconds per environment step, for an environment that does not say "
        "(e.g. MountainCarContinuous-v0)",
    },
    "evaluate_starts": {
        **_field("evaluate_starts"),
        "help": "an evaluation is the mean of greedy trials from N starts drawn once per "
        "experiment (0: one greedy trial from the task's next start); for a task that starts "
        "anywhere, e.g. Pendulum-v1",
    },
    "no_optimal": {
        "action": "store_true",
        "help": "skip the near-optimal return (dynamic programming, about 30 s of CPU the first "
        "time, then cached)",
    },
    "no_progress": {
        "action": "store_true",
        "help": "no progress display (bars on a terminal, periodic lines otherwise)",
    },
    "config": {
        "type": pathlib.Path,
        "default": None,
        "metavar": "FILE.toml",
        "help": "protocol and hyperparameters from a sweep-style file with single values "
        "(docs/studies/README.md); options given here override it",
    },
}


def add_options(parser: argparse.ArgumentParser, *dests: str, **own: dict[str, Any]) -> None:
    """The options ``dests`` of :data:`OPTIONS`, in that order, each with its keywords in ``own``
    (by dest) over the declared ones."""
    for dest in dests:
        parser.add_argument("--" + dest.replace("_", "-"), **{**OPTIONS[dest], **own.get(dest, {})})


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
    algorithms = {
        "help": f"comma-separated learners, from {', '.join(ALGORITHMS)} (default: rmac,s-ac, the "
        "paper's; with --set, only the learners --set names)"
    }
    add_options(
        reproduce,
        *("experiments", "trials", "steps", "algorithms", "seed", "jobs", "out", "resume"),
        *("evaluate_every", "scheduler", "set", "smooth", "prior", "prior_trials", "prior_parts"),
        algorithms=algorithms,
    )
    add_outside_options(reproduce)
    add_trust_env(reproduce, "the directory being resumed (--resume)")
    add_options(
        reproduce,
        *("trial_steps", "control_timestep", "evaluate_starts", "no_optimal", "no_progress"),
        "config",
    )
    if defaults:
        reproduce.set_defaults(**defaults)


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
    over_the_files = {
        "experiments": "learning experiments per learner and configuration",
        "trials": "trials per experiment (with steps: at most this many)",
        "steps": "a budget of environment steps per experiment",
    }
    add_options(
        sweep,
        *SWEEP_SIZE_OPTIONS,
        "out",
        "jobs",
        "scheduler",
        "resume",
        "no_optimal",
        "no_progress",
        **{
            dest: {"default": None, "help": f"{what}, over the file's"}
            for dest, what in over_the_files.items()
        },
        out={
            "required": True,
            "default": None,
            "help": "directory of the sweep: one result directory per configuration",
        },
        jobs={"help": "worker processes shared by all configurations (default: all cores)"},
        resume={
            "help": "finish an interrupted sweep in --out (a file that only raises experiments adds them)"
        },
        no_optimal={"help": "skip the near-optimal return and exploration floor"},
    )


def add_panel(commands) -> None:
    """``panel``: the public panel of tasks."""
    panel = add_command(
        commands,
        "panel",
        "the public panel (docs/panel.md): seven tasks nobody tuned for, every "
        "learner at equal interaction, against fixed goals",
    )
    add_options(
        panel,
        "out",
        "algorithms",
        "experiments",
        out={
            "required": True,
            "default": None,
            "help": "directory of the panel: one result directory per task",
        },
        algorithms={
            "default": "recommended,s-ac-dyna,sb3-sac,sb3-crossq",
            "help": "comma-separated learners",
        },
        experiments={
            "default": panel_tasks.EXPERIMENTS,
            "help": "learning experiments per learner and task",
        },
    )
    panel.add_argument(
        "--tasks",
        default=None,
        metavar="TASK[,TASK]",
        help="some of the panel's tasks (default: all): "
        + ", ".join(task.name for task in panel_tasks.TASKS),
    )
    add_options(
        panel,
        "seed",
        "jobs",
        "resume",
        "trials",
        "no_progress",
        jobs={"help": "worker processes shared by all tasks (default: all cores)"},
        resume={"help": "finish an interrupted panel in --out"},
        trials={
            "default": None,
            "help": "every task only N trials, evaluated after each (a smoke test, not the panel)",
        },
    )

"""The ``rmac-mj`` command line: every command's options, their types and defaults."""

from __future__ import annotations

import argparse
import math
import pathlib
from collections.abc import Mapping
from typing import Any

from rmac_mj import __version__, constraints
from rmac_mj.cli.common import PROG
from rmac_mj.experiments import panel as panel_tasks

DESCRIPTION = "The rmac-mj command: reproduce the paper's comparison, draw its figures, render videos, benchmark."

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


class _Parser(argparse.ArgumentParser):
    """Argument errors as one line and exit status 2, not a usage dump."""

    def error(self, message: str):  # noqa: D102
        self.exit(2, f"{self.prog}: error: {message}\n")


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Options' help with "(default: X)", except where there is nothing to say (None, False, [])
    or the help already says it."""

    def _get_help_string(self, action):
        if (
            action.default is None
            or action.default is False
            or action.default == []
            or "default" in (action.help or "")
        ):
            return action.help
        return super()._get_help_string(action)


def _int_at_least(minimum: int, expected: str):
    """An argparse type: an integer >= ``minimum``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {value}")
        return value

    return parse


_positive_int = _int_at_least(1, "a positive integer")


def _size(limit: constraints.Limit):
    """An argparse type: an integer within ``limit`` (a :class:`rmac_mj.constraints.Limit`), its
    reason said when refused."""
    allowed = [limit.constraint()]

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = text
        problem = constraints.unmet(value, allowed)
        if problem is not None:
            raise argparse.ArgumentTypeError(f"expected {problem}, got {text!r}")
        return value

    return parse


def _positive_seconds(text: str) -> float:
    """An argparse type: a positive, finite number of seconds."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a positive number of seconds, got {text!r}"
        ) from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return value


_non_negative_int = _int_at_least(0, "an integer >= 0")


def _floats(count: int | None, expected: str):
    """An argparse type: comma-separated finite numbers (``count`` of them, if given)."""

    def parse(text: str) -> tuple[float, ...]:
        try:
            values = tuple(float(v) for v in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
        if (count is not None and len(values) != count) or not all(map(math.isfinite, values)):
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
        return values

    return parse


def _dims(text: str) -> tuple[int, int]:
    try:
        i, j = (int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected two state dimensions I,J, got {text!r}"
        ) from None
    return i, j


def _json_object(text: str) -> dict:
    """An argparse type: a JSON object, e.g. '{"bounds": {"velocity": [-10, 10]}}'."""
    import json

    try:
        value = json.loads(text)
    except json.JSONDecodeError as error:
        raise argparse.ArgumentTypeError(
            f"expected a JSON object, got {text!r} ({error})"
        ) from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"expected a JSON object {{...}}, got {text!r}")
    return value


def _add_task_options(parser: argparse.ArgumentParser, default: bool, what: str) -> None:
    """--domain and --task; with ``default`` the suite's default task, else None (``what``); and
    --env, an outside environment instead."""
    from rmac_mj.tasks import DEFAULT_TASK

    parser.add_argument(
        "--domain",
        default=DEFAULT_TASK[0] if default else None,
        help=f"domain of the task suite ({what})",
    )
    parser.add_argument(
        "--task", default=DEFAULT_TASK[1] if default else None, help=f"task of the domain ({what})"
    )
    parser.add_argument(
        "--env",
        default=None,
        metavar="SPEC",
        help="an outside environment instead: dm_control:DOMAIN/TASK, gymnasium:ID, "
        "package.module:factory or path/file.py:factory (README, 'Your own "
        "task')",
    )


def _add_outside_options(parser: argparse.ArgumentParser) -> None:
    """What an outside environment (--env) may need beside its SPEC."""
    parser.add_argument(
        "--learner-state",
        type=_json_object,
        default=None,
        metavar="JSON",
        help="with --env: what the learners' state is where it cannot be inferred, "
        "some of LearnerStateSpec's fields or per-dimension bounds, e.g. "
        '\'{"bounds": {"velocity": [-10, 10]}}\' (a --config file\'s '
        "[learner_state] table)",
    )
    parser.add_argument(
        "--action-repeat",
        type=_size(constraints.ACTION_REPEAT),
        default=1,
        metavar="N",
        help="with --env: environment steps per learner step, the action held",
    )


def build_parser(reproduce_defaults: Mapping[str, Any] | None = None) -> argparse.ArgumentParser:
    """The parser of every command. ``reproduce_defaults``: defaults of ``reproduce``'s options that
    replace its own (the settings of a ``--config`` file or of a directory being resumed), by dest."""
    from rmac_mj.agents import ALGORITHMS

    parser = _Parser(
        prog=PROG,
        description=DESCRIPTION,
        epilog="Run 'rmac-mj COMMAND --help' for a command's options.",
        formatter_class=_HelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    commands = parser.add_subparsers(
        dest="command", metavar="COMMAND", title="commands", parser_class=_Parser
    )

    def command(name: str, help: str) -> argparse.ArgumentParser:
        return commands.add_parser(
            name, help=help, description=help, formatter_class=_HelpFormatter
        )

    reproduce = command(
        "reproduce",
        "run the paper's comparison (section 6): learning curves, summary, Fig. 2, snapshots",
    )
    _add_task_options(reproduce, True, "default: the paper's swing-up")
    reproduce.add_argument(
        "--experiments",
        type=_size(constraints.EXPERIMENTS),
        default=40,
        metavar="N",
        help="learning experiments per learner (default: 40, the paper's)",
    )
    reproduce.add_argument(
        "--trials",
        type=_size(constraints.TRIALS),
        default=600,
        metavar="N",
        help="consecutive trials per experiment (default: 600, the "
        "paper's, of 3 s); with --steps, at most this many",
    )
    reproduce.add_argument(
        "--steps",
        type=_positive_int,
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
    reproduce.add_argument("--seed", type=_non_negative_int, default=0, help="root random seed")
    reproduce.add_argument(
        "--jobs",
        type=_positive_int,
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
        type=_non_negative_int,
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
        type=_positive_int,
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
        type=_size(constraints.PRIOR_TRIALS),
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
    _add_outside_options(reproduce)
    reproduce.add_argument(
        "--trial-steps",
        type=_size(constraints.TRIAL_STEPS),
        default=None,
        metavar="N",
        help="with --env: learner steps after which a trial is truncated "
        "(default: the environment's own time limit)",
    )
    reproduce.add_argument(
        "--control-timestep",
        type=_positive_seconds,
        default=None,
        metavar="S",
        help="with --env: seconds per environment step, for an environment that "
        "does not say (e.g. MountainCarContinuous-v0)",
    )
    reproduce.add_argument(
        "--evaluate-starts",
        type=_size(constraints.EVALUATE_STARTS),
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
    if reproduce_defaults:
        reproduce.set_defaults(**reproduce_defaults)

    sweep = commands.add_parser("sweep", help="run every configuration of a sweep file")
    sweep.add_argument(
        "file",
        type=pathlib.Path,
        metavar="SWEEP.toml",
        help="[protocol], [grid] and [[variant]] tables (docs/studies/README.md)",
    )
    sweep.add_argument(
        "--out",
        type=pathlib.Path,
        required=True,
        help="directory of the sweep: one result directory per configuration",
    )
    sweep.add_argument(
        "--jobs",
        type=_positive_int,
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

    panel = command(
        "panel",
        "the public panel (docs/panel.md): six tasks nobody tuned for, every "
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
        default="rmac,s-ac,mlac,sb3-sac",
        metavar="ALGO[,ALGO]",
        help="comma-separated learners",
    )
    panel.add_argument(
        "--experiments",
        type=_size(constraints.EXPERIMENTS),
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
    panel.add_argument("--seed", type=_non_negative_int, default=0, help="root random seed")
    panel.add_argument(
        "--jobs",
        type=_positive_int,
        default=None,
        metavar="N",
        help="worker processes shared by all tasks (default: all cores)",
    )
    panel.add_argument("--resume", action="store_true", help="finish an interrupted panel in --out")
    panel.add_argument(
        "--trials",
        type=_size(constraints.TRIALS),
        default=None,
        metavar="N",
        help="every task only N trials, evaluated after each (a smoke test, not the panel)",
    )
    panel.add_argument("--no-progress", action="store_true", help="no progress display")

    compare = command(
        "compare", "overlay the learning curves of result directories and tabulate them"
    )
    compare.add_argument(
        "dirs",
        nargs="+",
        type=pathlib.Path,
        metavar="DIR",
        help="result directories written by rmac-mj reproduce (with summary.json)",
    )
    compare.add_argument(
        "--out",
        type=pathlib.Path,
        default=None,
        help="figure path without suffix (.png and .pdf are written; "
        "default: FIRST_DIR/compare, beside the first run's own figures)",
    )
    compare.add_argument(
        "--smooth",
        type=_positive_int,
        default=1,
        metavar="N",
        help="running mean over N trials (1: none)",
    )
    compare.add_argument(
        "--x-axis",
        choices=("minutes", "env-steps"),
        default="minutes",
        help="Fig. 2's x axis: simulated minutes (the paper's) or environment steps "
        "(equal interaction)",
    )

    policy = command(
        "policy",
        "draw snapshots' policies and critics (Figs. 3, 4); two snapshots side "
        "by side on shared colour scales",
    )
    policy.add_argument(
        "snapshots",
        nargs="+",
        type=pathlib.Path,
        metavar="SNAPSHOT",
        help="agent snapshot(s), e.g. RESULT_DIR/snapshots/rmac/exp_000/trial_0600.npz",
    )
    policy.add_argument(
        "--out",
        type=pathlib.Path,
        default=None,
        help="figure path without suffix (default: beside the first snapshot)",
    )
    policy.add_argument(
        "--dims",
        type=_dims,
        default=(0, 1),
        metavar="I,J",
        help="the state dimensions on the x and y axes (default 0,1); with more "
        "than two, the maps slice through the start state (or --at)",
    )
    policy.add_argument(
        "--xlim",
        type=_floats(2, "LO,HI"),
        default=None,
        metavar="LO,HI",
        help="x axis range (default: the task's state box); write --xlim=-2,2 when LO is negative",
    )
    policy.add_argument(
        "--ylim",
        type=_floats(2, "LO,HI"),
        default=None,
        metavar="LO,HI",
        help="y axis range (default: the task's state box); --ylim=-2,2 when LO is negative",
    )
    policy.add_argument(
        "--at",
        type=_floats(None, "comma-separated numbers"),
        default=None,
        metavar="X1,...,XN",
        help="the state the maps slice through (default: the task's start state)",
    )
    policy.add_argument(
        "--resolution",
        type=_size(constraints.MAP_RESOLUTION),
        default=101,
        metavar="N",
        help="grid points along each axis (default 101)",
    )
    policy.add_argument(
        "--no-trajectory",
        action="store_true",
        help="do not draw the greedy trial from the start state over the maps",
    )
    _add_task_options(policy, False, "default: the snapshot's own")

    optimal = command(
        "optimal",
        "near-optimal return of a task (cached), by the method the task "
        "declares (dynamic programming, trajectory optimisation)",
    )
    _add_task_options(optimal, True, "default: the paper's swing-up")
    optimal.add_argument("--refresh", action="store_true", help="recompute, ignoring the cache")

    render = command("render", "render greedy episodes off-screen to MP4 or GIF")
    render.add_argument(
        "snapshot",
        nargs="?",
        type=pathlib.Path,
        default=None,
        help="agent snapshot to render (or give --progression or --compare)",
    )
    render.add_argument(
        "--progression",
        type=pathlib.Path,
        default=None,
        metavar="RESULT_DIR",
        help="one experiment after trials 1, 10, 50, 200 and the last, in sequence",
    )
    render.add_argument(
        "--compare",
        type=pathlib.Path,
        default=None,
        metavar="RESULT_DIR",
        help="S-AC and RMAC side by side after the same trial",
    )
    render.add_argument(
        "--experiment",
        type=_non_negative_int,
        default=0,
        metavar="I",
        help="which experiment of RESULT_DIR (with --progression or --compare)",
    )
    render.add_argument("--out", type=pathlib.Path, required=True, help=".mp4 or .gif")
    render.add_argument("--width", type=_positive_int, default=320, help="frame width (px)")
    render.add_argument("--height", type=_positive_int, default=240, help="frame height (px)")
    render.add_argument("--no-overlay", action="store_true", help="no text overlay")
    render.add_argument(
        "--frames-per-step",
        type=_positive_int,
        default=1,
        metavar="N",
        help="frames per control step, from physics substeps (a divisor of their "
        "number, e.g. 1 or 3 for the pendulum's 3)",
    )
    _add_task_options(render, False, "default: the one each snapshot learned on")

    bench = command("bench", "microseconds per step, against the raw physics step")
    bench.add_argument(
        "--json", type=pathlib.Path, default=None, help="also write the figures here"
    )
    bench.add_argument(
        "--quick", action="store_true", help="fewer repeats and a shorter experiment"
    )
    _add_task_options(bench, True, "default: the paper's swing-up")
    _add_outside_options(bench)
    bench.add_argument(
        "--markdown",
        action="store_true",
        help="print the table as Markdown (the README's speed table)",
    )
    return parser

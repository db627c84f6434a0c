"""The rmac-mj command: reproduce the paper's comparison, draw its figures, render videos, benchmark.

    rmac-mj reproduce [--domain D --task T] [--experiments 40] [--trials 600]
                      [--algorithms rmac,s-ac] [--seed 0] [--jobs N] [--out DIR] [--resume]
                      [--evaluate-every N] [--scheduler ADDRESS]
                      [--prior demo|FILE.npz] [--prior-trials N] [--prior-parts process,...]
                      [--config FILE.toml]
    rmac-mj sweep SWEEP.toml --out DIR [--jobs N | --scheduler ADDRESS] [--resume]
    rmac-mj compare DIR [DIR ...] [--out STEM]
    rmac-mj policy SNAPSHOT [SNAPSHOT] [--out STEM] [--dims 0,1] [--xlim LO,HI] [--ylim LO,HI]
    rmac-mj optimal [--domain D --task T] [--refresh]
    rmac-mj render SNAPSHOT --out episode.mp4 | rmac-mj render --progression DIR --out progression.mp4
    rmac-mj bench [--domain D --task T] [--json FILE] [--quick] [--markdown]

``rmac-mj`` alone prints the commands; ``rmac-mj COMMAND --help`` their options and defaults.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import pathlib
import signal
import sys
import time
from typing import Any, Sequence

from rmac_mj import __version__
from rmac_mj.errors import UserInputError

#: When this process started (near enough: this module is imported first); wall times count from here.
_STARTED = time.perf_counter()
_PROG = "rmac-mj"


class _Parser(argparse.ArgumentParser):
    """Argument errors as one line and exit status 2, not a usage dump."""

    def error(self, message: str):  # noqa: D102
        self.exit(2, f"{self.prog}: error: {message}\n")


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Options' help with "(default: X)", except where there is nothing to say (None, False, [])
    or the help already says it."""

    def _get_help_string(self, action):
        if (action.default is None or action.default is False or action.default == []
                or "default" in (action.help or "")):
            return action.help
        return super()._get_help_string(action)


class UsageError(UserInputError):
    """A bad argument found after parsing: reported as one line, exit status 2."""


class _Interrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM, with what the user needs to know (what was saved, how to resume)."""


def _say(message: str) -> None:
    """A status line on stderr, for anything slow that shows no progress of its own."""
    print(f"{_PROG}: {message}", file=sys.stderr, flush=True)


@contextlib.contextmanager
def _user_input(what: str = ""):
    """Validation of what the user gave (a configuration, a file): its ValueError becomes a
    :class:`UsageError`, reported as one line. Wrap only validation, never a computation, so that a
    bug elsewhere keeps its traceback."""
    try:
        yield
    except UserInputError:
        raise
    except (ValueError, TypeError) as error:
        raise UsageError(f"{what}{error}") from None


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
_non_negative_int = _int_at_least(0, "an integer >= 0")


def _writable_dir(path: pathlib.Path) -> pathlib.Path:
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / ".write-probe"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as error:
        raise UsageError(f"cannot write to {path}: {error.strerror or error}") from None
    return path


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
        raise argparse.ArgumentTypeError(f"expected two state dimensions I,J, got {text!r}") from None
    return i, j


def _add_task_options(parser: argparse.ArgumentParser, default: bool, what: str) -> None:
    """--domain and --task; with ``default`` the suite's default task, else None (``what``)."""
    from rmac_mj.tasks import DEFAULT_TASK

    parser.add_argument("--domain", default=DEFAULT_TASK[0] if default else None,
                        help=f"domain of the task suite ({what})")
    parser.add_argument("--task", default=DEFAULT_TASK[1] if default else None,
                        help=f"task of the domain ({what})")


def _parser() -> argparse.ArgumentParser:
    from rmac_mj.agents import ALGORITHMS

    parser = _Parser(prog=_PROG, description=__doc__.split("\n\n")[0],
                     epilog="Run 'rmac-mj COMMAND --help' for a command's options.",
                     formatter_class=_HelpFormatter)
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands",
                                     parser_class=_Parser)

    def command(name: str, help: str) -> argparse.ArgumentParser:
        return commands.add_parser(name, help=help, description=help, formatter_class=_HelpFormatter)

    reproduce = command("reproduce", "run the paper's comparison (section 6): learning curves, summary, "
                                     "Fig. 2, snapshots")
    _add_task_options(reproduce, True, "default: the paper's swing-up")
    reproduce.add_argument("--experiments", type=_positive_int, default=40,
                           metavar="N", help="learning experiments per learner (default: 40, the "
                                             "paper's)")
    reproduce.add_argument("--trials", type=_positive_int, default=600,
                           metavar="N", help="consecutive trials per experiment (default: 600, the "
                                             "paper's, of 3 s)")
    reproduce.add_argument("--algorithms", default=None, metavar="ALGO[,ALGO]",
                           help=f"comma-separated learners, from {', '.join(ALGORITHMS)} (default: "
                                "rmac,s-ac, the paper's; with --set, only the learners --set names)")
    reproduce.add_argument("--seed", type=_non_negative_int, default=0, help="root random seed")
    reproduce.add_argument("--jobs", type=_positive_int, default=None, metavar="N",
                           help="worker processes (default: all cores)")
    reproduce.add_argument("--out", type=pathlib.Path, default=pathlib.Path("results/reproduce"),
                           help="result directory")
    reproduce.add_argument("--resume", action="store_true",
                           help="finish an interrupted run in --out (same settings)")
    reproduce.add_argument("--evaluate-every", type=_non_negative_int, default=0, metavar="N",
                           help="a greedy trial after every N learning trials (0: none)")
    reproduce.add_argument("--scheduler", default=None, metavar="ADDRESS",
                           help="Dask scheduler address (tcp://host:8786) to run experiments on")
    reproduce.add_argument("--set", action="append", default=[], metavar="ALGO.FIELD=VALUE",
                           help="override a hyperparameter, e.g. s-ac.rate_split=actor or "
                                "rmac.exploration.sigma=0.5 (JSON values; repeatable). Without "
                                "--algorithms only the learners named here run: an ablation of "
                                "rmac does not rerun s-ac")
    reproduce.add_argument("--smooth", type=_positive_int, default=1, metavar="N",
                           help="Fig. 2: running mean over N trials (1: none)")
    reproduce.add_argument("--prior", default=None, metavar="DEMONSTRATOR|FILE.npz",
                           help="seed every learner before its first trial with prior knowledge: "
                                "trials of a demonstrator the task declares (e.g. 'demo') or "
                                "recorded transitions (docs/prior-knowledge.md gives the format)")
    reproduce.add_argument("--prior-trials", type=_positive_int, default=None,
                           help="demonstrator trials recorded per experiment (default 5)")
    reproduce.add_argument("--prior-parts", default=None, metavar="PART,...",
                           help="seed only these kinds of knowledge: process, reference, critic, "
                                "actor (default: all a learner takes)")
    reproduce.add_argument("--no-optimal", action="store_true",
                           help="skip the near-optimal reference (dynamic programming, about a "
                                "minute the first time, then cached)")
    reproduce.add_argument("--no-progress", action="store_true",
                           help="no progress display (bars on a terminal, periodic lines otherwise)")
    reproduce.add_argument("--config", type=pathlib.Path, default=None, metavar="FILE.toml",
                           help="protocol and hyperparameters from a sweep-style file with single "
                                "values (docs/studies/README.md); options given here override it")
    parser.reproduce_parser = reproduce  # main() re-reads reproduce's defaults from --config

    sweep = commands.add_parser("sweep", help="run every configuration of a sweep file")
    sweep.add_argument("file", type=pathlib.Path, metavar="SWEEP.toml",
                       help="[protocol], [grid] and [[variant]] tables (docs/studies/README.md)")
    sweep.add_argument("--out", type=pathlib.Path, required=True,
                       help="directory of the sweep: one result directory per configuration")
    sweep.add_argument("--jobs", type=_positive_int, default=None,
                       help="worker processes shared by all configurations (default: all cores)")
    sweep.add_argument("--scheduler", default=None,
                       help="Dask scheduler address (tcp://host:8786) to run experiments on")
    sweep.add_argument("--resume", action="store_true", help="finish an interrupted sweep in --out")
    sweep.add_argument("--no-optimal", action="store_true",
                       help="skip the near-optimal reference and exploration floor")
    sweep.add_argument("--no-progress", action="store_true", help="no progress display")

    compare = command("compare", "overlay the learning curves of result directories and tabulate them")
    compare.add_argument("dirs", nargs="+", type=pathlib.Path, metavar="DIR",
                         help="result directories written by rmac-mj reproduce (with summary.json)")
    compare.add_argument("--out", type=pathlib.Path, default=pathlib.Path("compare"),
                         help="figure path without suffix (.png and .pdf are written)")
    compare.add_argument("--smooth", type=_positive_int, default=1, metavar="N",
                         help="running mean over N trials (1: none)")

    policy = command("policy", "draw snapshots' policies and critics (Figs. 3, 4); two snapshots side "
                               "by side on shared colour scales")
    policy.add_argument("snapshots", nargs="+", type=pathlib.Path, metavar="SNAPSHOT",
                        help="agent snapshot(s), e.g. RESULT_DIR/snapshots/rmac/exp_000/trial_0600.npz")
    policy.add_argument("--out", type=pathlib.Path, default=None,
                        help="figure path without suffix (default: beside the first snapshot)")
    policy.add_argument("--dims", type=_dims, default=(0, 1), metavar="I,J",
                        help="the state dimensions on the x and y axes (default 0,1); with more "
                             "than two, the maps slice through the start state (or --at)")
    policy.add_argument("--xlim", type=_floats(2, "LO,HI"), default=None, metavar="LO,HI",
                        help="x axis range (default: the task's state box); write --xlim=-2,2 "
                             "when LO is negative")
    policy.add_argument("--ylim", type=_floats(2, "LO,HI"), default=None, metavar="LO,HI",
                        help="y axis range (default: the task's state box); --ylim=-2,2 when LO is "
                             "negative")
    policy.add_argument("--at", type=_floats(None, "comma-separated numbers"), default=None,
                        metavar="X1,...,XN", help="the state the maps slice through (default: the "
                                                  "task's start state)")
    policy.add_argument("--resolution", type=_positive_int, default=101, metavar="N",
                        help="grid points along each axis (default 101)")
    policy.add_argument("--no-trajectory", action="store_true",
                        help="do not draw the greedy trial from the start state over the maps")
    _add_task_options(policy, False, "default: the snapshot's own")

    optimal = command("optimal", "near-optimal return of a task (cached), by the method the task "
                                 "declares (dynamic programming, trajectory optimisation)")
    _add_task_options(optimal, True, "default: the paper's swing-up")
    optimal.add_argument("--refresh", action="store_true", help="recompute, ignoring the cache")

    render = command("render", "render greedy episodes off-screen to MP4 or GIF")
    render.add_argument("snapshot", nargs="?", type=pathlib.Path, default=None,
                        help="agent snapshot to render (or give --progression or --compare)")
    render.add_argument("--progression", type=pathlib.Path, default=None, metavar="RESULT_DIR",
                        help="one experiment after trials 1, 10, 50, 200 and the last, in sequence")
    render.add_argument("--compare", type=pathlib.Path, default=None, metavar="RESULT_DIR",
                        help="S-AC and RMAC side by side after the same trial")
    render.add_argument("--experiment", type=_non_negative_int, default=0, metavar="I",
                        help="which experiment of RESULT_DIR (with --progression or --compare)")
    render.add_argument("--out", type=pathlib.Path, required=True, help=".mp4 or .gif")
    render.add_argument("--width", type=_positive_int, default=320, help="frame width (px)")
    render.add_argument("--height", type=_positive_int, default=240, help="frame height (px)")
    render.add_argument("--no-overlay", action="store_true", help="no text overlay")
    render.add_argument("--frames-per-step", type=_positive_int, default=1, metavar="N",
                        help="frames per control step, from physics substeps (a divisor of their "
                             "number, e.g. 1 or 3 for the pendulum's 3)")
    _add_task_options(render, False, "default: the one each snapshot learned on")

    bench = command("bench", "microseconds per step, against the raw physics step")
    bench.add_argument("--json", type=pathlib.Path, default=None, help="also write the figures here")
    bench.add_argument("--quick", action="store_true", help="fewer repeats and a shorter experiment")
    _add_task_options(bench, True, "default: the paper's swing-up")
    bench.add_argument("--markdown", action="store_true",
                       help="print the table as Markdown (the README's speed table)")
    return parser


def parse_overrides(assignments: Sequence[str]) -> dict[str, dict]:
    """``["rmac.exploration.sigma=0.5", ...]`` -> ``{"rmac": {"exploration": {"sigma": 0.5}}}``."""
    from rmac_mj.experiments.sweep_file import nest
    flat: dict[str, Any] = {}
    for assignment in assignments:
        key, separator, text = assignment.partition("=")
        path = key.strip().split(".")
        if not separator or len(path) < 2 or not all(path):
            raise UsageError(f"--set expects ALGO.FIELD=VALUE, got {assignment!r}")
        try:
            flat[".".join(path)] = json.loads(text)
        except json.JSONDecodeError:
            flat[".".join(path)] = text  # a bare word, e.g. rate_split=actor
    return nest(flat)


def _algorithms(args, overrides: dict[str, dict]) -> tuple[str, ...]:
    """--algorithms if given (by --config too); else the learners --set names (an ablation reruns only
    them); else the paper's learners (``Protocol``'s default)."""
    from rmac_mj.experiments.protocol import Protocol

    if args.algorithms is not None:
        return tuple(a.strip() for a in args.algorithms.split(",") if a.strip())
    if overrides:
        chosen = tuple(overrides)
        others = [a for a in Protocol().algorithms if a not in chosen]
        if others:
            _say(f"--set names only {', '.join(chosen)}: running {'it' if len(chosen) == 1 else 'them'} "
                 f"alone (give --algorithms to run {', '.join(others)} too)")
        return chosen
    return Protocol().algorithms  # the paper's comparison: RMAC and S-AC


def _with_config(parser: argparse.ArgumentParser, argv: Sequence[str] | None, path: pathlib.Path):
    """Parse ``argv`` again with the --config file's values as reproduce's defaults: the file gives
    the protocol, options on the command line override it, and --set is applied on top of its
    hyperparameters. File options reproduce has no flag for travel in ``args.config_protocol``."""
    from rmac_mj.experiments import sweep_file

    config = sweep_file.load_configuration(path)
    reproduce = parser.reproduce_parser
    flags = {action.dest for action in reproduce._actions}
    defaults, extra = {}, {}
    for key, value in config.options.items():
        if key in flags:
            defaults[key] = ",".join(value) if key == "algorithms" else value
        else:
            extra[key] = value
    reproduce.set_defaults(**defaults, config_protocol=extra, config_agent_configs=config.agent_configs)
    return parser.parse_args(argv)


def _reproduce(args) -> int:
    from rmac_mj.experiments import report, runner, sweep_file
    from rmac_mj.experiments.protocol import Protocol

    if args.prior is None and (args.prior_trials is not None or args.prior_parts is not None):
        raise UsageError("--prior-trials and --prior-parts need --prior")
    if args.prior is not None and args.prior.endswith(".npz") and args.prior_trials is not None:
        raise UsageError("--prior-trials counts demonstrator trials; a recorded file is used whole")
    prior = {}
    if args.prior is not None:
        prior["prior"] = args.prior
        if args.prior_trials is not None:
            prior["prior_trials"] = args.prior_trials
        if args.prior_parts is not None:
            prior["prior_parts"] = tuple(p.strip() for p in args.prior_parts.split(",") if p.strip())
            if not prior["prior_parts"]:
                raise UsageError("--prior-parts must name at least one part")
    overrides = parse_overrides(args.set)
    agent_configs = sweep_file.merge(getattr(args, "config_agent_configs", {}), overrides)
    with _user_input():
        protocol = Protocol(
            domain=args.domain, task=args.task,
            algorithms=_algorithms(args, overrides), experiments=args.experiments,
            trials=args.trials, seed=args.seed, evaluate_every=args.evaluate_every,
            agent_configs=agent_configs, **{**getattr(args, "config_protocol", {}), **prior})
    out = _writable_dir(args.out)
    if args.jobs is not None and args.scheduler:
        raise UsageError("--jobs and --scheduler exclude each other")
    try:
        summary = runner.run_protocol(protocol, out, jobs=args.jobs, resume=args.resume,
                                      scheduler=args.scheduler, progress=not args.no_progress,
                                      references=not args.no_optimal, smooth=args.smooth, log=_say,
                                      started=_STARTED)
    except KeyboardInterrupt:
        saved = runner.finished_experiments(out, protocol)
        if saved:
            raise _Interrupted(f"{saved} finished experiment{' is' if saved == 1 else 's are'} saved "
                               f"in {out}, run again with --resume") from None
        raise _Interrupted(f"no experiment had finished, nothing is saved; run again with --resume "
                           f"to start over in {out}") from None
    print(report.summary_table(summary, protocol.algorithms))
    parts = summary["wall_time_parts_s"]
    total = summary["wall_time_s"]
    detail = (f" over {len(parts)} parts ({' + '.join(f'{p:.1f}' for p in parts)} s)"
              if len(parts) > 1 else "")
    print(f"wall time {total:.1f} s{detail}, all included (start-up, compiling, experiments, "
          f"reference, figures); results in {out}/ (summary.json, returns.csv, fig2_learning_curves.png)")
    return 0


def shortest_distinct_suffixes(paths: Sequence[pathlib.Path]) -> list[str]:
    """Each path's shortest trailing run of components that no other (different) path ends with:
    ``a/run`` and ``b/run`` stay ``a/run`` and ``b/run``; ``x/ten`` and ``y/oldest`` become ``ten``
    and ``oldest``."""
    parts = [pathlib.Path(p).resolve().parts for p in paths]
    labels = []
    for mine in parts:
        others = [theirs for theirs in parts if theirs != mine]
        for k in range(1, len(mine) + 1):
            if all(theirs[-k:] != mine[-k:] for theirs in others):
                break
        labels.append(str(pathlib.PurePath(*mine[-k:])))
    return labels


def _settings_line(summary: dict) -> str:
    """How a run was made: its size, seed and --set overrides."""
    protocol = summary.get("protocol", {})
    from rmac_mj.experiments.sweep_file import flatten
    overrides = [f"{key}={json.dumps(value)}"
                 for key, value in flatten(protocol.get("agent_configs") or {}).items()]
    text = (f"{protocol.get('experiments', '?')} experiments of {protocol.get('trials', '?')} trials, "
            f"seed {protocol.get('seed', '?')}")
    return text + ("; --set " + " ".join(overrides) if overrides else "; default hyperparameters")
def _sweep(args) -> int:
    from rmac_mj.experiments import sweep, sweep_file

    plan = sweep_file.load_sweep(args.file)  # the whole file is validated before anything runs
    if args.jobs is not None and args.scheduler:
        raise UsageError("--jobs and --scheduler exclude each other")
    out = _writable_dir(args.out)
    runs = len(plan.configurations)
    experiments = sum(c.protocol.experiments * len(c.protocol.algorithms) for c in plan.configurations)
    print(f"{args.file}: {runs} configuration{'s' * (runs != 1)}, {experiments} experiments, into {out}/",
          flush=True)
    try:
        rows = sweep.run_sweep(plan, out, jobs=args.jobs, scheduler=args.scheduler, resume=args.resume,
                               progress=not args.no_progress, references=not args.no_optimal,
                               log=_say, started=_STARTED)
    except KeyboardInterrupt:
        raise _Interrupted(f"finished experiments are saved in {out}, run again with --resume") from None
    print(sweep.format_table(plan, rows))
    print(f"results in {out}/ (sweep.csv, sweep_<metric>.png, sweep.json, one directory per "
          "configuration)")
    return 0


def _compare(args) -> int:
    from rmac_mj.agents import ALGORITHMS
    from rmac_mj.experiments import plots, report
    from rmac_mj.experiments.store import ResultStore

    directories = []
    for directory in args.dirs:
        if any(directory.resolve() == seen.resolve() for seen in directories):
            _say(f"{directory} is given twice; it is shown once")
            continue
        directories.append(directory)
    summaries = {}
    for directory, label in zip(directories, shortest_distinct_suffixes(directories)):
        store = ResultStore(directory)
        summaries[label] = store.read_summary()
        if "trial_seconds" not in summaries[label]:
            raise UsageError(f"{store.summary_path} has no trial_seconds (the task's trial length)")
    optimal = next((s["optimal_return"] for s in summaries.values() if s.get("optimal_return")), None)
    floors = {s.get("exploration_floor") for s in summaries.values()}
    paths = plots.plot_learning_curves(summaries, args.out, optimal_return=optimal, smooth=args.smooth,
                                       exploration_floor=floors.pop() if len(floors) == 1 else None)
    for label, summary in summaries.items():
        print(f"== {label}: {_settings_line(summary)}")
        print(report.summary_table(summary))
    if len(summaries) > 1:
        print("== across the runs")
        print("\n".join(report.across_runs(summaries)))
    paths += plots.plot_performance_profiles(
        {(label, a): s[a]["final_return_per_experiment"] for label, s in summaries.items()
         for a in ALGORITHMS if a in s and "final_return_per_experiment" in s[a]},
        args.out.with_name(args.out.name + "_profiles"))
    print("figures:", ", ".join(map(str, paths)))
    return 0


def _policy(args) -> int:
    from rmac_mj.experiments import policy_plots
    from rmac_mj.experiments.episode import learner_state_of, state_of
    from rmac_mj.experiments.snapshots import load_snapshot, snapshot_environment

    snapshots, envs = [], []
    for path in args.snapshots:
        with _user_input(f"{path}: "):
            agent, meta = load_snapshot(path)
        snapshots.append((agent, meta))
        envs.append(snapshot_environment(agent, meta, args.domain, args.task))
    learner_state = learner_state_of(envs[0])
    for path, env in zip(args.snapshots[1:], envs[1:]):
        if learner_state_of(env) != learner_state:
            raise UsageError(f"{path} learned on another state ({learner_state_of(env).labels}) than "
                             f"{args.snapshots[0]} ({learner_state.labels}); draw them one by one")
    meta = snapshots[0][1]
    n = len(learner_state.low)
    if args.at is not None:
        if len(args.at) != n:
            raise UsageError(f"--at needs {n} numbers (the state's dimensions), got {len(args.at)}")
        anchor = args.at
    else:
        anchor = state_of(envs[0].reset().observation, learner_state)
    if n < 2:
        raise UsageError(f"policy maps need at least two state dimensions; {meta['domain']} has {n}")
    i, j = args.dims
    if not (0 <= i < n and 0 <= j < n and i != j):
        raise UsageError(f"--dims must name two different state dimensions in [0, {n}), got {i},{j}")
    limits = {d: lim for d, lim in ((i, args.xlim), (j, args.ylim)) if lim is not None}
    for option, lim in (("--xlim", args.xlim), ("--ylim", args.ylim)):
        if lim is not None and not lim[0] < lim[1]:
            raise UsageError(f"{option} needs LO < HI, got {lim[0]:g},{lim[1]:g}")
    first = args.snapshots[0]
    stem = args.out or first.with_name(first.stem + ("_policy" if len(snapshots) == 1 else "_policies"))
    paths = policy_plots.plot_policies(snapshots, stem, learner_state, anchor, dims=(i, j), limits=limits,
                                resolution=args.resolution, envs=None if args.no_trajectory else envs)
    print("figure:", ", ".join(map(str, paths)))
    return 0


def _optimal(args) -> int:
    from rmac_mj.agents import Exploration
    from rmac_mj.experiments import reference

    with _user_input():
        if not reference.has_reference(args.domain, args.task):
            reference.reference(args.domain, args.task)  # raises, naming the tasks that have one
    result = reference.reference(args.domain, args.task, refresh=args.refresh, announce=_say)
    print(result.describe())
    paper = Exploration()  # the learners' default exploration (section 6.1)
    floor = reference.exploration_floor(args.domain, args.task, paper.sigma, paper.period,
                                        paper.phase, refresh=args.refresh, announce=_say)
    if floor is not None:  # a reference with a policy to explore with (the dynamic programme)
        print(floor.describe())
    return 0


def _render(args) -> int:
    chosen = [x for x in (args.snapshot, args.progression, args.compare) if x is not None]
    if len(chosen) != 1:
        raise UsageError("give exactly one of SNAPSHOT, --progression DIR or --compare DIR")
    from rmac_mj.experiments import result_videos

    options = {"width": args.width, "height": args.height, "overlay": not args.no_overlay,
               "frames_per_step": args.frames_per_step}
    if args.snapshot is not None:
        path = result_videos.render_snapshot(args.snapshot, args.out, domain=args.domain, task=args.task,
                                      **options)
    elif args.domain is not None or args.task is not None:
        raise UsageError("--domain/--task apply to a single SNAPSHOT only")
    elif args.progression is not None:
        path = result_videos.render_progression(args.progression, args.out, experiment=args.experiment,
                                         **options)
    else:
        path = result_videos.render_comparison(args.compare, args.out, experiment=args.experiment,
                                        **options)
    print("video:", path)
    return 0


def _bench(args) -> int:
    from rmac_mj.experiments import bench

    with _user_input():
        bench.check_task(args.domain, args.task)
    report = bench.run(quick=args.quick, domain=args.domain, task=args.task)
    print(bench.format_markdown(report) if args.markdown else bench.format_table(report))
    if args.json:
        from rmac_mj.experiments.files import write_json
        write_json(args.json, report)
        print("json:", args.json)
    return 0


_COMMANDS = {"reproduce": _reproduce, "sweep": _sweep, "compare": _compare, "policy": _policy,
             "optimal": _optimal, "render": _render, "bench": _bench}


def _announcing_compilation(command: str):
    """Say so when a command starts compiling kernels (the first time only: tens of seconds).
    ``reproduce`` and ``sweep`` say it themselves, as they compile them before starting their workers."""
    if command in ("reproduce", "sweep", "compare", "optimal"):  # these compile nothing, or say it themselves
        return contextlib.nullcontext()
    from rmac_mj import _cache

    return _cache.on_first_compile(lambda: _say(f"compiling kernels, first run only (cached in "
                                                 f"{_cache.numba_cache_location()})"))


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main(argv: Sequence[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    prog = _PROG
    if args.command is None:  # `rmac-mj` alone: what it can do
        parser.print_help()
        return 2
    signal.signal(signal.SIGTERM, _interrupt)  # a polite kill cleans up like Ctrl-C
    try:
        if getattr(args, "config", None) is not None:
            args = _with_config(parser, argv, args.config)
        with _announcing_compilation(args.command):
            return _COMMANDS[args.command](args)
    except KeyboardInterrupt as interrupt:
        detail = f"; {interrupt}" if str(interrupt) else ""
        print(f"\n{prog}: interrupted{detail}", file=sys.stderr)
        return 130
    except UserInputError as error:  # UsageError, runner.ResumeRefused, missing inputs
        print(f"{prog}: error: {error}", file=sys.stderr)
        return 2
    except RuntimeError as error:
        from rmac_mj._gl import GLBackendError
        if isinstance(error, GLBackendError):  # no off-screen GL: the message names the packages
            print(f"{prog}: error: {error}", file=sys.stderr)
            return 2
        raise


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

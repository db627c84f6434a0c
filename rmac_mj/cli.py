"""The ``rmac-mj`` command: reproduce the paper's comparison, draw its figures, render, benchmark.

    rmac-mj reproduce [--experiments 40] [--trials 600] [--algorithms rmac,s-ac] [--seed 0]
                      [--jobs N] [--out DIR] [--resume] [--evaluate-every N] [--scheduler ADDRESS]
                      [--config FILE.toml]
    rmac-mj sweep SWEEP.toml --out DIR [--jobs N | --scheduler ADDRESS] [--resume]
    rmac-mj compare DIR [DIR ...] [--out STEM]
    rmac-mj policy SNAPSHOT [--out STEM]
    rmac-mj optimal [--refresh]
    rmac-mj render SNAPSHOT --out swingup.mp4 | rmac-mj render --progression DIR --out progression.mp4
    rmac-mj bench [--json FILE]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import pathlib
import signal
import sys
from typing import Sequence

from rmac_mj.errors import UserInputError


class _Parser(argparse.ArgumentParser):
    """Argument errors as one line and exit status 2, not a usage dump."""

    def error(self, message: str):  # noqa: D102
        self.exit(2, f"{self.prog}: error: {message}\n")


class UsageError(UserInputError):
    """A bad argument found after parsing: reported as one line, exit status 2."""


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


def _parser() -> argparse.ArgumentParser:
    from rmac_mj.agents import ALGORITHMS

    parser = _Parser(prog="rmac-mj", description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    reproduce = commands.add_parser("reproduce", help="run the paper's comparison (section 6)")
    reproduce.add_argument("--experiments", type=_positive_int, default=40,
                           help="learning experiments per learner (paper: 40)")
    reproduce.add_argument("--trials", type=_positive_int, default=600,
                           help="consecutive 3 s trials per experiment (paper: 600)")
    reproduce.add_argument("--algorithms", default=",".join(ALGORITHMS),
                           help=f"comma-separated learners, from {', '.join(ALGORITHMS)}")
    reproduce.add_argument("--seed", type=_non_negative_int, default=0, help="root random seed")
    reproduce.add_argument("--jobs", type=_positive_int, default=None,
                           help="worker processes (default: all cores)")
    reproduce.add_argument("--out", type=pathlib.Path, default=pathlib.Path("results/reproduce"),
                           help="result directory")
    reproduce.add_argument("--resume", action="store_true",
                           help="finish an interrupted run in --out")
    reproduce.add_argument("--evaluate-every", type=_non_negative_int, default=0,
                           help="a greedy trial after every N learning trials (0: none)")
    reproduce.add_argument("--scheduler", default=None,
                           help="Dask scheduler address (tcp://host:8786) to run experiments on")
    reproduce.add_argument("--set", action="append", default=[], metavar="ALGO.FIELD=VALUE",
                           help="override a hyperparameter, e.g. s-ac.rate_split=actor or "
                                "rmac.exploration.sigma=0.5 (JSON values; repeatable)")
    reproduce.add_argument("--no-optimal", action="store_true",
                           help="skip the near-optimal reference (dynamic programming)")
    reproduce.add_argument("--no-progress", action="store_true", help="no progress bars")
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
    sweep.add_argument("--no-progress", action="store_true", help="no progress bar")

    compare = commands.add_parser("compare", help="overlay the learning curves of result dirs")
    compare.add_argument("dirs", nargs="+", type=pathlib.Path)
    compare.add_argument("--out", type=pathlib.Path, default=pathlib.Path("compare"),
                         help="figure path without suffix (.png and .pdf are written)")

    policy = commands.add_parser("policy", help="draw a snapshot's policy and critic (Figs. 3, 4)")
    policy.add_argument("snapshot", type=pathlib.Path)
    policy.add_argument("--out", type=pathlib.Path, default=None,
                        help="figure path without suffix (default: beside the snapshot)")
    policy.add_argument("--max-speed", type=float, default=30.0, help="velocity axis range (rad/s)")

    optimal = commands.add_parser("optimal", help="near-optimal return by dynamic programming")
    optimal.add_argument("--refresh", action="store_true", help="recompute, ignoring the cache")

    render = commands.add_parser("render", help="render greedy swingups off-screen to MP4 or GIF")
    render.add_argument("snapshot", nargs="?", type=pathlib.Path, default=None)
    render.add_argument("--progression", type=pathlib.Path, default=None, metavar="RESULT_DIR",
                        help="one experiment after trials 1, 10, 50, 200 and the last, in sequence")
    render.add_argument("--compare", type=pathlib.Path, default=None, metavar="RESULT_DIR",
                        help="S-AC and RMAC side by side after the same trial")
    render.add_argument("--experiment", type=_non_negative_int, default=0)
    render.add_argument("--out", type=pathlib.Path, required=True, help=".mp4 or .gif")
    render.add_argument("--width", type=_positive_int, default=320)
    render.add_argument("--height", type=_positive_int, default=240)
    render.add_argument("--no-overlay", action="store_true", help="no text overlay")
    render.add_argument("--frames-per-step", type=_positive_int, default=1,
                        help="frames per 0.03 s control step, from physics substeps (1 or 3)")

    bench = commands.add_parser("bench", help="microseconds per step, against env.step")
    bench.add_argument("--json", type=pathlib.Path, default=None, help="also write the figures here")
    bench.add_argument("--quick", action="store_true", help="fewer repeats and a shorter experiment")
    return parser


def _optimal_for(protocol) -> float | None:
    """The near-optimal return of the protocol's task, when it is the paper's swing-up."""
    if (protocol.domain, protocol.task, protocol.task_kwargs) != ("dc_pendulum", "swingup", {}):
        return None
    from rmac_mj.experiments import optimal
    return float(optimal.optimal_return().simulated_return)


def _exploration_floor_for(protocol, algorithm: str) -> float | None:
    """The exploration floor of ``algorithm``'s exploration on the paper's swing-up, else None."""
    if (protocol.domain, protocol.task, protocol.task_kwargs) != ("dc_pendulum", "swingup", {}):
        return None
    from rmac_mj.agents import config_class, config_from_dict
    from rmac_mj.experiments import optimal
    config = config_from_dict(config_class(algorithm), protocol.agent_configs.get(algorithm, {}))
    exploration = getattr(config, "exploration", None)
    if exploration is None:
        return None
    return float(optimal.exploration_floor(exploration.sigma, exploration.period,
                                           exploration.phase).mean)


def parse_overrides(assignments: Sequence[str]) -> dict[str, dict]:
    """``["rmac.exploration.sigma=0.5", ...]`` -> ``{"rmac": {"exploration": {"sigma": 0.5}}}``."""
    overrides: dict[str, dict] = {}
    for assignment in assignments:
        key, separator, text = assignment.partition("=")
        path = key.strip().split(".")
        if not separator or len(path) < 2 or not all(path):
            raise UsageError(f"--set expects ALGO.FIELD=VALUE, got {assignment!r}")
        try:
            value = json.loads(text)
        except json.JSONDecodeError:
            value = text  # a bare word, e.g. rate_split=actor
        node = overrides.setdefault(path[0], {})
        for part in path[1:-1]:
            node = node.setdefault(part, {})
        node[path[-1]] = value
    return overrides


def _with_config(parser: argparse.ArgumentParser, argv: Sequence[str] | None, path: pathlib.Path):
    """Parse ``argv`` again with the --config file's values as reproduce's defaults: the file gives
    the protocol, options on the command line override it, and --set is applied on top of its
    hyperparameters. File options reproduce has no flag for travel in ``args.config_protocol``."""
    from rmac_mj.experiments import sweep

    config = sweep.load_configuration(path)
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
    from rmac_mj.experiments import runner, sweep

    agent_configs = sweep.merge(getattr(args, "config_agent_configs", {}), parse_overrides(args.set))
    with _user_input():
        protocol = runner.Protocol(
            algorithms=tuple(a.strip() for a in args.algorithms.split(",") if a),
            experiments=args.experiments, trials=args.trials, seed=args.seed,
            evaluate_every=args.evaluate_every, agent_configs=agent_configs,
            **getattr(args, "config_protocol", {}))
    out = _writable_dir(args.out)
    if args.jobs is not None and args.scheduler:
        raise UsageError("--jobs and --scheduler exclude each other")
    summary = runner.run_protocol(protocol, out, jobs=args.jobs, resume=args.resume,
                                  scheduler=args.scheduler, progress=not args.no_progress,
                                  optimal=None if args.no_optimal else _optimal_for,
                                  floor=None if args.no_optimal else _exploration_floor_for)
    print(runner.summary_table(summary, protocol.algorithms))
    print(f"wall time {summary['wall_time_s']:.1f} s; results in {out}/ "
          f"(summary.json, returns.csv, fig2_learning_curves.png)")
    return 0


def _sweep(args) -> int:
    from rmac_mj.experiments import sweep

    plan = sweep.load_sweep(args.file)  # the whole file is validated before anything runs
    if args.jobs is not None and args.scheduler:
        raise UsageError("--jobs and --scheduler exclude each other")
    out = _writable_dir(args.out)
    runs = len(plan.configurations)
    experiments = sum(c.protocol.experiments * len(c.protocol.algorithms) for c in plan.configurations)
    print(f"{args.file}: {runs} configuration{'s' * (runs != 1)}, {experiments} experiments, into {out}/",
          flush=True)
    rows = sweep.run_sweep(plan, out, jobs=args.jobs, scheduler=args.scheduler, resume=args.resume,
                           progress=not args.no_progress,
                           optimal=None if args.no_optimal else _optimal_for,
                           floor=None if args.no_optimal else _exploration_floor_for)
    print(sweep.format_table(plan, rows))
    print(f"results in {out}/ (sweep.csv, sweep_<metric>.png, sweep.json, one directory per "
          "configuration)")
    return 0


def _compare(args) -> int:
    from rmac_mj.experiments import plots, runner

    summaries = {}
    for directory in args.dirs:
        path = directory / "summary.json"
        if not path.is_file():
            raise UsageError(f"{directory} has no summary.json (not a finished `reproduce` run)")
        with _user_input(f"{path}: "):
            summaries[directory.name or str(directory)] = json.loads(path.read_text())
    optimal = next((s["optimal_return"] for s in summaries.values() if s.get("optimal_return")), None)
    floors = {s.get("exploration_floor") for s in summaries.values()}
    paths = plots.plot_learning_curves(summaries, args.out, optimal_return=optimal,
                                       exploration_floor=floors.pop() if len(floors) == 1 else None)
    for label, summary in summaries.items():
        print(f"== {label}")
        print(runner.summary_table(summary))
    print("figure:", ", ".join(map(str, paths)))
    return 0


def _policy(args) -> int:
    from rmac_mj.experiments import plots
    from rmac_mj.experiments.snapshots import load_snapshot

    with _user_input(f"{args.snapshot}: "):
        agent, meta = load_snapshot(args.snapshot)
    stem = args.out or args.snapshot.with_name(args.snapshot.stem + "_policy")
    paths = plots.plot_policy(agent, meta, stem, max_speed=args.max_speed)
    print("figure:", ", ".join(map(str, paths)))
    return 0


def _optimal(args) -> int:
    from rmac_mj.experiments import optimal

    result = optimal.optimal_return(refresh=args.refresh)
    print(result.describe())
    print(optimal.exploration_floor(refresh=args.refresh).describe())
    return 0


def _render(args) -> int:
    chosen = [x for x in (args.snapshot, args.progression, args.compare) if x is not None]
    if len(chosen) != 1:
        raise UsageError("give exactly one of SNAPSHOT, --progression DIR or --compare DIR")
    from rmac_mj.experiments import render

    options = {"width": args.width, "height": args.height, "overlay": not args.no_overlay,
               "frames_per_step": args.frames_per_step}
    if args.snapshot is not None:
        path = render.render_snapshot(args.snapshot, args.out, **options)
    elif args.progression is not None:
        path = render.render_progression(args.progression, args.out, experiment=args.experiment,
                                         **options)
    else:
        path = render.render_comparison(args.compare, args.out, experiment=args.experiment,
                                        **options)
    print("video:", path)
    return 0


def _bench(args) -> int:
    from rmac_mj.experiments import bench

    report = bench.run(quick=args.quick)
    print(bench.format_table(report))
    if args.json:
        from rmac_mj.experiments.results import write_json
        write_json(args.json, report)
        print("json:", args.json)
    return 0


_COMMANDS = {"reproduce": _reproduce, "sweep": _sweep, "compare": _compare, "policy": _policy, "optimal": _optimal,
             "render": _render, "bench": _bench}


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main(argv: Sequence[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    prog = "rmac-mj"
    signal.signal(signal.SIGTERM, _interrupt)  # a polite kill cleans up like Ctrl-C
    try:
        if getattr(args, "config", None) is not None:
            args = _with_config(parser, argv, args.config)
        return _COMMANDS[args.command](args)
    except KeyboardInterrupt:
        print(f"\n{prog}: interrupted; finished experiments are saved, run again with --resume",
              file=sys.stderr)
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

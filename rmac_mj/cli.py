"""The ``rmac-mj`` command: reproduce the paper's comparison, draw its figures, render, benchmark.

    rmac-mj reproduce [--domain dc_pendulum --task swingup] [--experiments 40] [--trials 600]
                      [--algorithms rmac,s-ac] [--seed 0] [--jobs N] [--out DIR] [--resume]
                      [--evaluate-every N] [--scheduler ADDRESS]
                      [--prior demo|FILE.npz] [--prior-trials N] [--prior-parts process,...]
    rmac-mj compare DIR [DIR ...] [--out STEM]
    rmac-mj policy SNAPSHOT [--out STEM] [--dims 0,1] [--xlim LO,HI] [--ylim LO,HI]
    rmac-mj optimal [--refresh]
    rmac-mj render SNAPSHOT --out episode.mp4 | rmac-mj render --progression DIR --out progression.mp4
    rmac-mj bench [--domain dc_pendulum --task swingup] [--json FILE] [--quick] [--markdown]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
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
    """--domain and --task; with ``default`` the paper's dc_pendulum/swingup, else None (``what``)."""
    parser.add_argument("--domain", default="dc_pendulum" if default else None,
                        help=f"domain of the task suite ({what})")
    parser.add_argument("--task", default="swingup" if default else None,
                        help=f"task of the domain ({what})")


def _parser() -> argparse.ArgumentParser:
    from rmac_mj.agents import ALGORITHMS

    parser = _Parser(prog="rmac-mj", description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    reproduce = commands.add_parser("reproduce", help="run the paper's comparison (section 6)")
    _add_task_options(reproduce, True, "default: the paper's dc_pendulum/swingup")
    reproduce.add_argument("--experiments", type=_positive_int, default=40,
                           help="learning experiments per learner (paper: 40)")
    reproduce.add_argument("--trials", type=_positive_int, default=600,
                           help="consecutive trials per experiment (paper: 600 of 3 s)")
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
    reproduce.add_argument("--prior", default=None, metavar="DEMONSTRATOR|FILE.npz",
                           help="seed every learner before its first trial with prior knowledge: "
                                "trials of a demonstrator of the task ('demo', 'poor-demo') or "
                                "recorded transitions (docs/prior-knowledge.md gives the format)")
    reproduce.add_argument("--prior-trials", type=_positive_int, default=None,
                           help="demonstrator trials recorded per experiment (default 5)")
    reproduce.add_argument("--prior-parts", default=None, metavar="PART,...",
                           help="seed only these kinds of knowledge: process, reference, critic, "
                                "actor (default: all a learner takes)")
    reproduce.add_argument("--no-optimal", action="store_true",
                           help="skip the near-optimal reference (dynamic programming)")
    reproduce.add_argument("--no-progress", action="store_true", help="no progress bars")

    compare = commands.add_parser("compare", help="overlay the learning curves of result dirs")
    compare.add_argument("dirs", nargs="+", type=pathlib.Path)
    compare.add_argument("--out", type=pathlib.Path, default=pathlib.Path("compare"),
                         help="figure path without suffix (.png and .pdf are written)")

    policy = commands.add_parser("policy", help="draw a snapshot's policy and critic (Figs. 3, 4)")
    policy.add_argument("snapshot", type=pathlib.Path)
    policy.add_argument("--out", type=pathlib.Path, default=None,
                        help="figure path without suffix (default: beside the snapshot)")
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
    policy.add_argument("--resolution", type=_positive_int, default=101,
                        help="grid points along each axis (default 101)")
    _add_task_options(policy, False, "default: the snapshot's own")

    optimal = commands.add_parser("optimal", help="near-optimal return by dynamic programming")
    optimal.add_argument("--refresh", action="store_true", help="recompute, ignoring the cache")

    render = commands.add_parser("render", help="render greedy episodes off-screen to MP4 or GIF")
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
                        help="frames per control step, from physics substeps (a divisor of their "
                             "number, e.g. 1 or 3 for dc_pendulum)")
    _add_task_options(render, False, "default: the one each snapshot learned on")

    bench = commands.add_parser("bench", help="microseconds per step, against the raw physics step")
    bench.add_argument("--json", type=pathlib.Path, default=None, help="also write the figures here")
    bench.add_argument("--quick", action="store_true", help="fewer repeats and a shorter experiment")
    _add_task_options(bench, True, "default: dc_pendulum/swingup")
    bench.add_argument("--markdown", action="store_true",
                       help="print the table as Markdown (the README's speed table)")
    return parser


def _optimal_for(protocol) -> float | None:
    """The near-optimal return of the protocol's task, when it is the paper's swing-up."""
    if (protocol.domain, protocol.task, protocol.task_kwargs) != ("dc_pendulum", "swingup", {}):
        return None
    from rmac_mj.experiments import optimal
    return float(optimal.optimal_return().simulated_return)


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


def _reproduce(args) -> int:
    from rmac_mj.experiments import runner

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
    with _user_input():
        protocol = runner.Protocol(
            domain=args.domain, task=args.task,
            algorithms=tuple(a.strip() for a in args.algorithms.split(",") if a),
            experiments=args.experiments, trials=args.trials, seed=args.seed,
            evaluate_every=args.evaluate_every, agent_configs=parse_overrides(args.set), **prior)
    out = _writable_dir(args.out)
    if args.jobs is not None and args.scheduler:
        raise UsageError("--jobs and --scheduler exclude each other")
    summary = runner.run_protocol(protocol, out, jobs=args.jobs, resume=args.resume,
                                  scheduler=args.scheduler, progress=not args.no_progress,
                                  optimal=None if args.no_optimal else _optimal_for)
    print(runner.summary_table(summary, protocol.algorithms))
    print(f"wall time {summary['wall_time_s']:.1f} s; results in {out}/ "
          f"(summary.json, returns.csv, fig2_learning_curves.png)")
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
        if "trial_seconds" not in summaries[directory.name or str(directory)]:
            raise UsageError(f"{path} has no trial_seconds (the task's trial length)")
    optimal = next((s["optimal_return"] for s in summaries.values() if s.get("optimal_return")), None)
    paths = plots.plot_learning_curves(summaries, args.out, optimal_return=optimal)
    for label, summary in summaries.items():
        print(f"== {label}")
        print(runner.summary_table(summary))
    print("figure:", ", ".join(map(str, paths)))
    return 0


def _policy(args) -> int:
    from rmac_mj.experiments import plots
    from rmac_mj.experiments.episode import learner_state_of, state_of
    from rmac_mj.experiments.render import snapshot_environment
    from rmac_mj.experiments.snapshots import load_snapshot

    with _user_input(f"{args.snapshot}: "):
        agent, meta = load_snapshot(args.snapshot)
    env = snapshot_environment(agent, meta, args.domain, args.task)
    learner_state = learner_state_of(env)
    n = len(learner_state.low)
    if args.at is not None:
        if len(args.at) != n:
            raise UsageError(f"--at needs {n} numbers (the state's dimensions), got {len(args.at)}")
        anchor = args.at
    else:
        anchor = state_of(env.reset().observation, learner_state)
    if n < 2:
        raise UsageError(f"policy maps need at least two state dimensions; {meta['domain']} has {n}")
    i, j = args.dims
    if not (0 <= i < n and 0 <= j < n and i != j):
        raise UsageError(f"--dims must name two different state dimensions in [0, {n}), got {i},{j}")
    limits = {d: lim for d, lim in ((i, args.xlim), (j, args.ylim)) if lim is not None}
    for option, lim in (("--xlim", args.xlim), ("--ylim", args.ylim)):
        if lim is not None and not lim[0] < lim[1]:
            raise UsageError(f"{option} needs LO < HI, got {lim[0]:g},{lim[1]:g}")
    stem = args.out or args.snapshot.with_name(args.snapshot.stem + "_policy")
    paths = plots.plot_policy(agent, meta, stem, learner_state, anchor, dims=(i, j), limits=limits,
                              resolution=args.resolution)
    print("figure:", ", ".join(map(str, paths)))
    return 0


def _optimal(args) -> int:
    from rmac_mj.experiments import optimal

    result = optimal.optimal_return(refresh=args.refresh)
    print(result.describe())
    return 0


def _render(args) -> int:
    chosen = [x for x in (args.snapshot, args.progression, args.compare) if x is not None]
    if len(chosen) != 1:
        raise UsageError("give exactly one of SNAPSHOT, --progression DIR or --compare DIR")
    from rmac_mj.experiments import render

    options = {"width": args.width, "height": args.height, "overlay": not args.no_overlay,
               "frames_per_step": args.frames_per_step}
    if args.snapshot is not None:
        path = render.render_snapshot(args.snapshot, args.out, domain=args.domain, task=args.task,
                                      **options)
    elif args.domain is not None or args.task is not None:
        raise UsageError("--domain/--task apply to a single SNAPSHOT only")
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

    with _user_input():
        bench.check_task(args.domain, args.task)
    report = bench.run(quick=args.quick, domain=args.domain, task=args.task)
    print(bench.format_markdown(report) if args.markdown else bench.format_table(report))
    if args.json:
        from rmac_mj.experiments.results import write_json
        write_json(args.json, report)
        print("json:", args.json)
    return 0


_COMMANDS = {"reproduce": _reproduce, "compare": _compare, "policy": _policy, "optimal": _optimal,
             "render": _render, "bench": _bench}


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    prog = "rmac-mj"
    signal.signal(signal.SIGTERM, _interrupt)  # a polite kill cleans up like Ctrl-C
    try:
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

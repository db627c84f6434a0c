"""The options of the commands that look at results, a task's optimum or the code's speed:
``compare``, ``policy``, ``optimal``, ``render``, ``bench``."""

from __future__ import annotations

import argparse
import pathlib

from rmac_mj import constraints
from rmac_mj.cli.arguments import (
    add_command,
    add_outside_options,
    add_task_options,
    add_trust_env,
    floats,
    non_negative_int,
    positive_int,
    size_within,
    state_dims,
)


def add_compare(commands) -> None:
    """``compare``: result directories' curves overlaid and tabulated."""
    compare = add_command(
        commands, "compare", "overlay the learning curves of result directories and tabulate them"
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
        default=None,
        metavar="PATH",
        help="where the two figures go: a folder (existing, or ending in /) gets compare.png "
        "and compare_profiles.png; a path ending in .png or .pdf, or without suffix, names "
        "the learning curves, the performance profiles beside them as NAME_profiles (each "
        "as .png and .pdf; default: FIRST_DIR/compare, beside the first run's own figures)",
    )
    compare.add_argument(
        "--smooth",
        type=positive_int,
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


def add_policy(commands) -> None:
    """``policy``: snapshots' policy and critic maps."""
    policy = add_command(
        commands,
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
    _add_map_options(policy)
    policy.add_argument(
        "--no-trajectory",
        action="store_true",
        help="do not draw the greedy trial from the start state over the maps",
    )
    add_task_options(policy, False, "default: the snapshot's own")
    add_trust_env(policy, "each snapshot")


def _add_map_options(policy: argparse.ArgumentParser) -> None:
    """``policy``'s options of what the maps show: which dimensions, their ranges, the slice, the grid."""
    policy.add_argument(
        "--dims",
        type=state_dims,
        default=(0, 1),
        metavar="I,J",
        help="the state dimensions on the x and y axes (default 0,1); with more "
        "than two, the maps slice through the start state (or --at)",
    )
    policy.add_argument(
        "--xlim",
        type=floats(2, "LO,HI"),
        default=None,
        metavar="LO,HI",
        help="x axis range (default: the task's state box); write --xlim=-2,2 when LO is negative",
    )
    policy.add_argument(
        "--ylim",
        type=floats(2, "LO,HI"),
        default=None,
        metavar="LO,HI",
        help="y axis range (default: the task's state box); --ylim=-2,2 when LO is negative",
    )
    policy.add_argument(
        "--at",
        type=floats(None, "comma-separated numbers"),
        default=None,
        metavar="X1,...,XN",
        help="the state the maps slice through (default: the task's start state)",
    )
    policy.add_argument(
        "--resolution",
        type=size_within(constraints.MAP_RESOLUTION),
        default=101,
        metavar="N",
        help="grid points along each axis (default 101)",
    )


def add_optimal(commands) -> None:
    """``optimal``: a task's near-optimal return."""
    optimal = add_command(
        commands,
        "optimal",
        "near-optimal return of a task (cached), by the method the task "
        "declares (dynamic programming, trajectory optimisation)",
    )
    add_task_options(optimal, True, "default: the paper's swing-up")
    optimal.add_argument("--refresh", action="store_true", help="recompute, ignoring the cache")


def add_render(commands) -> None:
    """``render``: greedy episodes as video."""
    render = add_command(commands, "render", "render greedy episodes off-screen to MP4 or GIF")
    render.add_argument(
        "snapshot",
        nargs="?",
        type=pathlib.Path,
        default=None,
        help="agent snapshot to render (or give --progression or --compare)",
    )
    for option, what in (
        ("--progression", "one experiment after trials 1, 10, 50, 200 and the last, in sequence"),
        ("--compare", "S-AC and RMAC side by side after the same trial"),
    ):
        render.add_argument(
            option, type=pathlib.Path, default=None, metavar="RESULT_DIR", help=what
        )
    render.add_argument(
        "--experiment",
        type=non_negative_int,
        default=0,
        metavar="I",
        help="which experiment of RESULT_DIR (with --progression or --compare)",
    )
    render.add_argument("--out", type=pathlib.Path, required=True, help=".mp4 or .gif")
    render.add_argument("--width", type=positive_int, default=320, help="frame width (px)")
    render.add_argument("--height", type=positive_int, default=240, help="frame height (px)")
    render.add_argument("--no-overlay", action="store_true", help="no text overlay")
    render.add_argument(
        "--frames-per-step",
        type=positive_int,
        default=1,
        metavar="N",
        help="frames per control step, from physics substeps (a divisor of their "
        "number, e.g. 1 or 3 for the pendulum's 3)",
    )
    add_task_options(render, False, "default: the one each snapshot learned on")
    add_trust_env(render, "each snapshot")


def add_bench(commands) -> None:
    """``bench``: microseconds per step."""
    bench = add_command(commands, "bench", "microseconds per step, against the raw physics step")
    bench.add_argument(
        "--json", type=pathlib.Path, default=None, help="also write the figures here"
    )
    bench.add_argument(
        "--quick", action="store_true", help="fewer repeats and a shorter experiment"
    )
    add_task_options(bench, True, "default: the paper's swing-up")
    add_outside_options(bench)
    bench.add_argument(
        "--markdown",
        action="store_true",
        help="print the table as Markdown (the README's speed table)",
    )
    bench.add_argument(
        "--cold",
        action="store_true",
        help="instead: each learner's compile from an empty cache, in a fresh process (CPU and "
        "wall seconds), then the quick run (reproduce --experiments 4) from empty caches; with "
        "--quick, the compiles only",
    )

"""The ``rmac-mj`` command: reproduce, sweep, panel, compare, policy, optimal, render, bench.

``rmac-mj`` alone prints the commands, ``rmac-mj COMMAND --help`` their options and defaults; the
options are declared in :mod:`rmac_mj.cli.options`, the commands that run experiments in
:mod:`rmac_mj.cli.runs`, those that look at results in :mod:`rmac_mj.cli.views`.
"""

from __future__ import annotations

import contextlib
import errno
import signal
import sys
from collections.abc import Sequence

from rmac_mj.cli import runs, views
from rmac_mj.cli.common import PROG, say  # first: its import time is the start of the wall time
from rmac_mj.cli.options import build_parser
from rmac_mj.errors import UserInputError

_COMMANDS = {
    "reproduce": runs.reproduce,
    "sweep": runs.sweep,
    "panel": runs.panel,
    "compare": views.compare,
    "policy": views.policy,
    "optimal": views.optimal,
    "render": views.render,
    "bench": views.bench,
}


def _announcing_compilation(command: str):
    """Say so when a command starts compiling kernels (the first time only).
    ``reproduce`` and ``sweep`` say it themselves, as they compile them before starting their workers."""
    if command in (
        "reproduce",
        "sweep",
        "panel",
        "compare",
        "optimal",
    ):  # these compile nothing, or say it themselves
        return contextlib.nullcontext()
    from rmac_mj import _cache

    return _cache.on_first_compile(
        lambda: say(
            f"compiling kernels, first run only (cached in {_cache.numba_cache_location()})"
        )
    )


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    prog = PROG
    if args.command is None:  # `rmac-mj` alone: what it can do
        parser.print_help()
        return 0
    signal.signal(signal.SIGTERM, _interrupt)  # a polite kill cleans up like Ctrl-C
    try:
        if args.command == "reproduce":
            args = runs.settings_from_files(argv, args)
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
    except OSError as error:
        if error.errno not in _STORAGE_ERRORS:
            raise
        # The machine's storage, not a bug: what was saved is whole (every file is written
        # atomically), and --resume finishes the run once there is room.
        where = f" ({error.filename})" if error.filename else ""
        print(
            f"{prog}: error: cannot write{where}: {error.strerror}; what was saved is whole: free "
            "some space and run again with --resume",
            file=sys.stderr,
        )
        return 1


#: Storage errors reported in one line (disk full, quota exceeded, read-only file system).
_STORAGE_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS)

"""The ``rmac-mj`` command: reproduce, sweep, panel, compare, policy, optimal, render, bench.

``rmac-mj`` alone prints the commands, ``rmac-mj COMMAND --help`` their options and defaults. From
Python, :func:`main` (``main(["reproduce", "--experiments", "4"])``) runs a command as the console
script does and returns its exit status; :func:`build_parser` is its parser. The parser's options
are in :mod:`rmac_mj.cli.run_options` and :mod:`rmac_mj.cli.view_options`, their building blocks in
:mod:`rmac_mj.cli.arguments`; the commands that run experiments in :mod:`rmac_mj.cli.runs`, those
that look at results in :mod:`rmac_mj.cli.views`.

Every command ends through :func:`main`, which holds the one rule for what goes wrong (the exit
statuses are :mod:`rmac_mj.errors`'): a bad input (an option, a configuration, a result file, a
snapshot) is one line ``rmac-mj: error: ...`` and exit status 2, nothing changed; an outside
environment's failure (raised, exited, non-finite or absurd observation or reward) is one line
``rmac-mj: environment failure: ...`` with its own message, the SPEC, the phase and the experiment and
trial, exit status 3; a full disk is one line, exit status 1; anything else is a bug of the package:
one line ``rmac-mj: internal error, a bug of rmac-mj: ...``, exit status 1. Except for a bad input,
the line ends with where the traceback was written: ``error.log`` in the run's result directory, or
a file under the cache's ``errors/``; ``rmac-mj --debug COMMAND`` prints it too.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import pathlib
import signal
import sys
import time
import traceback
from collections.abc import Mapping, Sequence
from typing import Any

from rmac_mj import __version__
from rmac_mj import _heartbeat as heartbeat
from rmac_mj.cli import run_options, runs, view_options, views
from rmac_mj.cli.arguments import PROG, HelpFormatter, OneLineErrorParser, say
from rmac_mj.errors import (
    EXIT_BAD_INPUT,
    EXIT_BUG,
    EXIT_ENVIRONMENT,
    EnvironmentFailure,
    UserInputError,
)

DESCRIPTION = "The rmac-mj command: reproduce the paper's comparison, draw its figures, render videos, benchmark."


def build_parser(reproduce_defaults: Mapping[str, Any] | None = None) -> argparse.ArgumentParser:
    """The parser of every command. ``reproduce_defaults``: defaults of ``reproduce``'s options that
    replace its own (the settings of a ``--config`` file or of a directory being resumed), by dest."""
    parser = OneLineErrorParser(
        prog=PROG,
        description=DESCRIPTION,
        epilog="Run 'rmac-mj COMMAND --help' for a command's options.",
        formatter_class=HelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    commands = parser.add_subparsers(
        dest="command", metavar="COMMAND", title="commands", parser_class=OneLineErrorParser
    )
    run_options.add_reproduce(commands, reproduce_defaults)
    run_options.add_sweep(commands)
    run_options.add_panel(commands)
    view_options.add_compare(commands)
    view_options.add_policy(commands)
    view_options.add_optimal(commands)
    view_options.add_render(commands)
    view_options.add_bench(commands)
    return parser


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
    parser.add_argument(
        "--debug",
        action="store_true",
        help="on any error, print its full traceback too (it is written to a log file anyway "
        "when the error is not a bad input)",
    )
    args = parser.parse_args(argv)
    if args.command is None:  # `rmac-mj` alone: what it can do
        parser.print_help()
        return 0
    signal.signal(signal.SIGTERM, _interrupt)  # a polite kill cleans up like Ctrl-C
    try:
        if args.command == "reproduce":
            with heartbeat.listening(say):  # a --config file's environment is probed
                args = runs.settings_from_files(argv, args)
        with _announcing_compilation(args.command), heartbeat.listening(say):
            status = _COMMANDS[args.command](args)
        if status == 0 and (log := _run_log(args)) is not None:
            log.unlink(missing_ok=True)  # an earlier failure's, now that the run has finished
        return status
    except KeyboardInterrupt as interrupt:
        detail = f"; {interrupt}" if str(interrupt) else ""
        print(f"\n{PROG}: interrupted{detail}", file=sys.stderr)
        return 130
    except Exception as error:
        return report(error, args)


def report(error: Exception, args: argparse.Namespace) -> int:
    """Say what went wrong in one line on stderr and return the exit status (module docstring);
    the traceback goes to a log file unless the input was bad, and to stderr too with --debug."""
    if getattr(args, "debug", False):
        traceback.print_exception(error, file=sys.stderr)
    kind = _kind(error)
    if kind == "input":
        _say_error(f"error: {error}")
        return EXIT_BAD_INPUT
    if kind == "misplaced":
        # os.replace(temporary, target) names the target second
        path = error.filename2 if getattr(error, "filename2", None) else error.filename
        _say_error(
            f"error: {path} is a "
            f"{'directory' if isinstance(error, IsADirectoryError) else 'file'} where a "
            f"{'file' if isinstance(error, IsADirectoryError) else 'directory'} is expected; "
            "what was saved is whole: move it away, or choose another path"
        )
        return EXIT_BAD_INPUT
    if kind == "storage":
        # The machine's storage, not a bug: what was saved is whole (every file is written
        # atomically), and --resume finishes the run once there is room.
        where = f" ({error.filename})" if error.filename else ""
        _say_error(
            f"error: cannot write{where}: {error.strerror}; what was saved is whole: free "
            "some space and run again with --resume"
        )
        return EXIT_BUG
    log = _write_log(error, args)
    kept = f"traceback in {log}" if isinstance(log, pathlib.Path) else f"traceback not kept: {log}"
    if kind == "environment":
        _say_error(f"environment failure: {error} ({kept})")
        return EXIT_ENVIRONMENT
    if kind == "memory":
        _say_error(
            f"error: out of memory ({type(error).__name__}: {error or 'no detail'}); nothing "
            f"larger than the machine can hold should be asked for ({kept})"
        )
        return EXIT_BUG
    _say_error(
        f"internal error, a bug of rmac-mj: {type(error).__name__}: {error} ({kept}; "
        "please report it)"
    )
    return EXIT_BUG


def _kind(error: Exception) -> str:
    """'input', 'misplaced' (a directory where a file belongs, or the reverse), 'environment',
    'storage', 'memory' or 'bug'."""
    from rmac_mj._gl import GLBackendError

    if isinstance(error, UserInputError | GLBackendError):  # no off-screen GL: names the packages
        return "input"
    if isinstance(error, EnvironmentFailure):
        return "environment"
    if isinstance(error, IsADirectoryError | NotADirectoryError) and error.filename:
        return "misplaced"  # the package makes no such thing: a user put it there
    if isinstance(error, OSError) and error.errno in _STORAGE_ERRORS:
        return "storage"
    if isinstance(error, MemoryError):
        return "memory"
    return "bug"


def _say_error(message: str) -> None:
    """``rmac-mj: MESSAGE`` on stderr, as one line whatever newlines the message holds."""
    line = " ".join(part.strip() for part in message.splitlines() if part.strip())
    print(f"{PROG}: {line}", file=sys.stderr, flush=True)


def _write_log(error: Exception, args: argparse.Namespace) -> pathlib.Path | str:
    """Write the traceback of ``error`` to :data:`ERROR_LOG` in the run's result directory (when it
    has one already), else to a new file under the cache's ``errors/``; its path, or why not."""
    path = _run_log(args)
    if path is None:
        from rmac_mj import _cache

        stamp = time.strftime("%Y%m%d-%H%M%S")
        path = _cache.user_cache_dir() / "errors" / f"{args.command}-{stamp}-{os.getpid()}.log"
    text = "".join(traceback.format_exception(error))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(f"{PROG} {args.command}\n{text}")
    except OSError as failure:
        return f"cannot write {path}: {failure.strerror or failure}"
    return path


def _run_log(args: argparse.Namespace) -> pathlib.Path | None:
    """Where a run keeps its last failure's traceback: :data:`ERROR_LOG` in its result directory
    (None when the command runs nothing, or the directory is not there yet)."""
    out = getattr(args, "out", None)
    if args.command not in ("reproduce", "sweep", "panel") or out is None:
        return None
    return pathlib.Path(out) / ERROR_LOG if pathlib.Path(out).is_dir() else None


#: The file in a result directory that keeps the traceback of the run's last failure.
ERROR_LOG = "error.log"


#: Storage errors reported in one line (disk full, quota exceeded, read-only file system).
_STORAGE_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS)


__all__ = ["ERROR_LOG", "build_parser", "main", "report"]

"""What every command shares: the program's name and start, one-line errors and status lines, and
the building blocks of the commands' options (the parser that reports an error in one line, the
help formatter, value types that refuse a bad value with what was expected, the option groups
several commands share)."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import pathlib
import sys
import time
from collections.abc import Sequence
from typing import Any

from rmac_mj import constraints
from rmac_mj.errors import UserInputError

#: When this process started (near enough: the CLI is imported first); wall times count from here.
STARTED = time.perf_counter()
PROG = "rmac-mj"


class UsageError(UserInputError):
    """A bad argument found after parsing: reported as one line, exit status 2."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM, with what the user needs to know (what was saved, how to resume)."""


def say(message: str) -> None:
    """A status line on stderr, for anything slow that shows no progress of its own."""
    print(f"{PROG}: {message}", file=sys.stderr, flush=True)


@contextlib.contextmanager
def user_input(what: str = ""):
    """Validation of what the user gave (a configuration, a file): its ValueError becomes a
    :class:`UsageError`, reported as one line. Wrap only validation, never a computation, so that a
    bug elsewhere keeps its traceback."""
    try:
        yield
    except UserInputError:
        raise
    except (ValueError, TypeError) as error:
        raise UsageError(f"{what}{error}") from None


def refuse_unwritable(path: pathlib.Path) -> None:
    """UsageError naming ``path`` when it cannot be made: checked without making anything, so that
    a command refuses a bad ``--out`` before the work that comes before writing (a panel measures
    its tasks' boxes first)."""
    existing = path
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise UsageError(f"cannot write to {path}: {existing} is not a directory")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise UsageError(f"cannot write to {path}: {existing} is not writable")


def writable_dir(path: pathlib.Path) -> pathlib.Path:
    """``path``, made if missing; UsageError naming it when it cannot be written to."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / ".write-probe"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as error:
        raise UsageError(f"cannot write to {path}: {error.strerror or error}") from None
    return path


class OneLineErrorParser(argparse.ArgumentParser):
    """Argument errors as one line and exit status 2, not a usage dump."""

    def error(self, message: str):  # noqa: D102
        self.exit(2, f"{self.prog}: error: {message}\n")


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
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


def int_at_least(minimum: int, expected: str):
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


positive_int = int_at_least(1, "a positive integer")


def constrained(allowed: Sequence[Any], number: type = int):
    """An argparse type: a ``number`` (int or float) that meets one of ``allowed``
    (:mod:`rmac_mj.constraints`), the constraint said when refused."""

    def parse(text: str):
        try:
            value = number(text)
        except ValueError:
            value = text
        problem = constraints.unmet(value, allowed)
        if problem is not None:
            raise argparse.ArgumentTypeError(f"expected {problem}, got {text!r}")
        return value

    return parse


def size_within(limit: constraints.Limit):
    """An argparse type: an integer within ``limit`` (a :class:`rmac_mj.constraints.Limit`), its
    reason said when refused."""
    return constrained([limit.constraint()])


non_negative_int = int_at_least(0, "an integer >= 0")


def floats(count: int | None, expected: str):
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


def state_dims(text: str) -> tuple[int, int]:
    try:
        i, j = (int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected two state dimensions I,J, got {text!r}"
        ) from None
    return i, j


def json_object(text: str) -> dict:
    """An argparse type: a JSON object, e.g. '{"bounds": {"velocity": [-10, 10]}}'."""
    import json

    try:
        value = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as error:
        shown = text if len(text) <= 80 else text[:77] + "..."
        raise argparse.ArgumentTypeError(
            f"expected a JSON object, got {shown!r} ({error or 'nested too deeply'})"
        ) from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"expected a JSON object {{...}}, got {text!r}")
    return value


def add_task_options(parser: argparse.ArgumentParser, default: bool, what: str) -> None:
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


def add_outside_options(parser: argparse.ArgumentParser) -> None:
    """What an outside environment (--env) may need beside its SPEC."""
    parser.add_argument(
        "--learner-state",
        type=json_object,
        default=None,
        metavar="JSON",
        help="with --env: what the learners' state is where it cannot be inferred, "
        "some of LearnerStateSpec's fields or per-dimension bounds, e.g. "
        '\'{"bounds": {"velocity": [-10, 10]}}\' (a --config file\'s '
        "[learner_state] table)",
    )
    parser.add_argument(
        "--action-repeat",
        type=size_within(constraints.ACTION_REPEAT),
        default=1,
        metavar="N",
        help="with --env: environment steps per learner step, the action held",
    )


def add_trust_env(parser: argparse.ArgumentParser, what: str) -> None:
    """--trust-env: run the outside environment ``what`` names (code of the user's) unnamed."""
    parser.add_argument(
        "--trust-env",
        action="store_true",
        help=f"run the environment {what} names where it is code of yours (a module or "
        "file) without naming it again with --env; a file is data otherwise, and opening it "
        "runs nothing it names (docs/guide/result-directory.md)",
    )


def add_command(commands, name: str, help: str) -> argparse.ArgumentParser:
    """A command of ``commands`` (the subparsers of the top parser), its ``help`` also its
    description; each ``add_COMMAND(commands)`` of the option modules declares one this way."""
    return commands.add_parser(name, help=help, description=help, formatter_class=HelpFormatter)

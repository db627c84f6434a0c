"""What every command shares: the program's name and start, one-line errors, status lines."""

from __future__ import annotations

import contextlib
import pathlib
import sys
import time

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

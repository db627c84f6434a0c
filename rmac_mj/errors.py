"""The exceptions for what goes wrong outside the package, and the exit status of each.

:class:`UserInputError` (bad input: an argument, a configuration, a file) and
:class:`EnvironmentFailure` (an outside environment failed or returned what no learner can take) are
one line from ``rmac-mj`` (exit :data:`EXIT_BAD_INPUT`, :data:`EXIT_ENVIRONMENT`); anything else is a
bug, one line naming where its traceback was written (:data:`EXIT_BUG`).
"""

import contextlib
from collections.abc import Iterator

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_BUG",
    "EXIT_ENVIRONMENT",
    "EnvironmentFailure",
    "MissingExtra",
    "MissingInputError",
    "UserInputError",
    "environment_failure_at",
]

#: Exit status of a bad input (as argparse's own): nothing was changed.
EXIT_BAD_INPUT = 2
#: Exit status of an outside environment's failure: its own message, and where it happened.
EXIT_ENVIRONMENT = 3
#: Exit status of a bug of the package (and of a full disk: what was saved is whole).
EXIT_BUG = 1


class UserInputError(ValueError):
    """Bad input from a user: an argument, a configuration, or a file they pointed to."""


class MissingInputError(UserInputError, FileNotFoundError):
    """A file or result the user pointed to does not exist (still a ``FileNotFoundError``)."""


class MissingExtra(UserInputError, ImportError):
    """What the user asked for needs an optional extra that is not installed (a learner of the
    ``[baselines]`` extra): the message names the extra and how to install it. Still an
    ``ImportError`` to code that catches one."""


class EnvironmentFailure(RuntimeError):
    """An outside environment failed (raised, exited, or gave a non-finite or absurd observation or
    reward); the message holds its own message and where it came from (the SPEC, the phase, the
    experiment and trial when known)."""

    def during(self, where: str) -> "EnvironmentFailure":
        """The same failure with ``where`` (e.g. ``"s-ac experiment 3, trial 17"``) appended."""
        failure = EnvironmentFailure(f"{self}; {where}")
        failure.__cause__ = self.__cause__ or self
        return failure


@contextlib.contextmanager
def environment_failure_at(where: str) -> Iterator[None]:
    """An :class:`EnvironmentFailure` in the body, told ``where`` it happened (appended)."""
    try:
        yield
    except EnvironmentFailure as failure:
        raise failure.during(where) from failure.__cause__

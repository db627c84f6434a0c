"""The project's exceptions for what goes wrong outside the package, and the exit status of each.

Anything a user can get wrong (a command-line argument, a configuration value, a result directory, a
snapshot or data file) raises :class:`UserInputError`; an outside environment (``rmac_mj.envs``) that
fails while it is imported, built, reset or stepped, or that hands back an observation or reward no
learner can take, raises :class:`EnvironmentFailure`. The ``rmac-mj`` command reports either as one
line (exit status :data:`EXIT_BAD_INPUT` or :data:`EXIT_ENVIRONMENT`); every other exception is a bug
of the package, reported in one line that says where its traceback was written
(:data:`EXIT_BUG`).
"""

import contextlib
from collections.abc import Iterator

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

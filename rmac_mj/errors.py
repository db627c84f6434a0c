"""The project's exception for bad user input.

Anything a user can get wrong (a command-line argument, a configuration value, a result directory, a
snapshot or data file) raises :class:`UserInputError`; the ``rmac-mj`` command reports it as one line
with exit status 2. Every other exception is a bug and keeps its traceback.
"""


class UserInputError(ValueError):
    """Bad input from a user: an argument, a configuration, or a file they pointed to."""


class MissingInputError(UserInputError, FileNotFoundError):
    """A file or result the user pointed to does not exist (still a ``FileNotFoundError``)."""

""":class:`UserInputError`: bad user input, which the CLI prints in one line (exit status 2).

Every other exception is a bug and keeps its traceback.
"""


class UserInputError(ValueError):
    """Bad input from a user: an argument, a configuration, or a file they pointed to."""


class MissingInputError(UserInputError, FileNotFoundError):
    """A file or result the user pointed to does not exist (still a ``FileNotFoundError``)."""

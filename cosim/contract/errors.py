"""Error types shared across the framework.

:class:`UserError` marks a problem with the user's input (a scenario, a log
file, a plugin, a parameter): the CLI prints its message as one line and
exits with status 2 instead of showing a traceback. Messages name the file,
field or component and say what is wrong.
"""


class UserError(Exception):
    """Bad input from the user; the message says what and where."""


class OutputWriteError(UserError):
    """Writing one of a run's output files failed (a full disk, a lost mount): ``path`` and the
    operating system's ``reason``."""

    def __init__(self, path, exc: OSError):
        from pathlib import Path

        self.path, self.reason = Path(path), exc.strerror or str(exc)
        super().__init__(f"writing {path} failed: {self.reason}")

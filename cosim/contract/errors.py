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


class ComponentError(UserError):
    """A component rejected its parameters or failed while stepping."""


class InputEnded(Exception):
    """Raised by a component's ``step`` when the recorded input it replays has run out: the run
    ends there, as one that ran its duration does (status ``ok``), with the ticks before this one."""


class ComponentFault(RuntimeError):
    """A component detected an unsafe condition and asks the run to stop cleanly.

    Raised by the framework, after the step's (safe) outputs went out, when a
    component has set its ``fault`` attribute (see :class:`Component`).
    """

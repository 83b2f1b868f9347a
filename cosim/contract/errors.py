"""The framework's errors, in two families.

* Bad input, found before a run starts: :class:`UserError` (a scenario, a log
  file, a plugin, a parameter) and its kinds, :class:`ScenarioError`,
  :class:`PluginError`, :class:`HostsError`, :class:`ComponentError`.
* A run that started and then stopped: :class:`RunError` (a component failed,
  hung or vanished), :class:`RunFault` (a component stopped it on an unsafe
  condition), :class:`WriteError` (its outputs could not be written).

The CLI prints either as one line and exits with status 2 instead of showing
a traceback; messages name the file, field or component and say what is wrong.
A component signals with :class:`InputEnded` and :class:`ComponentFault`.
"""

from pathlib import Path


class UserError(Exception):
    """Bad input from the user; the message says what and where."""


class ScenarioError(UserError):
    """A scenario file or override is invalid; the message names the field and line."""


class WiringError(ScenarioError):
    """The scenario's components cannot be wired as written (a port that does not exist, two sources for one
    input, a cycle without a delayed edge...)."""


class PluginError(UserError):
    """A plugin could not be loaded, or registered something invalid."""


class HostsError(UserError):
    """A hosts file (a run over machines) is invalid; the message names the field and line."""


class OutputWriteError(UserError):
    """Writing one of a run's output files failed (a full disk, a lost mount): ``path`` and the
    operating system's ``reason``."""

    def __init__(self, path, exc: OSError):
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


class PortTimeout(RuntimeError):
    """No value of ``component.port`` (of any of its outputs: ``port`` None) for tick ``stamp``: the run's
    scheduler turns it into a :class:`RunError` naming the component that did not answer."""

    def __init__(self, component: str, port: str | None, stamp: int):
        super().__init__(f"no value of {component}.{port or '*'} for tick {stamp}")
        self.component, self.port, self.stamp = component, port, stamp

    @property
    def what(self) -> str:
        """The missing value in words: "its output 'x'" or "its outputs"."""
        return f"its output {self.port!r}" if self.port else "its outputs"


class RunError(Exception):
    """A run stopped because a component failed, hung or vanished (not bad input: the run had started).

    ``tick``: the step that failed, when a node reported it (nodes may be
    ahead of the tick the scheduler was recording).
    """

    def __init__(self, component: str, message: str, tick: int | None = None):
        super().__init__(f"component {component!r}: {message}")
        self.component, self.tick = component, tick


class RunFault(RunError):
    """A component stopped the run on an unsafe condition (its outputs were made safe first)."""

    def __init__(self, component: str, message: str, tick: int | None = None):
        super().__init__(component, f"fault: {message}", tick)


class WriteError(RunError):
    """Writing the run's outputs failed (a full disk): the run stops, what was written is kept.
    ``phase``: "stepping" or "writing the outputs"."""

    def __init__(self, exc: OutputWriteError, phase: str, t_s: float | None = None):
        at = f" at t = {t_s:.3f} s" if t_s is not None else ""
        Exception.__init__(self, f"{exc} (the run stopped{at}, while {phase}; what was written before is kept)")
        self.component, self.tick, self.phase, self.path = "recording", None, phase, exc.path

"""The component contract: what the scheduler steps.

A component declares its input and output ports, is set up once with its
scenario parameters and a private seeded random generator, is stepped at
``t`` with the latest values of its inputs, and is closed at the end.
A component never sleeps, never reads the clock and never draws from a
global RNG, so a run is reproducible from its scenario and seed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Protocol

import numpy as np

from cosim.contract.errors import ComponentError, ComponentFault, InputEnded  # noqa: F401 (a component raises them)
from cosim.contract.params import read_params


@dataclass(frozen=True)
class Port:
    """One named array signal.

    ``shape`` is the array shape (``()`` for a scalar, ``(3,)`` for a vector);
    ``unit`` is an SI unit string (``"m"``, ``"rad/s"``, ``"T"``, ``"A"``,
    ``"V"``, ``"1"`` for dimensionless).
    """

    name: str
    shape: tuple[int, ...]
    unit: str
    doc: str = ""

    def zeros(self) -> np.ndarray:
        """An array of zeros of the port's shape."""
        return np.zeros(self.shape)


class Component:
    """Base class for components; subclasses override what they need.

    Class attributes:
        inputs, outputs: tuples of :class:`Port`. A component whose ports
            depend on its parameters sets them on the instance in ``setup``.
        period: default update period in multiples of the scenario's ``dt``
            (a scenario may override it); between updates the outputs hold.
    """

    inputs: tuple[Port, ...] = ()
    outputs: tuple[Port, ...] = ()
    period: int = 1
    #: Set to a message in ``step`` to stop the run cleanly after this step's
    #: outputs are published (e.g. an actuator's driver refusing a NaN command:
    #: it outputs zero field and sets ``fault``). The run records the fault.
    #: Set in ``close`` (making the outputs safe failed, or a fault found
    #: after the last step), it ends the run with status ``fault`` too.
    fault: str | None = None

    #: Set True to receive the scenario's path object as ``params["path"]``.
    uses_path: bool = False
    #: Set True to receive the run's output folder as ``params["run_dir"]`` (a
    #: :class:`pathlib.Path`, or None when the component runs outside a run), the
    #: id of the run's rerun recording as ``params["recording_id"]`` and its own name
    #: in the scenario as ``params["name"]``: for files of its own (a video of its
    #: frames, its part of the recording), written as the run goes.
    uses_run_dir: bool = False

    def setup(self, params: Mapping[str, Any], rng: np.random.Generator) -> None:
        """Validate ``params`` (raise :class:`ComponentError` naming the bad one) and initialise.

        ``params`` holds the scenario's parameters for this component plus
        ``dt`` (the scenario step [s]), when ``uses_path`` is set ``path`` (a
        :class:`cosim.contract.paths.ReferencePath`), and when ``uses_run_dir`` is set ``run_dir``,
        ``recording_id`` and ``name``. ``rng`` is private to the component and seeded
        from the scenario seed and the component name.
        """

    #: The parameters :func:`cosim.contract.params.read_params` reads in ``setup`` (``{name: Param}``):
    #: set it and the default :meth:`validate_params` checks names, types and bounds with them.
    params_spec: Mapping[str, Any] | None = None

    @classmethod
    def validate_params(cls, params: Mapping[str, Any]) -> None:
        """Check the scenario's ``params`` (plus ``dt``) cheaply, with no side effect (nothing
        trained, nothing written, no hardware opened); raise :class:`ComponentError`. Called by
        ``cosim validate`` and before any component is set up, so bad input fails before a run starts.
        Default: :attr:`params_spec` read as ``setup`` reads it, when set."""
        if cls.params_spec is not None:
            read_params(params, cls.params_spec)

    @classmethod
    def prepare(cls, params: Mapping[str, Any]) -> None:
        """Make, once and before runs fan out over processes or machines, what ``setup`` would
        otherwise make in each of them (a model trained on demand, a data set generated, the
        plant's FMU built), so parallel runs never race to make the same thing. Called in the
        process that starts the runs, with the scenario's ``params`` (plus ``dt``) of every
        combination of a sweep; must be cheap when everything is made already. Default: nothing."""

    @classmethod
    def artifacts(cls, params: Mapping[str, Any]) -> list:
        """The files besides code that this component's behaviour depends on for these
        ``params`` (plus ``dt``): a plant's FMU, a model file. Their content enters the run's
        fingerprint (see :mod:`cosim.runtime.fingerprint`), which sweep rows record and every node of
        a run over machines checks. Default: none."""
        return []

    @classmethod
    def recording_views(cls, name: str) -> list:
        """rerun blueprint views (``rerun.blueprint`` views) this component, named ``name`` in
        the scenario, adds to the run's recording layout, for what it logs itself (see
        :func:`cosim.record.rerun_log.component_recording`). Default: none."""
        return []

    @classmethod
    def summary_figures(cls, outputs: Mapping[str, np.ndarray]) -> dict[str, Any]:
        """Figures for the run's ``summary.json``, from this component's recorded outputs
        (``{port: (ticks, *port shape)}``, SI units, NaN where a port had no value). The keys
        join the summary's top level and must not reuse the framework's. Default: none."""
        return {}

    @classmethod
    def summary_accumulator(cls) -> SummaryAccumulator | None:
        """How the run computes :meth:`summary_figures` as it goes, batch by batch: an object
        with ``add(outputs)`` (``{port: (batch ticks, *port shape)}``, the ticks in order) and
        ``figures()`` (the figures of every batch added). Override it with one that keeps
        counts or running sums, so a run of any length stays in bounded memory. Default: None
        when :meth:`summary_figures` is not overridden, else one that keeps every batch and
        calls it at the end (its memory grows with the run)."""
        if cls.summary_figures.__func__ is Component.summary_figures.__func__:
            return None
        return KeepEveryBatch(cls.summary_figures)

    def initial_outputs(self) -> dict[str, np.ndarray]:
        """Outputs before the first step (used by delayed edges at t = 0). Default: zeros."""
        return {p.name: p.zeros() for p in self.outputs}

    def step(self, t: float, inputs: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Bring the component to time ``t`` [s] and return its outputs at ``t``.

        ``inputs`` holds the latest value of every input port. Over a delayed
        edge (``delay: 1``, e.g. a plant's actuator commands) that is the value
        produced one tick earlier, i.e. the input applied over ``[t - dt, t)``;
        a plant therefore integrates from its previous time to ``t`` with it.
        At the first tick (``t == 0``) a plant integrates nothing.
        """
        raise NotImplementedError

    def close(self) -> None:
        """Release resources (files, FMU instances) and make outputs safe. Called at the end of
        every run, also after a failure or a stop, before the recording is finished; may set
        ``fault``. It must be idempotent."""


class SummaryAccumulator(Protocol):
    """Figures of a component's outputs computed batch by batch (see :meth:`Component.summary_accumulator`)."""

    def add(self, outputs: Mapping[str, np.ndarray]) -> None:
        """Take one batch of the component's outputs, ``{port: array (n ticks, *shape)}``."""

    def figures(self) -> dict[str, Any]:
        """The figures of every batch taken, for the run's summary."""


class KeepEveryBatch:
    """The default accumulator: keeps every batch, calls ``summary_figures`` on all of them at the end."""

    def __init__(self, summary_figures):
        self._figures_of, self._batches = summary_figures, []

    def add(self, outputs: Mapping[str, np.ndarray]) -> None:
        """Keep a copy of the batch."""
        self._batches.append({k: np.array(v) for k, v in outputs.items()})

    def figures(self) -> dict[str, Any]:
        """``summary_figures`` of the batches joined ({} when none)."""
        if not self._batches:
            return {}
        return self._figures_of({k: np.concatenate([b[k] for b in self._batches]) for k in self._batches[0]})

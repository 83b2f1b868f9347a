"""An FMI 2.0 co-simulation FMU as a component (fmpy).

A subclass declares its ports as any component does, and maps each onto the
FMU's variables: :attr:`FmuComponent.input_variables` and
:attr:`FmuComponent.output_variables` (``{port: (variable, ...)}``, one
variable per element of the port, in order). It names the FMU file in
:meth:`FmuComponent.fmu_file` (by default the ``fmu`` parameter). Every
other parameter is set on the FMU by its FMI name (reals, integers,
booleans); an unknown name is refused with the list of valid ones.

Inputs arrive over delayed edges: the values seen at ``step(t)`` were
applied over ``[t_prev, t)``, so the component sets them and integrates the
FMU from its previous time to ``t``. A call that returns an error status, or
during which the FMU logs a message at error status or above, raises a
:class:`~cosim.contract.component.ComponentError` with the FMU's messages.
The hot path calls the FMI functions of the FMU's library directly (the
ctypes functions fmpy configured, without its per-call wrapper) on
preallocated buffers: one ``fmi2SetReal``, one ``fmi2DoStep`` and one
``fmi2GetReal`` per step.
"""

from __future__ import annotations

import ctypes
import shutil
from pathlib import Path
from typing import Any, Mapping

import numpy as np
from fmpy import calloc, extract, free, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2Real,
    fmi2ValueReference,
)

from cosim.contract.component import Component, ComponentError

#: fmi2Error: a message logged at this status or above fails the call that logged it
ERROR_STATUS = 3
#: fmi2Warning: a call that returns a status above it failed
WARNING_STATUS = 1
#: parameters the component takes itself (not FMU variables)
OPTIONS = ("fmu", "dt")


class FmuComponent(Component):
    """Base of a component that runs one FMU instance (see the module docstring)."""

    #: ``{input port: (FMU variable, ...)}``, one variable per element of the port
    input_variables: Mapping[str, tuple[str, ...]] = {}
    #: ``{output port: (FMU variable, ...)}``; a variable may feed several ports
    output_variables: Mapping[str, tuple[str, ...]] = {}
    #: the FMU instance's name (in its log messages)
    instance_name = "fmu"
    #: whether the FMU may log its debug categories (its errors it logs either way)
    logging_on = True

    def __init__(self) -> None:
        self._fmu: FMU2Slave | None = None
        self._unzip_dir: str | None = None
        self._log: list[tuple[int, str]] = []  # (FMI status, message) the FMU logged
        self._t = 0.0
        self._last: dict[str, np.ndarray] = {}

    @classmethod
    def fmu_file(cls, params: Mapping[str, Any]) -> Path:
        """The FMU file to run: the ``fmu`` parameter (a subclass may build or find its own)."""
        given = params.get("fmu")
        if given is None:
            raise ComponentError("needs the parameter fmu (the FMU file to run)")
        path = Path(given)
        if not path.is_file():
            raise ComponentError(f"fmu={given}: no such FMU file")
        return path

    @classmethod
    def artifacts(cls, params: Mapping[str, Any]) -> list:
        """The FMU file: its content is part of a run's fingerprint."""
        return [cls.fmu_file(params)]

    @classmethod
    def model_description_file(cls, params: Mapping[str, Any]) -> Path:
        """Where :meth:`validate_params` reads the FMU's variables: the FMU itself by default (a
        subclass that builds its FMU may name its ``modelDescription.xml``, so checking builds nothing)."""
        return cls.fmu_file(params)

    @classmethod
    def validate_params(cls, params: Mapping[str, Any]) -> None:
        """Every parameter but the options names a settable FMU variable and has its type."""
        cls._checked_values(params, cls.model_description_file(params))

    @classmethod
    def _checked_values(cls, params: Mapping[str, Any], source: Path):
        """``(model description, {name: variable}, typed values)`` of ``params`` on the FMU's variables."""
        params = {k: v for k, v in params.items() if k not in OPTIONS}
        md = read_model_description(str(source))
        variables = {v.name: v for v in md.modelVariables}
        settable = {n: v for n, v in variables.items() if v.causality == "parameter"}
        unknown = sorted(set(params) - set(settable))
        if unknown:
            raise ComponentError(f"unknown parameter(s) {', '.join(unknown)}; "
                                 f"valid: {', '.join([*OPTIONS, *settable])}")
        missing = [n for names in (*cls.input_variables.values(), *cls.output_variables.values())
                   for n in names if n not in variables]
        if missing:
            raise ComponentError(f"{source} has no variable(s) {', '.join(missing)}")
        return md, variables, _typed_values(params, settable)

    # ------------------------------------------------------------ setup
    def setup(self, params: Mapping[str, Any], rng: np.random.Generator) -> None:
        """Instantiate the FMU of ``params`` with the parameters mapped onto its variables, up to t = 0."""
        fmu_path = self.fmu_file(params)
        md, variables, values = self._checked_values(params, fmu_path)

        self._unzip_dir = extract(str(fmu_path))
        self._fmu = FMU2Slave(guid=md.guid, unzipDirectory=self._unzip_dir,
                              modelIdentifier=md.coSimulation.modelIdentifier, instanceName=self.instance_name)
        self._fmu.instantiate(callbacks=self._callbacks(), loggingOn=self.logging_on)
        self._call("initialisation", self._initialise, values)

        in_names = [n for names in self.input_variables.values() for n in names]
        self._in_vr = _vr_array([variables[n].valueReference for n in in_names])
        self._in_buf = (fmi2Real * len(in_names))()
        self._in_np = np.ctypeslib.as_array(self._in_buf) if in_names else np.zeros(0)
        self._in_index = _port_slices(self.input_variables)
        out_names = [n for names in self.output_variables.values() for n in names]
        self._out_vr = _vr_array([variables[n].valueReference for n in out_names])
        self._out_buf = (fmi2Real * len(out_names))()
        self._out_np = np.ctypeslib.as_array(self._out_buf) if out_names else np.zeros(0)
        self._out_index = list(_port_slices(self.output_variables).items())
        dll = self._fmu.dll  # the functions fmpy configured (argument and result types)
        self._set_real, self._do_step_c, self._get_real = (getattr(dll, f) for f in
                                                           ("fmi2SetReal", "fmi2DoStep", "fmi2GetReal"))
        self._t = 0.0
        self._last = self._read_outputs()

    def _callbacks(self) -> fmi2CallbackFunctions:
        def logger(env, instance, status, category, message):  # noqa: ARG001
            self._log.append((status, message.decode("utf-8", "replace") if message else ""))

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self._cb = cb  # the ctypes callbacks must outlive the FMU instance
        return cb

    def _initialise(self, values: dict[str, dict[int, Any]]) -> None:
        fmu = self._fmu
        fmu.setupExperiment(startTime=0.0)
        for kind, setter in (("Real", fmu.setReal), ("Integer", fmu.setInteger), ("Boolean", fmu.setBoolean)):
            if values[kind]:
                setter(list(values[kind]), list(values[kind].values()))
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()

    def _call(self, what: str, fn, *args):
        """An FMU call; an error status, or an error the FMU logged meanwhile, becomes a
        ComponentError with the messages the FMU logged."""
        n_log = len(self._log)
        try:
            result, failed = fn(*args), None
        except FMICallException as exc:
            result, failed = None, exc
        if failed or len(self._log) > n_log:
            logged = self._log[n_log:]
            if failed or any(status >= ERROR_STATUS for status, _ in logged):
                raise ComponentError(f"{what} failed: {'; '.join(m for _, m in logged) or failed}")
        return result

    # ------------------------------------------------------------- stepping
    def initial_outputs(self) -> dict[str, np.ndarray]:
        """The FMU's outputs at t = 0, as its ports."""
        return {k: v.copy() for k, v in self._last.items()}

    def step(self, t: float, inputs: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Set the inputs, integrate the FMU from its last time to ``t`` [s] and return its outputs."""
        t = float(t)
        if t > self._t:
            buf = self._in_np
            for port, index in self._in_index.items():
                buf[index] = inputs[port]
            self._call(f"step to t={t:g} s", self._do_step, t)
            self._t = t
            self._last = self._read_outputs()
        elif t < self._t:
            raise ComponentError(f"time went backwards ({t:g} s after {self._t:g} s)")
        return self._last

    def _do_step(self, t: float) -> None:
        component = self._fmu.component
        if len(self._in_buf):
            _check("fmi2SetReal", self._set_real(component, self._in_vr, len(self._in_buf), self._in_buf))
        _check("fmi2DoStep", self._do_step_c(component, self._t, t - self._t, 1))

    def _read_outputs(self) -> dict[str, np.ndarray]:
        if len(self._out_buf):
            _check("fmi2GetReal", self._get_real(self._fmu.component, self._out_vr, len(self._out_buf), self._out_buf))
        values = self._out_np.copy()  # one fresh array per step; the ports are views into it
        return {port: values[index] for port, index in self._out_index}

    # ------------------------------------------------------ snapshot / close
    def snapshot(self) -> tuple[float, bytes]:
        """The full FMU state at the current time (serialized)."""
        state = self._fmu.getFMUstate()
        try:
            return self._t, self._fmu.serializeFMUstate(state)
        finally:
            self._fmu.freeFMUstate(state)

    def restore(self, snap: tuple[float, bytes]) -> None:
        """Return the FMU to a :meth:`snapshot` (its time, state and outputs)."""
        t, data = snap
        state = self._fmu.deSerializeFMUstate(data)
        try:
            self._fmu.setFMUstate(state)
        finally:
            self._fmu.freeFMUstate(state)
        self._t = t
        self._last = self._read_outputs()

    @property
    def log(self) -> list[str]:
        """Messages the FMU sent to its logger."""
        return [message for _, message in self._log]

    def close(self) -> None:
        """Terminate and free the FMU instance (idempotent)."""
        if self._fmu is not None:
            fmu, self._fmu = self._fmu, None
            try:
                fmu.terminate()
            except FMICallException:  # an FMU in the error state may refuse
                pass
            fmu.freeInstance()
        if self._unzip_dir is not None:
            shutil.rmtree(self._unzip_dir, ignore_errors=True)
            self._unzip_dir = None


def _check(function: str, status: int) -> None:
    if status > WARNING_STATUS:
        raise FMICallException(function=function, status=status)


def _vr_array(vrs: list[int]) -> ctypes.Array:
    return (fmi2ValueReference * len(vrs))(*vrs)


def _port_slices(variables: Mapping[str, tuple[str, ...]]) -> dict[str, Any]:
    """Where each port lies in a buffer of its variables laid end to end: a slice, or
    ``(i, ...)`` for a one-variable port (a 0-d view)."""
    out, start = {}, 0
    for port, names in variables.items():
        out[port] = (start, Ellipsis) if len(names) == 1 else slice(start, start + len(names))
        start += len(names)
    return out


def _typed_values(params: Mapping[str, Any], settable: Mapping) -> dict[str, dict[int, Any]]:
    """``{"Real" | "Integer" | "Boolean": {value reference: value}}`` of the FMU parameters in ``params``."""
    out: dict[str, dict[int, Any]] = {"Real": {}, "Integer": {}, "Boolean": {}}
    for name, value in params.items():
        var = settable[name]
        if var.type == "Boolean":
            if not (isinstance(value, (bool, np.bool_)) or value in (0, 1)):
                raise ComponentError(f"parameter {name} must be true or false, got {value!r}")
            out["Boolean"][var.valueReference] = bool(value)
        elif isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise ComponentError(f"parameter {name}={value!r}: expected a number")
        elif var.type in ("Integer", "Enumeration"):
            if value != int(value):
                raise ComponentError(f"parameter {name}={value!r}: expected a whole number")
            out["Integer"][var.valueReference] = int(value)
        else:
            out["Real"][var.valueReference] = float(value)
    return out

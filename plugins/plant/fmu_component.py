"""``plant.fmu``: the swimmer plant FMU as a cosim component (fmpy, FMI 2.0 CS).

Inputs arrive over a delayed edge from the coil driver: the values seen at
``step(t)`` were applied over ``[t_prev, t)``, so the plant sets them and
integrates from its previous time to ``t``. Every FMU parameter can be set
from the scenario by its FMI name (see ``fmus/swimmer_plant/README.md``).
"""

from __future__ import annotations

import ctypes
import shutil
from pathlib import Path
from typing import Any, Mapping

import numpy as np
from fmpy import extract, read_model_description
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

from cosim.component import Component, ComponentError, Port

#: FMU input variables, in the order of the input buffer.
INPUT_NAMES = (
    *(f"V_amp_{i}" for i in range(1, 7)),
    *(f"V_phase_{i}" for i in range(1, 7)),
    "freq",
)
#: Output ports -> FMU output variables.
OUTPUT_MAP = {
    "position": ("p_x", "p_y", "p_z"),
    "velocity": ("v_x", "v_y", "v_z"),
    "axis": ("axis_x", "axis_y", "axis_z"),
    "spin_rate": ("spin_rate",),
    "coil_current_amp": tuple(f"I_amp_{i}" for i in range(1, 7)),
    "field": ("B_x", "B_y", "B_z"),
}
#: Component options that are not FMU parameters.
OPTIONS = ("fmu", "dt")


class FmuPlant(Component):
    """Six-coil manipulator + spiral swimmer + tank, simulated by the C FMU."""

    inputs = (
        Port("coil_voltage_amp", (6,), "V", "voltage amplitude per coil (+x, -x, +y, -y, +z, -z)"),
        Port("coil_voltage_phase", (6,), "rad", "voltage phase per coil"),
        Port("drive_freq", (), "Hz", "drive frequency; v_i = amp_i cos(2 pi f t + phase_i)"),
    )
    outputs = (
        Port("position", (3,), "m", "swimmer centre"),
        Port("velocity", (3,), "m/s", "swimmer velocity"),
        Port("axis", (3,), "1", "unit vector of the long axis"),
        Port("spin_rate", (), "Hz", "mean spin about the long axis over the last step"),
        Port("coil_current_amp", (6,), "A", "current amplitude per coil"),
        Port("field", (3,), "T", "field at the swimmer"),
    )

    def __init__(self) -> None:
        self._fmu: FMU2Slave | None = None
        self._unzip_dir: str | None = None
        self._log: list[str] = []
        self._t = 0.0
        self._last: dict[str, np.ndarray] = {}

    # ------------------------------------------------------------ setup
    @classmethod
    def prepare(cls, params: Mapping[str, Any]) -> None:
        """Build the project's FMU now if it is missing or stale (a user's FMU is used as it is)."""
        _fmu_file(params)

    @classmethod
    def artifacts(cls, params: Mapping[str, Any]) -> list:
        return [_fmu_file(params)]

    def setup(self, params: Mapping[str, Any], rng: np.random.Generator) -> None:
        params = dict(params)
        fmu_path = _fmu_file(params)
        params.pop("fmu", None)
        self.dt = float(params.pop("dt", 0.02))
        md = read_model_description(str(fmu_path))
        variables = {v.name: v for v in md.modelVariables}
        settable = {n: v for n, v in variables.items() if v.causality == "parameter"}
        unknown = sorted(set(params) - set(settable))
        if unknown:
            valid = ", ".join([*OPTIONS, *settable])
            raise ComponentError(f"plant.fmu: unknown parameter(s) {', '.join(unknown)}; valid: {valid}")
        reals, bools = self._split_params(params, settable)

        self._unzip_dir = extract(str(fmu_path))
        self._fmu = FMU2Slave(
            guid=md.guid,
            unzipDirectory=self._unzip_dir,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName="plant",
        )
        self._fmu.instantiate(callbacks=self._make_callbacks())
        self._call("setting parameters", self._set_params, reals, bools)
        self._call("initialisation", self._initialise)

        self._in_vr = _vr_array([variables[n].valueReference for n in INPUT_NAMES])
        self._in_buf = (fmi2Real * len(INPUT_NAMES))()
        self._in_np = np.ctypeslib.as_array(self._in_buf)
        out_names = [n for names in OUTPUT_MAP.values() for n in names]
        self._out_vr = _vr_array([variables[n].valueReference for n in out_names])
        self._out_buf = (fmi2Real * len(out_names))()
        self._out_np = np.ctypeslib.as_array(self._out_buf)
        # where each port lies in the output buffer: a slice, or (i, ...) for a scalar (a 0-d view)
        self._out_index = []
        start = 0
        for port, names in OUTPUT_MAP.items():
            index = (start, Ellipsis) if len(names) == 1 else slice(start, start + len(names))
            self._out_index.append((port, index))
            start += len(names)
        self._t = 0.0
        self._last = self._read_outputs()

    @staticmethod
    def _split_params(params: dict, settable: dict) -> tuple[dict, dict]:
        reals, bools = {}, {}
        for name, value in params.items():
            var = settable[name]
            if var.type == "Boolean":
                if isinstance(value, (bool, np.bool_)) or value in (0, 1):
                    bools[var.valueReference] = bool(value)
                else:
                    raise ComponentError(f"plant.fmu: parameter {name} must be true or false, got {value!r}")
            else:
                try:
                    reals[var.valueReference] = float(value)
                except (TypeError, ValueError):
                    raise ComponentError(f"plant.fmu: parameter {name} must be a number, got {value!r}") from None
        return reals, bools

    def _make_callbacks(self) -> fmi2CallbackFunctions:
        from fmpy import calloc, free

        def logger(env, instance, status, category, message):  # noqa: ARG001
            self._log.append(message.decode("utf-8", "replace") if message else "")

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self._callbacks = cb  # keep the ctypes callbacks alive
        return cb

    def _set_params(self, reals: dict, bools: dict) -> None:
        fmu = self._fmu
        fmu.setupExperiment(startTime=0.0)
        if reals:
            fmu.setReal(list(reals), list(reals.values()))
        if bools:
            fmu.setBoolean(list(bools), list(bools.values()))

    def _initialise(self) -> None:
        self._fmu.enterInitializationMode()
        self._fmu.exitInitializationMode()

    def _call(self, what: str, fn, *args):
        """Run an FMU call; an error status becomes a ComponentError with the FMU's message."""
        n_log = len(self._log)
        try:
            return fn(*args)
        except FMICallException as exc:
            detail = "; ".join(self._log[n_log:]) or str(exc)
            raise ComponentError(f"plant.fmu: {what} failed: {detail}") from None

    # ------------------------------------------------------------- stepping
    def initial_outputs(self) -> dict[str, np.ndarray]:
        return {k: v.copy() for k, v in self._last.items()}

    def step(self, t: float, inputs: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        t = float(t)
        if t > self._t:
            buf = self._in_np
            buf[0:6] = inputs["coil_voltage_amp"]
            buf[6:12] = inputs["coil_voltage_phase"]
            buf[12] = inputs["drive_freq"]
            fmu = self._fmu
            n_log = len(self._log)
            try:
                fmu.fmi2SetReal(fmu.component, self._in_vr, 13, self._in_buf)
                fmu.fmi2DoStep(fmu.component, self._t, t - self._t, 1)
            except FMICallException as exc:
                detail = "; ".join(self._log[n_log:]) or str(exc)
                raise ComponentError(f"plant.fmu: step to t={t:g} s failed: {detail}") from None
            self._t = t
            self._last = self._read_outputs()
        elif t < self._t:
            raise ComponentError(f"plant.fmu: time went backwards ({t:g} s after {self._t:g} s)")
        return self._last

    def _read_outputs(self) -> dict[str, np.ndarray]:
        fmu = self._fmu
        fmu.fmi2GetReal(fmu.component, self._out_vr, len(self._out_buf), self._out_buf)
        values = self._out_np.copy()  # one fresh array per step; the ports are views into it
        return {port: values[index] for port, index in self._out_index}

    # ------------------------------------------------------ snapshot / close
    def snapshot(self) -> tuple[float, bytes]:
        """The full plant state at the current time (FMU state, serialized)."""
        state = self._fmu.getFMUstate()
        try:
            return self._t, self._fmu.serializeFMUstate(state)
        finally:
            self._fmu.freeFMUstate(state)

    def restore(self, snap: tuple[float, bytes]) -> None:
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
        return list(self._log)

    def close(self) -> None:
        if self._fmu is not None:
            fmu, self._fmu = self._fmu, None
            try:
                fmu.terminate()
            except Exception:  # noqa: BLE001 - an FMU in the error state may refuse
                pass
            fmu.freeInstance()
        if self._unzip_dir is not None:
            shutil.rmtree(self._unzip_dir, ignore_errors=True)
            self._unzip_dir = None


def _vr_array(vrs: list[int]) -> ctypes.Array:
    return (fmi2ValueReference * len(vrs))(*vrs)


def _fmu_file(params: Mapping[str, Any]) -> Path:
    """The FMU the plant runs: ``params["fmu"]`` (a user's, used as it is) or the project's,
    built on first use."""
    # imported here so that `python -m cosim_plugins.plant.build` does not
    # import its own module twice (the package imports this file)
    from cosim_plugins.plant.build import ensure_fmu

    given = params.get("fmu")
    if given is None:
        return ensure_fmu()
    fmu_path = Path(given)
    if not fmu_path.is_file():
        raise ComponentError(f"plant.fmu: fmu={given}: no such FMU file")
    return fmu_path

"""``dc_motor.fmu``: the DC motor FMU (``dc_motor_fmu.py``, exported by pythonfmu) as a component, run by fmpy.

The inputs arrive over delayed edges: the values seen at ``step(t)`` were
applied over ``[t_prev, t)``, so the component sets them on the FMU and
steps it from its previous time to ``t``. Every FMU parameter (``R_ohm``,
``L_H``, ``k_Nm_per_A``, ``J_kgm2``, ``b_Nms_per_rad``, ``max_substep_s``,
the initial state ``current0_A``, ``speed0_rad_s``, ``angle0_rad``) can be
set from the scenario by its FMI name; ``fmu`` names another FMU file with
the same variables (default: the one ``build.py`` builds and caches).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from fmpy import calloc, extract, free, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

from cosim import Component, ComponentError, Port

from .build import SOURCE, FmuBuildError, ensure_fmu

#: the FMU's input and state (output) variables, in the order of the ports
INPUTS = ("voltage_V", "load_torque_Nm")
STATE = ("current_A", "speed_rad_s", "angle_rad")
#: fmi2Error: a message the FMU logs at this status or above fails the call that logged it
ERROR_STATUS = 3


class MotorFmu(Component):
    """Permanent-magnet DC motor: armature circuit, rotor inertia, viscous friction, load torque."""

    inputs = (
        Port("voltage_V", (), "V", "armature voltage applied over the last step"),
        Port("load_torque_Nm", (), "N m", "load torque on the shaft over the last step (against positive speed)"),
    )
    outputs = (
        Port("current_A", (), "A", "armature current"),
        Port("speed_rad_s", (), "rad/s", "rotor speed"),
        Port("angle_rad", (), "rad", "rotor angle, not wrapped"),
        Port("state", (3,), "A, rad/s, rad", "(current_A, speed_rad_s, angle_rad) in one vector"),
    )

    def __init__(self) -> None:
        self._fmu: FMU2Slave | None = None
        self._unzip_dir: str | None = None
        self._log: list[tuple[int, str]] = []  # (FMI status, message) the FMU logged
        self._t = 0.0
        self._last: dict[str, np.ndarray] = {}

    @classmethod
    def prepare(cls, params):
        """Build the FMU (unless ``fmu`` names one) once, before runs fan out over processes."""
        if params.get("fmu") is None:
            _built_fmu()

    @classmethod
    def artifacts(cls, params):
        """The file the motor depends on besides code: the FMU given as ``fmu``, else the model's
        source, which the FMU is built from (pythonfmu stamps each build with a new GUID and time,
        so two builds of the same source differ in their bytes)."""
        return [Path(params["fmu"])] if params.get("fmu") is not None else [SOURCE]

    def setup(self, params, rng):
        params = {k: v for k, v in params.items() if k != "dt"}
        given = params.pop("fmu", None)
        fmu_path = _built_fmu() if given is None else Path(given)
        if not fmu_path.is_file():
            raise ComponentError(f"fmu={given}: no such FMU file")
        md = read_model_description(str(fmu_path))
        refs = {v.name: v.valueReference for v in md.modelVariables}
        settable = [v.name for v in md.modelVariables if v.causality == "parameter"]
        unknown = sorted(set(params) - set(settable))
        if unknown:
            raise ComponentError(f"unknown parameter(s) {', '.join(unknown)}; valid: fmu, {', '.join(settable)}")
        for name, value in params.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ComponentError(f"parameter {name}={value!r}: expected a number")
        missing = [n for n in (*INPUTS, *STATE) if n not in refs]
        if missing:
            raise ComponentError(f"{fmu_path} has no variable(s) {', '.join(missing)}")
        self._in_refs = [refs[n] for n in INPUTS]
        self._out_refs = [refs[n] for n in STATE]
        self._unzip_dir = extract(str(fmu_path))
        self._fmu = FMU2Slave(guid=md.guid, unzipDirectory=self._unzip_dir,
                              modelIdentifier=md.coSimulation.modelIdentifier, instanceName="dc_motor")
        self._fmu.instantiate(callbacks=self._callbacks(), loggingOn=True)
        self._call("initialisation", self._initialise, {refs[n]: float(v) for n, v in params.items()})
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

    def _initialise(self, values: dict[int, float]) -> None:
        self._fmu.setupExperiment(startTime=0.0)
        if values:
            self._fmu.setReal(list(values), list(values.values()))
        self._fmu.enterInitializationMode()
        self._fmu.exitInitializationMode()

    def _call(self, what: str, fn, *args) -> None:
        """An FMU call; an error status, or an error the FMU logged meanwhile, becomes a
        ComponentError with the messages the FMU logged."""
        n_log = len(self._log)
        try:
            fn(*args)
            failed = None
        except FMICallException as exc:
            failed = exc
        logged = self._log[n_log:]
        if failed or any(status >= ERROR_STATUS for status, _ in logged):
            raise ComponentError(f"{what} failed: {'; '.join(m for _, m in logged) or failed}")

    def _read_outputs(self) -> dict[str, np.ndarray]:
        state = np.array(self._fmu.getReal(self._out_refs))
        return {**{name: state[i] for i, name in enumerate(STATE)}, "state": state}

    def initial_outputs(self):
        return dict(self._last)

    def step(self, t, inputs):
        t = float(t)
        if t > self._t:
            values = [float(inputs[name]) for name in INPUTS]
            self._call(f"step to t={t:g} s", self._do_step, values, t)
            self._t = t
            self._last = self._read_outputs()
        elif t < self._t:
            raise ComponentError(f"time went backwards ({t:g} s after {self._t:g} s)")
        return self._last

    def _do_step(self, values: list[float], t: float) -> None:
        self._fmu.setReal(self._in_refs, values)
        self._fmu.doStep(currentCommunicationPoint=self._t, communicationStepSize=t - self._t)

    def close(self):
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


def _built_fmu() -> Path:
    """The FMU of the current model source (see ``build.py``); a failed build is a ComponentError."""
    try:
        return ensure_fmu()
    except FmuBuildError as exc:
        raise ComponentError(str(exc)) from None

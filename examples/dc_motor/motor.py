"""``dc_motor.fmu``: the DC motor FMU (``dc_motor_fmu.py``, exported by pythonfmu) as a component.

A :class:`cosim.components.FmuComponent` (fmpy): the inputs arrive over
delayed edges (the values seen at ``step(t)`` were applied over
``[t_prev, t)``); a call during which the model logs an error fails with the
model's message. Every FMU parameter (``R_ohm``,
``L_H``, ``k_Nm_per_A``, ``J_kgm2``, ``b_Nms_per_rad``, ``max_substep_s``,
the initial state ``current0_A``, ``speed0_rad_s``, ``angle0_rad``) can be
set from the scenario by its FMI name; ``fmu`` names another FMU file with
the same variables (default: the one ``build.py`` builds and caches).
"""

from __future__ import annotations

from pathlib import Path

from cosim import ComponentError, FmuComponent, Port

from .build import SOURCE, FmuBuildError, ensure_fmu

#: the FMU's state variables, in the order of the ``state`` port
STATE = ("current_A", "speed_rad_s", "angle_rad")


class MotorFmu(FmuComponent):
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

    input_variables = {"voltage_V": ("voltage_V",), "load_torque_Nm": ("load_torque_Nm",)}
    output_variables = {**{name: (name,) for name in STATE}, "state": STATE}
    instance_name = "dc_motor"

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

    @classmethod
    def fmu_file(cls, params):
        return _built_fmu() if params.get("fmu") is None else super().fmu_file(params)


def _built_fmu() -> Path:
    """The FMU of the current model source (see ``build.py``); a failed build is a ComponentError."""
    try:
        return ensure_fmu()
    except FmuBuildError as exc:
        raise ComponentError(str(exc)) from None

"""``plant.fmu``: the swimmer plant FMU as a cosim component (fmpy, FMI 2.0 CS).

A :class:`cosim.FmuComponent`: inputs arrive over a delayed edge
from the coil driver (the values seen at ``step(t)`` were applied over
``[t_prev, t)``), and every FMU parameter can be set from the scenario by its
FMI name (see ``cosim_plugins/plant/swimmer_plant/README.md``). The project's FMU is built on
first use; ``fmu`` names a user's.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

from cosim import FmuComponent, Port


class FmuPlant(FmuComponent):
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

    input_variables = {
        "coil_voltage_amp": tuple(f"V_amp_{i}" for i in range(1, 7)),
        "coil_voltage_phase": tuple(f"V_phase_{i}" for i in range(1, 7)),
        "drive_freq": ("freq",),
    }
    output_variables = {
        "position": ("p_x", "p_y", "p_z"),
        "velocity": ("v_x", "v_y", "v_z"),
        "axis": ("axis_x", "axis_y", "axis_z"),
        "spin_rate": ("spin_rate",),
        "coil_current_amp": tuple(f"I_amp_{i}" for i in range(1, 7)),
        "field": ("B_x", "B_y", "B_z"),
    }
    instance_name = "plant"
    logging_on = False

    @classmethod
    def prepare(cls, params: Mapping[str, Any]) -> None:
        """Build the project's FMU now if it is missing or stale (a user's FMU is used as it is)."""
        cls.fmu_file(params)

    @classmethod
    def model_description_file(cls, params: Mapping[str, Any]) -> Path:
        """The project's ``modelDescription.xml`` (checking a scenario builds nothing), or a user's FMU."""
        from cosim_plugins.plant.build import SOURCE_DIR

        return SOURCE_DIR / "modelDescription.xml" if params.get("fmu") is None else cls.fmu_file(params)

    @classmethod
    def fmu_file(cls, params: Mapping[str, Any]) -> Path:
        """``params["fmu"]`` (a user's, used as it is) or the project's, built on first use."""
        # imported here so that `python -m cosim_plugins.plant.build` does not
        # import its own module twice (the package imports this file)
        from cosim_plugins.plant.build import ensure_fmu

        return ensure_fmu() if params.get("fmu") is None else super().fmu_file(params)


_AXES = "xyz"


class FmuForcedPlant(FmuPlant):
    """``plant.fmu_forced``: the same FMU with its external force input wired as ports.

    The force (N, tank frame) is added to the swimmer's forces inside the FMU's integration:
    ``external_force`` held over the step, plus ``external_force_dp`` (p - p_0) +
    ``external_force_dv`` (v - v_0), p_0 and v_0 the state at the step's start, evaluated at every
    internal step. ``twin.effect`` (``cosim_plugins/twin``) computes these from effects; wire them with
    ``delay: 1`` (the force computed at t acts over [t, t + dt)). Zero inputs give ``plant.fmu``'s run.
    """

    inputs = (
        *FmuPlant.inputs,
        Port("external_force", (3,), "N", "force added to the swimmer, tank frame"),
        Port("external_force_dp", (9,), "N/m", "its derivative dF_a/dp_b, row-major (a, b)"),
        Port("external_force_dv", (9,), "N s/m", "its derivative dF_a/dv_b, row-major (a, b)"),
    )
    input_variables = {
        **FmuPlant.input_variables,
        "external_force": tuple(f"F_ext_{a}" for a in _AXES),
        "external_force_dp": tuple(f"F_ext_dp_{a}{b}" for a in _AXES for b in _AXES),
        "external_force_dv": tuple(f"F_ext_dv_{a}{b}" for a in _AXES for b in _AXES),
    }

"""The twin's calibrated parameters: what each is, its unit, and how it sets the plant FMU.

A knob is one scalar the calibration fits (:mod:`.calibrate`): an FMU parameter (propulsion,
drags, net weight, heading response, gradient force), the camera's latency, or a force
effect's parameter (injected through the FMU's external force input). The optimiser works
on ``x``: log(value) for a positive knob, value / scale otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cosim_plugins.twin.units import HZ_PER_RAD_S, N_PER_UN, N_PER_UN_PER_MM, fmu_defaults

FIELD_T = 3e-3  # the coil driver's default rotating field [T] (coil_driver field_mT = 3)


@dataclass(frozen=True)
class Knob:
    """name; unit; ``where``: "fmu", "camera" or "effect"; log: fitted as log(value) (value > 0), else as
    value / scale; lo, hi: bounds of the value; doc: what the logs see of it."""

    name: str
    unit: str
    where: str
    log: bool
    lo: float
    hi: float
    scale: float
    doc: str

    def to_x(self, value: float) -> float:
        return math.log(value) if self.log else value / self.scale

    def from_x(self, x: float) -> float:
        return math.exp(x) if self.log else x * self.scale

    def x_bounds(self) -> tuple[float, float]:
        if self.log:
            return math.log(self.lo), math.log(self.hi)
        return self.lo / self.scale, self.hi / self.scale


PLANT_KNOBS = (
    Knob("prop_coeff", "N s/rad", "fmu", True, 1e-10, 1e-5, 1.0, "propulsion per spin rate (speed per Hz with "
         "the drag)"),
    Knob("drag_axial", "N s/m", "fmu", True, 1e-7, 1e-2, 1.0, "linear drag along the long axis (velocity time "
         "constant with the mass)"),
    Knob("anisotropy_ratio", "1", "fmu", True, 0.3, 10.0, 1.0, "broadside / axial drag (the drag's rise with the "
         "angle of attack)"),
    Knob("net_weight", "N", "fmu", False, -1e-5, 1e-5, 1e-7, "weight less buoyancy, downwards (sets the FMU's "
         "volume: the sinking speed)"),
    Knob("rot_drag_perp", "N m s", "fmu", True, 1e-11, 1e-5, 1.0, "rotational drag across the axis (the heading's "
         "response to a turning field: time constant rot_drag_perp / (moment B))"),
    Knob("gradient_force_scale", "1", "fmu", False, 0.0, 20.0, 0.5, "the coils' (m . grad) B force, x the FMU's "
         "own law"),
)
LATENCY = Knob("latency_s", "s", "camera", False, 0.0, 0.3, 0.02, "camera latency: a frame reports the plant "
               "this long before it is logged")


def effect_knobs(effects) -> list[Knob]:
    """A knob per parameter of each force effect (its bounds; the optimiser's scale is the effect's)."""
    out = []
    for e in effects:
        for p in e.params:
            lo, hi = (p.lo if math.isfinite(p.lo) else -1e6), (p.hi if math.isfinite(p.hi) else 1e6)
            out.append(Knob(f"{e.name}.{p.name}", p.unit, "effect", False, lo, hi, p.typical(), e.summary()))
    return out


def fmu_values(values: dict) -> dict:
    """The FMU parameters (by FMI name) the plant knobs in ``values`` set (net_weight sets volume)."""
    d = fmu_defaults()
    out = {k: float(v) for k, v in values.items() if k in d}
    if "net_weight" in values:
        out["volume"] = (d["mass"] - float(values["net_weight"]) / d["g"]) / d["rho_fluid"]
    return out


def plant_from_host(host: dict) -> dict:
    """Start values of the plant knobs from a physical model's k, Cd1, Fvs (uN, mm, s, Hz).

    prop_coeff = k / 2 pi (a thrust k u [uN] at u = omega / 2 pi), drag_axial = Cd1, net weight = -Fvs,
    anisotropy_ratio = 1 (an isotropic Cd1 drag: the paper's Cd0 sin(alpha) drag is the effect
    ``twin_paper_forces``, :mod:`.host_forces`, which starts at the host's Cd0); the heading
    response keeps the FMU's default and the gradient force starts at 0 (the host model has neither).
    """
    d = fmu_defaults()
    cd1 = max(float(host["Cd1"]), 1e-6)
    k = abs(float(host["k"]))
    return {
        "prop_coeff": float(np.clip(k * N_PER_UN * HZ_PER_RAD_S, 1e-10, 1e-5)),
        "drag_axial": float(np.clip(cd1 * N_PER_UN_PER_MM, 1e-7, 1e-2)),
        "anisotropy_ratio": 1.0,
        "net_weight": float(np.clip(-float(host["Fvs"]) * N_PER_UN, -1e-5, 1e-5)),
        "rot_drag_perp": d["rot_drag_perp"],
        "gradient_force_scale": 0.0,
    }


def plant_defaults() -> dict:
    """The plant knobs at the FMU's defaults (the uncalibrated twin)."""
    d = fmu_defaults()
    return {"prop_coeff": d["prop_coeff"], "drag_axial": d["drag_axial"], "anisotropy_ratio": d["anisotropy_ratio"],
            "net_weight": (d["mass"] - d["rho_fluid"] * d["volume"]) * d["g"], "rot_drag_perp": d["rot_drag_perp"],
            "gradient_force_scale": d["gradient_force_scale"]}


def heading_time_constant_s(rot_drag_perp: float) -> float:
    """The heading's time constant rot_drag_perp / (moment B) [s] at the driver's default field."""
    return rot_drag_perp / (fmu_defaults()["moment"] * FIELD_T)


#: FMU parameters open-loop position logs cannot determine (held at the FMU's values), and why.
NOT_DETERMINED = {
    "mass": "only mass / drag (the velocity time constant) shows in positions: the mass is held, the drag fitted",
    "moment": "only rot_drag_perp / moment shows (the heading's time constant): the moment is held",
    "rot_drag_axial": "sets the step-out frequency, which logs below step-out never reach (fit the step_out "
                      "effect when they do)",
    "R_coil, L_coil, C_coil": "the coils' lag is fixed by the coil circuit; the logs hold commands, not currents",
    "added_mass_axial, added_mass_perp": "added mass changes the time constants as the drag does: not told apart",
    "quad_drag_cd": "off in the twin; a quadratic drag is the effect quadratic_drag (--effects)",
}

"""Inverse magnetics: rotation vector omega -> coil voltage phasors.

omega [rad/s] -> a field of ``field_mT`` rotating about omega at
``|omega| / 2 pi`` Hz -> least-norm coil current phasors from the centre
field matrix -> voltage phasors through each coil's series RLC impedance ->
scaled down together if any exceeds the supply limit (the field keeps its
direction and loses magnitude).

The field stays continuous when the command changes: the plant's coils are
driven as ``cos(2 pi f t + phase)`` in absolute time, so the driver starts
each new command's rotation where the field points now (projected onto the
new rotation plane) and offsets every phase by ``-2 pi f t``. Without that, a
frequency change of df would jump the field's angle by ``2 pi df t`` and the
magnet would lose step.

Safety: a non-finite omega, or one above ``f_limit_hz``, never reaches the
coils: the driver outputs zero field and raises a fault that stops the run
cleanly (recorded in the summary).
"""

from __future__ import annotations

import math

import numpy as np

from cosim import Component, ComponentError, Port
from cosim.params import Param, read_params
from cosim_plugins.coil_driver.actuation import (
    centre_matrix,
    field_direction,
    impedance_ohm,
    loop_field_on_axis_t_per_a,
    plane_start,
    rotating_field_phasor,
)
from cosim_plugins.vec3 import all_finite, norm

PARAMS = {
    "field_mT": Param(3.0, "rotating field amplitude at the swimmer [mT]", 0.0, 50.0),
    "turns": Param(795.0, "turns per coil", 1.0, 1e5),
    "r_inner_mm": Param(180.0, "coil inner radius [mm]", 1.0, 1e4),
    "r_outer_mm": Param(215.0, "coil outer radius [mm]", 1.0, 1e4),
    "z_near_mm": Param(150.0, "distance from the centre to the coil's inner face [mm]", 0.0, 1e4),
    "thickness_mm": Param(40.0, "axial winding thickness [mm]", 0.0, 1e4),
    "r_ohm": Param(12.9, "coil resistance [ohm]", 0.0, 1e4),
    "l_h": Param(0.411, "coil inductance [H]", 0.0, 100.0),
    "c_f": Param(430e-6, "series capacitor [F]", 1e-12, 100.0),
    "v_max": Param(40.0, "supply limit per coil [V] (two +-20 V supplies in series)", 0.0, 1e4),
    "f_min_hz": Param(0.05, "below this spin frequency the field is off [Hz]", 0.0, 100.0),
    "f_limit_hz": Param(60.0, "a command above this spin frequency is a fault [Hz]", 0.0, 1e4),
    "backend": Param("fmu", "where the voltages go: 'fmu' (the plant's coil inputs)"),
}
BACKENDS = ("fmu",)


class InverseMagnetics(Component):
    """omega -> rotating field -> least-norm coil currents -> RLC voltages, clipped to the supply."""

    inputs = (Port("omega", (3,), "rad/s", "commanded rotation vector"),)
    outputs = (
        Port("coil_voltage_amp", (6,), "V", "voltage amplitude per coil"),
        Port("coil_voltage_phase", (6,), "rad", "voltage phase per coil"),
        Port("drive_freq", (), "Hz", "drive frequency"),
    )

    def setup(self, params, rng):
        p = self.p = read_params(params, PARAMS)
        if p["r_outer_mm"] <= p["r_inner_mm"]:
            raise ComponentError("r_outer_mm must exceed r_inner_mm")
        if p["backend"] not in BACKENDS:
            raise ComponentError(f"backend {p['backend']!r} unknown; known: {', '.join(BACKENDS)}")
        g = loop_field_on_axis_t_per_a(p["turns"], p["r_inner_mm"] * 1e-3, p["r_outer_mm"] * 1e-3,
                                       p["z_near_mm"] * 1e-3, (p["z_near_mm"] + p["thickness_mm"]) * 1e-3)
        # (6, 3) A/T, complex like the field phasors it multiplies (numpy would cast it every step)
        self.m_pinv = np.linalg.pinv(centre_matrix(g)).astype(complex)
        self.zero = {"coil_voltage_amp": np.zeros(6), "coil_voltage_phase": np.zeros(6), "drive_freq": np.array(0.0)}
        self.rotation = None  # (n, e1, f_hz, t0_s) of the field being driven: angle 2 pi f (t - t0)

    def initial_outputs(self):
        return self.zero

    def step(self, t, inputs):
        omega = inputs["omega"]
        f = norm(omega) / (2 * math.pi)
        if not all_finite(omega) or f > self.p["f_limit_hz"]:
            self.fault = f"unsafe command omega = {omega} rad/s (limit {self.p['f_limit_hz']:g} Hz): field off"
            self.rotation = None
            return self.zero
        if f < self.p["f_min_hz"] or self.p["field_mT"] == 0.0:
            self.rotation = None
            return self.zero
        n = omega / (2 * math.pi * f)
        now = None
        if self.rotation is not None:  # where the field points now, continued in the new plane
            n0, e10, f0, t0 = self.rotation
            now = field_direction(n0, e10, 2 * math.pi * f0 * (t - t0))
        e1 = plane_start(n, now)
        self.rotation = (n, e1, f, t)
        field = rotating_field_phasor(n, e1, self.p["field_mT"] * 1e-3)
        current = self.m_pinv.dot(field)  # (6,) complex A
        volts = current * impedance_ohm(f, self.p["r_ohm"], self.p["l_h"], self.p["c_f"])
        amp = np.abs(volts)
        peak = amp.max()
        if peak > self.p["v_max"]:
            volts = volts * (self.p["v_max"] / peak)
            amp = np.abs(volts)
        phase = np.angle(volts) - (2 * math.pi * f * t) % (2 * math.pi)  # angle 0 at t, in absolute time
        return {"coil_voltage_amp": amp, "coil_voltage_phase": phase, "drive_freq": np.array(f)}

"""PI path following on top of pure pursuit.

The desired swimming velocity points at the pure-pursuit target with the
cruise speed (the proportional part: the target's offset steers the heading),
plus an integral of the cross-track error that cancels slow biases such as
sinking. The rotation vector omega [rad/s] points along the desired
velocity (the spiral swims along +omega) with ``|omega| = 2 pi f``, where
``f = |v_des| / speed_per_hz`` is clipped to ``[0, f_max_hz]``.
"""

from __future__ import annotations

import math

import numpy as np

from cosim.contract.params import Param, read_params
from cosim_plugins.controllers.common import PathController, SolveTimer
from cosim_plugins.controllers.pure_pursuit import PurePursuit
from cosim_plugins.vec3 import Vec3, add, all_finite, div, length, scale, sub

PARAMS = {
    "speed_mm_s": Param(20.0, "cruise speed [mm/s]", 0.0, 200.0),
    "lookahead_mm": Param(9.0, "pure-pursuit look-ahead distance [mm]", 0.1, 100.0),
    "lookahead_gain_s": Param(0.001, "look-ahead growth with speed [s]", 0.0, 10.0),
    "kp": Param(1.0, "cross-track proportional gain [1/s]", 0.0, 100.0),
    "ki": Param(0.5, "cross-track integral gain [1/s^2]", 0.0, 100.0),
    "i_max_mm_s": Param(10.0, "integral term limit [mm/s]", 0.0, 200.0),
    "speed_per_hz_mm_s": Param(2.5, "swimmer speed per Hz of spin [mm/s/Hz]", 1e-3, 100.0),
    "f_max_hz": Param(20.0, "largest commanded spin frequency [Hz]", 0.0, 200.0),
}


class PIController(PathController):
    """Pure pursuit (look-ahead 9 mm) + PI on the cross-track error, 3D."""

    params_spec = PARAMS

    def setup(self, params, rng):
        p = read_params(params, PARAMS)
        self.dt = params["dt"]
        self.pursuit = PurePursuit(params["path"], p["lookahead_mm"] * 1e-3, p["lookahead_gain_s"])
        self.speed = p["speed_mm_s"] * 1e-3
        self.kp, self.ki = p["kp"], p["ki"]
        self.i_max = p["i_max_mm_s"] * 1e-3
        self.m_per_hz = p["speed_per_hz_mm_s"] * 1e-3
        self.f_max = p["f_max_hz"]
        self.integral: Vec3 = (0.0, 0.0, 0.0)  # [m/s]

    def step(self, t, inputs):
        with SolveTimer() as timer:
            omega = self._control(t, inputs["position"], inputs["velocity"])
        return {"omega": omega, "solve_time": timer.elapsed}

    def _control(self, t, pos, vel):
        if not all_finite(pos):
            return np.zeros(3)
        target, closest, at_end = self.pursuit.reference(pos, vel, t)
        pos_m = tuple(pos.tolist())
        to_target = sub(tuple(target.tolist()), pos_m)
        dist = length(to_target)
        speed = self.speed * (min(dist / self.pursuit.lookahead_m, 1.0) if at_end else 1.0)
        cross_m = sub(tuple(closest.tolist()), pos_m)
        self.integral = _clip_norm(add(self.integral, scale(scale(cross_m, self.ki), self.dt)), self.i_max)
        v_des = add(add(div(scale(to_target, speed), max(dist, 1e-9)), scale(cross_m, self.kp)), self.integral)
        return velocity_to_omega(v_des, self.m_per_hz, self.f_max)


def _clip_norm(v: Vec3, limit: float) -> Vec3:
    n = length(v)
    return v if n <= limit else scale(v, limit / n)


def velocity_to_omega(v_des_m_s: Vec3, m_per_hz: float, f_max_hz: float) -> np.ndarray:
    """Rotation vector (3,) [rad/s] that swims at ``v_des`` [m/s]: along it, 2 pi f with f = |v| / m_per_hz."""
    speed = length(v_des_m_s)
    if speed < 1e-12:
        return np.zeros(3)
    f = min(speed / m_per_hz, f_max_hz)
    return np.array(scale(div(v_des_m_s, speed), 2 * math.pi * f))

"""``dc_motor.pi_speed``: a discrete PI speed controller producing the armature voltage, with saturation.

At each tick ``t`` it reads the measured speed and the setpoint at ``t`` and
puts out the voltage the motor applies over ``[t, t + dt)`` (the motor's
input edge is delayed). The integral term is held while the output is
saturated and the error would drive it further (conditional integration,
against wind-up). The defaults cancel the default motor's mechanical pole
(``kp / ki`` = its 16 ms time constant) and give a closed loop of about
20 ms time constant below saturation.
"""

from __future__ import annotations

import numpy as np

from cosim import Component, Param, Port, read_params

PARAMS = {
    "kp_V_s_per_rad": Param(0.04, "proportional gain [V/(rad/s)]", 0.0),
    "ki_V_per_rad": Param(2.5, "integral gain [V/rad] (V per rad/s of error per second)", 0.0),
    "voltage_max_V": Param(24.0, "supply limit: the output is clipped to +-this [V]", 0.0),
}


class SpeedPi(Component):
    """PI from the speed error to the armature voltage, clipped to the supply, with anti-wind-up."""

    inputs = (
        Port("speed_rad_s", (), "rad/s", "measured rotor speed"),
        Port("setpoint_rad_s", (), "rad/s", "speed setpoint"),
    )
    outputs = (
        Port("voltage_V", (), "V", "armature voltage to apply over [t, t + dt)"),
        Port("speed_error_rad_s", (), "rad/s", "setpoint minus measured speed"),
        Port("command", (3,), "V, rad/s, V",
             "(voltage_V applied, setpoint_rad_s, the PI's demand before clipping [V])"),
    )

    @classmethod
    def validate_params(cls, params):
        read_params(params, PARAMS)

    def setup(self, params, rng):
        p = read_params(params, PARAMS)
        self.kp, self.ki, self.v_max = p["kp_V_s_per_rad"], p["ki_V_per_rad"], p["voltage_max_V"]
        self.dt = float(params["dt"])
        self.integral_V = 0.0

    def initial_outputs(self):
        return {"voltage_V": 0.0, "speed_error_rad_s": 0.0, "command": np.zeros(3)}

    def step(self, t, inputs):
        setpoint = float(inputs["setpoint_rad_s"])
        error = setpoint - float(inputs["speed_rad_s"])
        integral = self.integral_V + self.ki * error * self.dt
        demand = self.kp * error + integral
        voltage = min(max(demand, -self.v_max), self.v_max)
        if voltage == demand or np.sign(error) != np.sign(demand):  # not winding up against the limit
            self.integral_V = integral
        return {"voltage_V": voltage, "speed_error_rad_s": error,
                "command": np.array([voltage, setpoint, demand])}

    @classmethod
    def summary_figures(cls, outputs):
        """``speed_error_rad_s`` {rms, max_abs} and ``saturated_fraction`` over the ticks run (none: no figure)."""
        error, command = outputs["speed_error_rad_s"], outputs["command"]
        ran = np.isfinite(error)
        if not ran.any():
            return {}
        error, command = error[ran], command[ran]
        return {"speed_error_rad_s": {"rms": float(np.sqrt(np.mean(error**2))),
                                      "max_abs": float(np.max(np.abs(error)))},
                "saturated_fraction": float(np.mean(command[:, 0] != command[:, 2]))}

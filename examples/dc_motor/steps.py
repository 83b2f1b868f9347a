"""``dc_motor.steps``: piecewise-constant profiles of the speed setpoint and of the load torque.

Each profile is a list of ``[t_s, value]`` pairs with increasing times: the
value holds from its time until the next one's; before the first it is 0.
"""

from __future__ import annotations

import numpy as np

from cosim import Component, ComponentError, Param, Port, read_params

PARAMS = {
    "setpoint_rad_s": Param([], "speed setpoint profile: [[t_s, rad/s], ...]"),
    "load_torque_Nm": Param([], "load torque profile: [[t_s, N m], ...]"),
}


def read_profile(name: str, value) -> tuple[np.ndarray, np.ndarray]:
    """``[[t_s, value], ...]`` -> (times (n,) [s], values (n,)); raises :class:`ComponentError`."""
    try:
        table = np.array(value, dtype=float).reshape(-1, 2) if len(value) == 0 else np.array(value, dtype=float)
    except (TypeError, ValueError):
        table = None
    if table is None or table.ndim != 2 or table.shape[1] != 2:
        raise ComponentError(f"parameter {name}: expected a list of [t_s, value] pairs, got {value!r}")
    if not np.all(np.isfinite(table)) or np.any(np.diff(table[:, 0]) <= 0):
        raise ComponentError(f"parameter {name}: times must be finite and increasing, got {value!r}")
    return table[:, 0], table[:, 1]


class Steps(Component):
    """Outputs each profile's value at the tick's time."""

    outputs = (
        Port("setpoint_rad_s", (), "rad/s", "speed setpoint"),
        Port("load_torque_Nm", (), "N m", "load torque on the motor's shaft"),
    )

    @classmethod
    def validate_params(cls, params):
        for name, value in read_params(params, PARAMS).items():
            read_profile(name, value)

    def setup(self, params, rng):
        self.profiles = {name: read_profile(name, value) for name, value in read_params(params, PARAMS).items()}

    def initial_outputs(self):
        return self.step(0.0, {})

    def step(self, t, inputs):
        out = {}
        for name, (times, values) in self.profiles.items():
            k = np.searchsorted(times, t + 1e-9, side="right") - 1  # a step at t_s holds from the tick at t_s
            out[name] = float(values[k]) if k >= 0 else 0.0
        return out

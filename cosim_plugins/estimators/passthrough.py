"""The no-model estimator: hold the last measurement."""

from __future__ import annotations

import numpy as np

from cosim import Component, Port
from cosim.contract.params import read_params
from cosim_plugins.vec3 import all_finite


class Passthrough(Component):
    """Last measurement held; velocity from the last two frames (zero until there are two)."""

    inputs = (Port("position", (3,), "m", "measurement; NaN when none arrived"),)
    outputs = (
        Port("position", (3,), "m", "estimated position (NaN before the first frame)"),
        Port("velocity", (3,), "m/s", "estimated velocity"),
    )
    params_spec: dict = {}  # none

    def setup(self, params, rng):
        read_params(params, {})
        self.position = np.full(3, np.nan)
        self.velocity = np.zeros(3)
        self.t_last = None

    def initial_outputs(self):
        return {"position": self.position, "velocity": self.velocity}

    def step(self, t, inputs):
        z = inputs["position"]
        if all_finite(z):
            if self.t_last is not None and t > self.t_last:
                self.velocity = (z - self.position) / (t - self.t_last)
            self.position, self.t_last = z, t
        return {"position": self.position, "velocity": self.velocity}

"""A command shaper for identification runs: the controller steers, a schedule sets the spin rate.

It sits between the controller and the coil driver and replaces the
magnitude of the commanded rotation vector with a piecewise-constant spin
frequency, redrawn uniformly in [f_low_hz, f_high_hz] every ``hold_s``
seconds, keeping the controller's direction. Speeds (and spin rates) then
vary within one log, which is what separates a quadratic from a linear drag
or shows a step-out frequency, while the path is still followed.
Load it from a scenario with ``plugins: [excitation.py]`` and record
``shaper.omega`` as the log's command (see excited.yaml).
"""

import numpy as np

from cosim import Component, Port, hookimpl
from cosim.contract.params import Param, read_params

PARAMS = {
    "f_low_hz": Param(5.0, "lowest scheduled spin frequency [Hz]", 0.0, 100.0),
    "f_high_hz": Param(15.0, "highest scheduled spin frequency [Hz]", 0.0, 100.0),
    "hold_s": Param(2.0, "time between changes of the spin frequency [s]", 0.02, 1e4),
}


class SpeedSchedule(Component):
    """omega_out = f(t) 2 pi omega_in / |omega_in|, f piecewise constant (seeded draws)."""

    inputs = (Port("omega", (3,), "rad/s", "the controller's rotation vector"),)
    outputs = (Port("omega", (3,), "rad/s", "same direction, scheduled magnitude"),)
    params_spec = PARAMS

    def setup(self, params, rng):
        self.p = read_params(params, PARAMS)
        self.rng = rng
        self.next_change = 0.0
        self.f = self.p["f_low_hz"]

    def initial_outputs(self):
        return {"omega": np.zeros(3)}

    def step(self, t, inputs):
        if t >= self.next_change - 1e-9:
            self.f = float(self.rng.uniform(self.p["f_low_hz"], self.p["f_high_hz"]))
            self.next_change += self.p["hold_s"]
        w = np.asarray(inputs["omega"], dtype=float)
        n = float(np.linalg.norm(w))
        if not np.isfinite(n) or n < 1e-9:
            return {"omega": np.zeros(3)}
        return {"omega": w / n * (2 * np.pi * self.f)}


@hookimpl
def cosim_register_components(register):
    register("diagnose.speed_schedule", SpeedSchedule)

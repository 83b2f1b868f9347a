"""An example plugin: an estimator that smooths camera frames with an exponential moving average.

Load it from a scenario with ``plugins: [ema_estimator.py]`` (see
``ema_racetrack.yaml``), or ship it in a package with an entry point in the
``cosim`` group. docs/framework/writing-a-plugin.md walks through it.
"""

import numpy as np

from cosim import Component, Param, Port, hookimpl, read_params


class EmaEstimator(Component):
    """Exponential moving average of the measured position; velocity from successive estimates."""

    inputs = (Port("position", (3,), "m", "measurement; NaN when no frame arrived"),)
    outputs = (Port("position", (3,), "m"), Port("velocity", (3,), "m/s"))
    #: what `cosim validate` checks (names, types, bounds) before a run starts
    params_spec = {"alpha": Param(0.5, "weight of a new frame", 0.0, 1.0)}

    def setup(self, params, rng):
        self.alpha = read_params(params, self.params_spec)["alpha"]
        self.position, self.velocity, self.t_last = np.full(3, np.nan), np.zeros(3), None

    def initial_outputs(self):
        return {"position": self.position, "velocity": self.velocity}

    def step(self, t, inputs):
        z = inputs["position"]
        if np.all(np.isfinite(z)):
            if self.t_last is None:
                self.position = z
            else:
                new = self.alpha * z + (1 - self.alpha) * self.position
                self.velocity = (new - self.position) / (t - self.t_last)
                self.position = new
            self.t_last = t
        return {"position": self.position, "velocity": self.velocity}


@hookimpl
def cosim_register_components(register):
    register("estimator.ema", EmaEstimator)

"""A throwaway controller for the safety test: pure pursuit PI until ``nan_at_s``, then NaN.

Registered through a scenario's ``plugins:`` field (see data/nan_racetrack.yaml),
exactly as a user's own controller file would be.
"""

from __future__ import annotations

import numpy as np

from cosim import hookimpl
from cosim.contract.params import Param
from cosim_plugins.controllers.pi import PIController


class NaNController(PIController):
    """The PI controller, except that from ``nan_at_s`` on it outputs ``value`` (NaN by default)."""

    params_spec = {**PIController.params_spec, "nan_at_s": Param(1.0, "time of the first bad command [s]"),
                   "value": Param("nan", "the bad command's every component [rad/s]: a number, nan or inf")}

    def setup(self, params, rng):
        params = dict(params)
        self.nan_at = float(params.pop("nan_at_s", 1.0))
        self.value = float(params.pop("value", np.nan))
        super().setup(params, rng)

    def step(self, t, inputs):
        out = super().step(t, inputs)
        if t >= self.nan_at - 1e-9:
            out["omega"] = np.full(3, self.value)
        return out


@hookimpl
def cosim_register_components(register):
    register("test.nan_controller", NaNController)

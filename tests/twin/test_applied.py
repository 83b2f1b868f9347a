"""The twin's applied effects: the forces the plant FMU is given are the diagnosis model's laws."""

from __future__ import annotations

import numpy as np

from cosim_plugins.identify.effect import resolve
from cosim_plugins.models.physical import forces
from cosim_plugins.twin.applied import AppliedEffects

HOST = {"k": 0.8, "Cd0": 0.1, "Cd1": 0.2, "Cl0": -0.05, "Fvs": -0.8, "Fmax": 0.3}


def test_the_drags_applied_beside_a_flow_act_on_the_velocity_relative_to_the_water():
    """With a flow and a quadratic drag applied, a swimmer drifting with the water feels no quadratic drag, and the
    applied force is the physical model's force less its host part (the diagnosis's law)."""
    effects = resolve(["background_flow", "quadratic_drag"])
    values = {"background_flow.w_x": 3.0, "background_flow.w_y": -2.0, "quadratic_drag.c": 0.01}
    applied = AppliedEffects(effects, values, HOST)
    flow_only = AppliedEffects(effects[:1], {k: v for k, v in values.items() if k.startswith("background")}, HOST)
    rng = np.random.default_rng(0)
    p, u = rng.uniform(-40, 40, (6, 3)), rng.uniform(-10, 10, (6, 3))
    drift = np.tile([3.0, -2.0, 0.0], (6, 1))
    np.testing.assert_allclose(applied.force_mm(p, drift, u), flow_only.force_mm(p, drift, u), rtol=1e-12)
    v = rng.normal(0, 15, (6, 3))
    named = {**HOST, **values}
    np.testing.assert_allclose(applied.force_mm(p, v, u), forces(p, v, u, named, effects) - forces(p, v, u, HOST),
                               rtol=1e-10, atol=1e-12)

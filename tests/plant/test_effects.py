"""Every optional effect changes the trajectory when on and nothing when off."""

from __future__ import annotations

import numpy as np
import pytest

# switch -> magnitude parameters that only matter while the switch is on
EFFECTS = {
    "background_flow_on": {"flow_x": 0.005, "flow_y": -0.003, "flow_z": 0.002},
    "wall_drag_on": {"wall_drag_gain": 5.0, "wall_drag_length": 0.004},
    "gradient_force_on": {"gradient_force_scale": 3.0},
    "quadratic_drag_on": {"quad_drag_cd": 2.0},
    "anisotropic_drag_on": {"anisotropy_ratio": 3.0},
    "actuation_lag_on": {},
    "heading_dynamics_on": {"rot_drag_perp": 3.0e-8},
    "added_mass_on": {"added_mass_axial": 0.3, "added_mass_perp": 1.2},
}
# near the +x wall and the floor, axis across the drive's rotation axis
BASE = {"p0_x": 0.07, "p0_z": -0.07, "axis0_x": 0.0, "axis0_y": 1.0, "axis0_z": 0.0}


@pytest.fixture(scope="module")
def drive(helpers):
    return helpers.rotating_drive([-1, 0.3, 0.4], 3e-3, 10.0)


@pytest.mark.parametrize("switch", sorted(EFFECTS))
def test_effect_changes_trajectory_only_when_on(sim, drive, switch):
    off = sim.run({**BASE, switch: False}, drive, T=2.0)
    off_with_magnitude = sim.run({**BASE, switch: False, **EFFECTS[switch]}, drive, T=2.0)
    on = sim.run({**BASE, switch: True, **EFFECTS[switch]}, drive, T=2.0)
    for key in off:
        assert np.array_equal(off[key], off_with_magnitude[key]), key
    assert np.linalg.norm(on["position"] - off["position"], axis=1).max() > 2e-4   # > 0.2 mm


def test_background_flow_carries_the_swimmer(sim):
    flow = {"flow_x": 0.004, "flow_y": -0.002, "flow_z": 0.0}
    r = sim.run({"background_flow_on": True, "anisotropic_drag_on": False, **flow}, None, T=2.0)
    assert r["velocity"][-1, 0] == pytest.approx(0.004, rel=0.01)
    assert r["velocity"][-1, 1] == pytest.approx(-0.002, rel=0.01)


def test_quadratic_and_wall_drag_slow_the_sinking(sim):
    plain = sim.run({}, None, T=2.0)["velocity"][-1, 2]
    quad = sim.run({"quadratic_drag_on": True}, None, T=2.0)["velocity"][-1, 2]
    near_floor = {"p0_z": -0.0725, "wall_drag_on": True}
    wall = sim.run(near_floor, None, T=0.2)["velocity"][-1, 2]
    assert plain < quad < 0          # sinking (negative), quadratic drag slows it
    assert plain < wall < 0


def test_gradient_force_pulls_back_along_the_rotation_axis(sim, helpers):
    """Field rotating about x, swimmer 40 mm off centre along x, no thrust: the
    (m.grad)B force points to the centre (|B| grows towards the centre there)."""
    drive = helpers.rotating_drive([1, 0, 0], 3e-3, 10.0)
    params = {"prop_coeff": 0.0, "p0_x": 0.04, "volume": 12.4e-6 / 998.2}
    on = sim.run(params, drive, T=1.0)
    off = sim.run({**params, "gradient_force_on": False}, drive, T=1.0)
    assert on["position"][-1, 0] < 0.04 - 1e-3
    assert off["position"][-1, 0] == pytest.approx(0.04, abs=1e-6)

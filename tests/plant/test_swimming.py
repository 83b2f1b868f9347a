"""Swimming: propulsion vs frequency, step-out, sinking, walls, integrator step."""

from __future__ import annotations

import math

import numpy as np
import pytest

MOMENT, ROT_DRAG_AXIAL = 1.0e-4, 2.0e-9          # defaults [A m^2], [N m s]
PROP, DRAG_AXIAL, ANISO = 3.2e-8, 8.0e-5, 1.5     # [N s/rad], [N s/m], [-]
NET_WEIGHT = (12.4e-6 - 998.2 * 12.38e-9) * 9.81  # mass - buoyancy, times g [N]
WALL = 0.075 - 1.25e-3                            # reachable centre coordinate [m]


def mean_spin(sim, helpers, field_t, f_hz, extra=None, T=1.5):
    """Mean spin [Hz] over 0.5 s..T, swimmer held at the centre (no thrust, neutrally
    buoyant) so the field it sees stays ``field_t``."""
    params = {"prop_coeff": 0.0, "V_supply_max": 100.0, "volume": 12.4e-6 / 998.2, **(extra or {})}
    r = sim.run(params, helpers.rotating_drive([1, 0, 0], field_t, f_hz, vmax=100.0), T=T)
    return r["spin_rate"][r["t"] > 0.5].mean()


def step_out_frequency(sim, helpers, field_t, lo=2.0, hi=60.0):
    """Highest frequency [Hz] at which the magnet stays locked (mean spin >= 95 % of f)."""
    for _ in range(9):
        mid = 0.5 * (lo + hi)
        if mean_spin(sim, helpers, field_t, mid) >= 0.95 * mid:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def test_speed_linear_in_frequency_below_step_out(sim, helpers):
    freqs = np.array([4.0, 6, 8, 10, 12, 14, 16])
    speeds, spins = [], []
    for f in freqs:
        r = sim.run({"p0_x": -0.04}, helpers.rotating_drive([1, 0, 0], 3e-3, f), T=1.0)
        late = r["t"] > 0.6
        speeds.append(r["velocity"][late, 0].mean())
        spins.append(r["spin_rate"][late].mean())
    speeds = np.array(speeds)
    slope, icpt = np.polyfit(freqs, speeds, 1)
    resid = speeds - (slope * freqs + icpt)
    r2 = 1 - (resid**2).sum() / ((speeds - speeds.mean()) ** 2).sum()
    assert r2 > 0.99
    # ideal slope 2 pi k / c_axial = 2.51 mm/s per Hz; the gradient force adds a little
    assert slope == pytest.approx(2 * math.pi * PROP / DRAG_AXIAL, rel=0.15)
    assert np.allclose(spins, freqs, rtol=0.01)
    # above step-out (the 40 V supply caps the field too) the speed collapses
    r = sim.run({"p0_x": -0.04}, helpers.rotating_drive([1, 0, 0], 3e-3, 30.0), T=1.0)
    assert r["velocity"][r["t"] > 0.6, 0].mean() < 0.3 * speeds[-1]


def test_step_out_frequency_proportional_to_field(sim, helpers):
    f1 = step_out_frequency(sim, helpers, 1.25e-3)
    f2 = step_out_frequency(sim, helpers, 2.5e-3)
    assert f2 / f1 == pytest.approx(2.0, rel=0.10)
    assert f1 == pytest.approx(MOMENT * 1.25e-3 / (2 * math.pi * ROT_DRAG_AXIAL), rel=0.10)


def test_mean_spin_above_step_out_follows_adler(sim, helpers):
    """Heading held on the rotation normal: mean spin = f - sqrt(f^2 - f_so^2) (3 %)."""
    field = 2e-3
    f_so = MOMENT * field / (2 * math.pi * ROT_DRAG_AXIAL)
    for ratio in (1.3, 2.0):
        f = ratio * f_so
        spin = mean_spin(sim, helpers, field, f, {"heading_dynamics_on": False}, T=4.0)
        assert spin == pytest.approx(f - math.sqrt(f * f - f_so * f_so), rel=0.03)


@pytest.mark.parametrize("anisotropic", [True, False])
def test_sinking_speed_with_field_off(sim, anisotropic):
    r = sim.run({"anisotropic_drag_on": anisotropic}, None, T=2.0)
    drag = DRAG_AXIAL * (ANISO if anisotropic else 1.0)   # long axis horizontal: broadside
    terminal = NET_WEIGHT / drag
    assert 2e-3 < terminal < 6e-3                           # "a few mm/s"
    assert -r["velocity"][-1, 2] == pytest.approx(terminal, rel=0.05)
    assert np.allclose(r["velocity"][-1, :2], 0.0)


@pytest.mark.parametrize("axis", ["horizontal", "vertical"])
def test_added_mass_slows_the_sinking_transient_not_its_end(sim, axis):
    """Field off, from rest: v_z(t) = -v_end (1 - exp(-t / tau)), v_end = W / c unchanged and
    tau = (m + k rho V) / c with the drag c and the added-mass ratio k of the direction of motion
    (broadside with the axis horizontal, axial with it vertical)."""
    k_ax, k_perp = 0.165, 0.752
    c, k = (DRAG_AXIAL * ANISO, k_perp) if axis == "horizontal" else (DRAG_AXIAL, k_ax)
    tilt = {"axis0_x": 0.0, "axis0_z": 1.0} if axis == "vertical" else {}
    params = {"gradient_force_on": False, "p0_z": 0.05, **tilt}
    rho_v = 998.2 * 12.38e-9
    for on, mass in ((False, 12.4e-6), (True, 12.4e-6 + k * rho_v)):
        r = sim.run({**params, "added_mass_on": on}, None, T=0.6, dt=0.005)
        v_end, tau = NET_WEIGHT / c, mass / c
        expected = -v_end * (1.0 - np.exp(-r["t"] / tau))
        assert np.abs(r["velocity"][:, 2] - expected).max() < 1e-3 * v_end, on
        assert np.allclose(r["velocity"][:, :2], 0.0, atol=1e-12)


@pytest.mark.parametrize("direction", [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)])
def test_never_crosses_a_wall(sim, helpers, direction):
    n = np.array(direction, float)
    r = sim.run({"axis0_x": 0.0, "axis0_y": 0.6, "axis0_z": 0.8},
                helpers.rotating_drive(n, 3e-3, 14.0), T=4.0)
    assert np.abs(r["position"]).max() <= WALL + 1e-12
    assert r["position"][-1] @ n == pytest.approx(WALL, abs=2e-3)   # pressed against the wall
    assert r["velocity"][-1] @ n <= 1e-12                            # no outward normal velocity


def _busy_run(sim, helpers, dt_internal):
    params = {
        "dt_internal": dt_internal, "p0_x": -0.02, "p0_y": 0.01,
        "axis0_x": 0.0, "axis0_y": 1.0, "axis0_z": 0.0,
        "quadratic_drag_on": True, "background_flow_on": True, "wall_drag_on": True,
    }
    return sim.run(params, helpers.rotating_drive([1, 0.5, -0.3], 3e-3, 12.0), T=3.0)


def test_halving_internal_step_changes_trajectory_less_than_one_percent(sim, helpers):
    a = _busy_run(sim, helpers, 1e-3)
    b = _busy_run(sim, helpers, 5e-4)
    travel = np.linalg.norm(a["position"] - a["position"][0], axis=1).max()
    assert travel > 0.02
    assert np.linalg.norm(a["position"] - b["position"], axis=1).max() < 0.01 * travel
    assert np.abs(a["velocity"] - b["velocity"]).max() < 0.01 * np.abs(a["velocity"]).max()


def test_runs_are_deterministic(sim, helpers):
    a = _busy_run(sim, helpers, 1e-3)
    b = _busy_run(sim, helpers, 1e-3)
    for key in a:
        assert np.array_equal(a[key], b[key])

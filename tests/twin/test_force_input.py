"""The FMU's external force input: a constant force drifts the swimmer at F / drag; the derivative inputs
act at the internal steps; zero inputs change nothing."""

from __future__ import annotations

import numpy as np
import pytest

from cosim_plugins.plant.fmu_component import FmuForcedPlant, FmuPlant

DRAG = 8.0e-5          # drag_axial [N s/m] (the FMU's default)
FREE = {"p0_z": 0.0, "anisotropic_drag_on": False, "gradient_force_on": False,
        "g": 0.0}      # no weight: only the applied force moves the swimmer


def _run(fmu, params, force=(0.0, 0.0, 0.0), dv=None, T=1.5, dt=0.02, cls=FmuForcedPlant):
    plant = cls()
    plant.setup({"fmu": fmu, **params}, np.random.default_rng(0))
    inputs = {"coil_voltage_amp": np.zeros(6), "coil_voltage_phase": np.zeros(6), "drive_freq": np.array(0.0)}
    if cls is FmuForcedPlant:
        inputs.update(external_force=np.asarray(force, float), external_force_dp=np.zeros(9),
                      external_force_dv=np.zeros(9) if dv is None else np.asarray(dv, float).reshape(9))
    try:
        rows = [plant.step(k * dt, inputs) for k in range(1, int(round(T / dt)) + 1)]
    finally:
        plant.close()
    return np.array([r["position"] for r in rows]), np.array([r["velocity"] for r in rows])


@pytest.mark.parametrize("force", [(1e-7, 0.0, 0.0), (0.0, -2e-7, 5e-8)])
def test_a_constant_force_gives_the_terminal_velocity_force_over_drag(twin_fmu, force):
    p, v = _run(twin_fmu, FREE, force)
    want = np.asarray(force) / DRAG                     # [m/s]: 1.25 mm/s for 0.1 uN
    assert np.allclose(v[-1], want, rtol=2e-3, atol=1e-9)
    # and the position drifts at that speed once the transient (m / drag = 0.155 s) has passed
    assert np.allclose((p[-1] - p[-26]) / 0.5, want, rtol=1e-2, atol=1e-9)


def _feedback(fmu, extra, linear, T=1.0, dt=0.02):
    """The swimmer pushed by 0.1 uN against an extra drag -extra v [N s/m] applied from outside, as
    twin.effect does: the force at the step's start, plus (linear) its derivative in v."""
    plant = FmuForcedPlant()
    plant.setup({"fmu": fmu, **FREE}, np.random.default_rng(0))
    inputs = {"coil_voltage_amp": np.zeros(6), "coil_voltage_phase": np.zeros(6), "drive_freq": np.array(0.0),
              "external_force_dp": np.zeros(9),
              "external_force_dv": (-extra * np.eye(3) if linear else np.zeros((3, 3))).reshape(9)}
    v = np.zeros(3)
    try:
        for k in range(1, int(round(T / dt)) + 1):
            inputs["external_force"] = np.array([1e-7, 0.0, 0.0]) - extra * v
            v = plant.step(k * dt, inputs)["velocity"]
    finally:
        plant.close()
    return v


def test_the_velocity_derivative_keeps_a_stiff_applied_drag_stable_within_the_step(twin_fmu):
    extra = 30 * DRAG     # m / (31 drag) = 5 ms, a quarter of the 20 ms step
    want = 1e-7 / (DRAG + extra)
    assert _feedback(twin_fmu, extra, linear=True)[0] == pytest.approx(want, rel=1e-3)
    # held over the step, the same drag overshoots: each step's force answers the last step's speed
    held = _feedback(twin_fmu, extra, linear=False)
    assert not abs(held[0] - want) < 0.5 * want


def test_zero_force_inputs_give_plant_fmus_run_exactly(twin_fmu):
    params = {"p0_x": 0.01, "background_flow_on": True}
    a = _run(twin_fmu, params, T=0.4, cls=FmuPlant)
    b = _run(twin_fmu, params, T=0.4)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])

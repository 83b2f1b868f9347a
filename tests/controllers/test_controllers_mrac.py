"""MRAC: the adapted gains stay inside their bounds under heavy measurement noise."""

from __future__ import annotations

import numpy as np
import pytest

from cosim import ComponentError
from cosim.scenario.paths import make_path
from cosim_plugins.controllers.mrac import PARAMS, MRACController

DT = 0.02


def closed_loop(params, noise_mm, steps=3000, seed=0, b=1.2, tau_s=0.15, sink_mm_s=3.5):
    """MRAC on a first-order swimmer (gain b mm/s per Hz, lag tau, sinking) with noisy
    position measurements and backward-difference velocity; yields (k_hat, d_hat, error mm)."""
    path = make_path("racetrack", {"straight_mm": 30, "radius_mm": 40})
    ctrl = MRACController()
    ctrl.setup({**params, "dt": DT, "path": path}, np.random.default_rng(seed))
    rng = np.random.default_rng(seed)
    p, v = np.array([-15.0, -40.0, 0.0]), np.zeros(3)  # mm, mm/s
    a = np.exp(-DT / tau_s)
    z_prev = None
    for k in range(steps):
        z = p + rng.normal(0, noise_mm, 3)
        v_meas = np.zeros(3) if z_prev is None else (z - z_prev) / DT
        z_prev = z
        out = ctrl.step(k * DT, {"position": z * 1e-3, "velocity": v_meas * 1e-3})
        u = out["omega"] / (2 * np.pi)
        v_ss = b * u + np.array([0.0, 0.0, -sink_mm_s])
        v = a * v + (1 - a) * v_ss
        p = p + v * DT
        k_hat, d_hat = ctrl.gains
        yield k_hat, d_hat, np.sqrt(((path.points() * 1e3 - p) ** 2).sum(axis=1).min())


@pytest.mark.parametrize("scale", [1.0, 100.0])
def test_adapted_gains_stay_bounded_under_noise(scale):
    """Position noise 0.5 mm (5x the camera's; velocity noise ~35 mm/s); with the default rates
    and with rates 100x larger the projection keeps k_hat in [k_min, k_max] and |d_hat| <= d_max."""
    params = {"gamma_k": PARAMS["gamma_k"].default * scale, "gamma_d": PARAMS["gamma_d"].default * scale}
    k_min, k_max, d_max = (PARAMS[n].default for n in ("k_min", "k_max", "d_max_hz"))
    rows = list(closed_loop(params, noise_mm=0.5))
    k = np.array([r[0] for r in rows])
    d = np.array([np.linalg.norm(r[1]) for r in rows])
    err = np.array([r[2] for r in rows])
    assert np.all((k >= k_min - 1e-12) & (k <= k_max + 1e-12))
    assert np.all(d <= d_max + 1e-9)
    assert np.all(np.isfinite(err)) and err.max() < 30.0  # stays near the path throughout
    if scale == 1.0:
        assert err[len(err) // 2:].mean() < 2.0


def test_gains_learn_the_input_gain_and_the_sinking():
    """Without noise, the estimates move towards 1/b and the sinking compensation (+z)."""
    rows = list(closed_loop({}, noise_mm=0.0, b=1.2))
    k_hat, d_hat, _ = rows[-1]
    assert k_hat > 0.6  # from 0.4 = 1/2.5 towards 1/1.2
    assert d_hat[2] > 1.0  # pushes up against sinking [Hz]


def test_inconsistent_gain_bounds_are_rejected():
    with pytest.raises(ComponentError, match="k_min <= k0 <= k_max"):
        MRACController.validate_params({"k0": 2.0, "k_max": 1.5})

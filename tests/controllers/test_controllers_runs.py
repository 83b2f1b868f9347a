"""Each controller on a short racetrack run (plant FMU, camera noise 0.5 px, 20 ms feedback)."""

from __future__ import annotations

import numpy as np
import pytest

from cosim_plugins.resources import SCENARIOS_DIR

SCENARIOS = SCENARIOS_DIR

DURATION_S = 12.0
#: Mean tracking error bound for the short run [mm] (60 s runs: PI ~1.8, MRAC ~0.6, MPC ~0.8).
MEAN_ERROR_BOUND_MM = {"pi": 2.5, "mrac": 1.5, "mpc": 1.5}


@pytest.fixture(scope="module")
def racetrack_runs(run_scenario):
    """{controller: (summary, out_dir)}, each run once for the whole module."""
    cache = {}

    def get(name, *extra):
        key = (name, *extra)
        if key not in cache:
            cache[key] = run_scenario(SCENARIOS / "controllers_racetrack.yaml", f"duration_s={DURATION_S}",
                                      f"components.controller.plugin=controller.{name}", *extra)
        return cache[key]

    return get


@pytest.mark.parametrize("name", ["pi", "mrac", "mpc"])
def test_controller_finishes_the_racetrack(racetrack_runs, name):
    summary, out = racetrack_runs(name)
    assert summary["status"] == "ok"
    assert summary["steps"] == int(DURATION_S / 0.02)
    assert summary["tracking_error_mm"]["mean"] < MEAN_ERROR_BOUND_MM[name]
    assert summary["solve_ms"]["median"] > 0
    with np.load(out / "trace.npz") as trace:
        omega = trace["controller.omega"]
    assert np.all(np.isfinite(omega))


def test_mpc_never_violates_its_bounds(racetrack_runs):
    """On every step: |u| <= 1 and |u_k - u_{k-1}| <= 1 per axis (u = omega_Hz / f_max, f_max = 20 Hz),
    and |omega| / 2 pi <= f_norm_max_hz = 20 Hz. Tight bounds (0.6, 0.05) make them bind."""
    for extra, u_max, du_max in [((), 1.0, 1.0),
                                 (("components.controller.params.u_max=0.6",
                                   "components.controller.params.du_max=0.05"), 0.6, 0.05)]:
        summary, out = racetrack_runs("mpc", *extra)
        assert summary["status"] == "ok"
        with np.load(out / "trace.npz") as trace:
            u = trace["controller.omega"] / (2 * np.pi) / 20.0
        du = np.diff(np.vstack([np.zeros(3), u]), axis=0)
        assert np.abs(u).max() <= u_max + 1e-9
        assert np.abs(du).max() <= du_max + 1e-9
        assert np.linalg.norm(u, axis=1).max() * 20.0 <= 20.0 + 1e-9
        if extra:
            assert np.isclose(np.abs(du).max(), du_max)  # the tight bound was active


def test_mpc_cvxpy_backend_runs_like_the_fast_path(racetrack_runs):
    """The reference formulation in the loop (short): same tracking within 0.3 mm."""
    fast, _ = racetrack_runs("mpc", "duration_s=4")
    ref, _ = racetrack_runs("mpc", "duration_s=4", "components.controller.params.backend=cvxpy")
    assert ref["status"] == "ok"
    assert abs(ref["tracking_error_mm"]["mean"] - fast["tracking_error_mm"]["mean"]) < 0.3

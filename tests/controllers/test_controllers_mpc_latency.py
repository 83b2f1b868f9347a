"""The MPC predicts a stale state over the camera's latency (``latency_s``) with its own model and
the commands it sent since the frame's capture; without that, behind the passthrough estimator,
it plans from where the swimmer was 40 ms ago and the loop rings: on the lab profile (30 s,
seed 1) the racetrack error was 2.98 mm against PI's 0.80, with the swimmer held ~3 mm below
the path while commanding ~9 Hz upwards; compensated, 1.07 mm and the height error of PI's.
Since the lab plant has the paper's drag anisotropy (1.165) the uncompensated loop no longer
rings, and the prediction still cuts the error by a third (60 s: 0.94 -> 0.61 mm).

Here the lab profile, 12 s, with its model identified on the short lab dataset: 0.99 -> 0.72 mm,
mean |z| 0.63 -> 0.41 mm (at 40 mm/s an ideal model, identified at 20 mm/s, is too wrong for the
prediction to help)."""

from __future__ import annotations

from collections import deque
from pathlib import Path

import numpy as np
import pytest

from cosim import ComponentError
from cosim_plugins.resources import SCENARIOS_DIR

SCENARIOS = SCENARIOS_DIR
LATENCY = ["profile=lab", "duration_s=12", "components.controller.plugin=controller.mpc"]


def mean_abs_z_mm(trace: Path, after_s: float = 2.0) -> float:
    with np.load(trace) as d:
        t, p = d["t_s"], d["plant.position"] * 1e3
    return float(np.mean(np.abs(p[t > after_s, 2])))


@pytest.fixture(scope="module")
def latency_runs(run_scenario):
    return {lat: run_scenario(SCENARIOS / "controllers_racetrack.yaml", *LATENCY,
                              f"components.controller.params.latency_s={lat}")
            for lat in (0.0, 0.04)}


def test_compensating_the_camera_latency_cuts_the_tracking_error(latency_runs):
    (raw, raw_dir), (comp, comp_dir) = latency_runs[0.0], latency_runs[0.04]
    assert raw["status"] == comp["status"] == "ok"
    e_raw, e_comp = raw["tracking_error_mm"]["mean"], comp["tracking_error_mm"]["mean"]
    assert e_comp < 0.85 * e_raw, f"compensated {e_comp:.2f} mm, uncompensated {e_raw:.2f} mm"
    z_raw, z_comp = mean_abs_z_mm(raw_dir / "trace.npz"), mean_abs_z_mm(comp_dir / "trace.npz")
    assert z_comp < 0.8 * z_raw, f"mean |z| compensated {z_comp:.2f} mm, uncompensated {z_raw:.2f} mm"


def test_present_state_steps_the_model_with_the_commands_sent_since():
    from cosim_plugins.controllers.mpc import MPCController
    from cosim_plugins.controllers.mpc_qp import MPCSpec

    rng = np.random.default_rng(3)
    A, B, c = np.eye(6) + 0.01 * rng.standard_normal((6, 6)), rng.standard_normal((6, 3)), rng.standard_normal(6)
    ctl = MPCController.__new__(MPCController)
    ctl.spec, ctl.sent = MPCSpec(A=A, B=B, c=c, f_max_hz=20.0), deque(maxlen=2)
    for u in rng.uniform(-1, 1, (4, 3)):
        ctl.sent.append(u)
    x = rng.standard_normal(6)
    expect = x
    for u in ctl.sent:
        expect = A @ expect + B @ (20.0 * u) + c
    assert len(ctl.sent) == 2
    np.testing.assert_allclose(ctl.present_state(x), expect)
    ctl.sent = deque(maxlen=0)
    ctl.sent.append(np.ones(3))
    np.testing.assert_allclose(ctl.present_state(x), x)


def test_a_latency_off_the_step_grid_is_refused(run_scenario):
    with pytest.raises(ComponentError, match="not a multiple"):
        run_scenario(SCENARIOS / "controllers_racetrack.yaml", "duration_s=1",
                     "components.controller.plugin=controller.mpc", "components.controller.params.latency_s=0.03")

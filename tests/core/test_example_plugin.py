"""The docs' plugin example (docs/framework/writing-a-plugin.md): a user's estimator loaded from a file
named in the scenario."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cosim.api import RunRequest, run

EXAMPLE = Path(__file__).parents[2] / "examples" / "ema_racetrack.yaml"


def test_example_plugin_runs_and_smooths(tmp_path):
    summary = run(RunRequest(EXAMPLE, tmp_path, ["duration_s=10"], progress=False))
    assert summary["status"] == "ok" and summary["tracking_error_mm"]["mean"] < 5.0
    trace = np.load(tmp_path / "trace.npz")
    measured, estimate = trace["camera.position"], trace["estimator.position"]
    # an EMA lags and smooths: its step-to-step jitter is below the camera's
    assert np.std(np.diff(estimate[10:, 0], 2)) < np.std(np.diff(measured[10:, 0], 2))

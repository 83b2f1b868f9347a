"""estimator.kf in the loop with the plant FMU: consistent innovations, outliers rejected.

The model is the linear SINDy one trained on demand on the short paper dataset
(``COSIM_DATASET=quick``, see conftest.py) and Q is fitted on the same logs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from cosim.api import RunRequest, run
from cosim_plugins.resources import SCENARIOS_DIR

SCENARIO = SCENARIOS_DIR / "feedback_sweep.yaml"


def loop_on_plant(out: Path, adapt_rate: float):
    """30 s of PI on the racetrack with the KF (linear SINDy), frames every 100 ms, no outliers: summary, trace."""
    overrides = ["sweep={}", "duration_s=30", "components.camera.params.interval_s=0.1",
                 "components.camera.params.outlier_prob=0.0", "components.estimator.params.model=sindy-linear",
                 f"components.estimator.params.adapt_rate={adapt_rate}"]
    summary = run(RunRequest(SCENARIO, out, overrides, progress=False))
    with np.load(out / "trace.npz") as trace:
        return summary, {k: trace[k] for k in trace.files}


def nis_after_the_first_second(trace: dict) -> np.ndarray:
    nis = trace["estimator.nis"]
    return nis[np.isfinite(nis)][10:]


@pytest.fixture(scope="module")
def plant_run(tmp_path_factory):
    """The loop with the default adaptive Q scale (adapt_rate 0.1)."""
    return loop_on_plant(tmp_path_factory.mktemp("kf_plant"), adapt_rate=0.1)


def test_normalised_innovations_are_chi_square_on_plant_data(plant_run):
    nis = nis_after_the_first_second(plant_run[1])  # the default: Q's scale follows the innovations
    n = len(nis)
    assert n >= 280
    below = np.mean(nis <= chi2.ppf(0.5, 3))  # binomial(n, 1/2) if NIS ~ chi-square(3): 4-sigma band
    assert abs(below - 0.5) <= 4 * np.sqrt(0.25 / n), below
    assert 0.01 <= np.mean(nis > chi2.ppf(0.95, 3)) <= 0.10  # 5 % expected
    assert 2.0 <= nis.mean() <= 4.0  # 3 expected
    assert np.mean(nis > chi2.ppf(0.9999, 3)) <= 0.01  # (almost) nothing gated on clean frames


def test_q_as_fitted_is_consistent_or_conservative_on_plant_data(tmp_path):
    """The Q fitted on all twelve training paths is a little conservative on the racetrack: never overconfident."""
    nis = nis_after_the_first_second(loop_on_plant(tmp_path, adapt_rate=0.0)[1])
    assert 1.5 <= nis.mean() <= chi2.ppf(0.995, 3 * len(nis)) / len(nis)  # at most 2x conservative
    assert np.mean(nis > chi2.ppf(0.95, 3)) <= 0.05


def test_loop_tracks_and_reports_its_prediction_error(plant_run):
    summary, trace = plant_run
    assert summary["status"] == "ok"
    assert summary["tracking_error_mm"]["mean"] < 1.5
    assert summary["estimation_error_mm"]["mean"] < 0.5
    pe = summary["prediction_error_mm"]
    assert pe["frames"] >= 295 and 0.05 < pe["rmse"] < 1.0


def test_reflection_outliers_are_rejected_in_the_loop(tmp_path):
    overrides = ["sweep={}", "duration_s=20", "components.camera.params.interval_s=0.02",
                 "components.camera.params.outlier_prob=0.02", "components.camera.params.outlier_mm=5.0",
                 "components.estimator.params.model=sindy-linear"]
    summary = run(RunRequest(SCENARIO, tmp_path, overrides, progress=False))
    with np.load(tmp_path / "trace.npz") as trace:
        innov = trace["estimator.innovation"] * 1e3
        est, truth = trace["estimator.position"], trace["plant.position"]
    big = np.linalg.norm(innov, axis=1) > 2.0  # 5 mm reflections (halved in x: two cameras)
    assert 8 <= big.sum() <= 40  # ~2 % of 1000 frames
    err = np.linalg.norm(est - truth, axis=1) * 1e3
    assert err[big].max() < 0.6  # the estimate did not follow them
    assert summary["estimation_error_mm"]["max"] < 1.5

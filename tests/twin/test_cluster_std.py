"""The calibration's standard errors cover the truth as often as they claim when the residuals are correlated
within each chunk (the windows of one FMU run share their rows' errors)."""

from __future__ import annotations

import numpy as np

from cosim_plugins.twin.calibrate import _cluster_std


def _coverage(std_of, trials: int = 120, clusters: int = 30, rows: int = 60, knobs: int = 10) -> float:
    """Share of 95 % intervals (1.96 std) that hold the true value 0, on linear least-squares problems shaped
    like the polish's: cluster-correlated regressors and residuals."""
    rng = np.random.default_rng(7)
    hits = 0
    for _ in range(trials):
        ids = np.repeat(np.arange(clusters), rows)
        J = rng.normal(size=(len(ids), knobs)) + 1.5 * rng.normal(size=(clusters, knobs))[ids]
        e = 0.5 * rng.normal(size=clusters)[ids] + 0.2 * rng.normal(size=len(ids))
        x = np.linalg.lstsq(J, e, rcond=None)[0]
        hits += int(np.sum(np.abs(x) < 1.96 * std_of(J, e - J @ x, ids)))
    return hits / (trials * knobs)


def test_the_standard_errors_cover_the_truth_with_residuals_correlated_within_chunks():
    assert 0.92 <= _coverage(_cluster_std) <= 0.98


def test_standard_errors_that_ignore_the_correlation_would_fail_the_same_check():
    def rows_independent(J, r, ids):
        return np.sqrt(np.diag(np.linalg.inv(J.T @ J)) * np.mean(r * r))

    assert _coverage(rows_independent) < 0.6

"""Run and sweep figures: the detection error, the largest interval under a threshold, the table and the plot."""

from __future__ import annotations

import numpy as np
from figure_checks import assert_labelled

from cosim.contract.figures import Figure
from cosim.record.summary import sweep_table
from cosim.record.sweep_report import largest_below, sweep_plot
from cosim_plugins.figures import detection_error_m


def row(interval, est, mean, status="ok"):
    return {"interval_s": interval, "estimator": est, "status": status,
            "tracking_error_mm": {"mean": mean, "std": 1.0, "max": 2 * mean}}


TRACKING = Figure("tracking_error_mm")
ROWS = [row(0.02, "none", 2.0), row(0.1, "none", 4.0), row(0.2, "none", 9.0), row(0.4, "none", 3.0),
        row(0.02, "kf", 1.5), row(0.1, "kf", 2.0), row(0.2, "kf", 3.0), row(0.4, "kf", 4.0, "failed")]


def test_largest_below_stops_at_the_first_value_over_the_threshold():
    got = {r["estimator"]: r["largest_below"] for r in largest_below(ROWS, TRACKING, 4.6)}
    # 0.4 s without an estimator is under 4.6 mm again, but 0.2 s was not: the answer is 0.1 s.
    # A failed run never counts.
    assert got == {"none": 0.1, "kf": 0.2}


def test_table_and_plot(tmp_path, saved_figures):
    table = sweep_table(ROWS)
    assert table.splitlines()[0].startswith("| interval_s | estimator | tracking error [mm]")
    assert "| 0.1 | kf | 2.00 ± 1.00 | 4.00 |" in table
    files = sweep_plot(ROWS, tmp_path, TRACKING, 4.6, "fig6")
    assert [f.name for f in files] == ["sweep_interval_s.png"] and files[0].stat().st_size > 10_000
    assert_labelled(saved_figures)
    assert saved_figures["sweep_interval_s.png"]["axes"] == [("interval [s]", "mean tracking error [mm]")]
    assert saved_figures["sweep_interval_s.png"]["title"].startswith("fig6: ")


def test_detection_error_compares_each_measurement_with_the_truth_when_it_was_captured():
    t_s = np.arange(5) * 0.02
    truth = np.stack([t_s * 0.01, np.zeros(5), np.zeros(5)], axis=1)  # 10 mm/s along x
    measured = np.full((5, 3), np.nan)
    measured[2] = truth[1] + [0.0, 3e-6, 0.0]  # delivered at row 2, captured at row 1's time, 3 um off
    measured[4] = truth[4] + [0.0, 0.0, 4e-6]  # no capture time: taken at its own row
    capture = np.array([np.nan, np.nan, 0.02, np.nan, np.nan])
    error = detection_error_m(measured, truth, t_s, capture)
    assert np.isnan(error[[0, 1, 3]]).all()
    assert np.allclose(error[[2, 4]], [3e-6, 4e-6])
    assert detection_error_m(measured, truth, t_s)[2] > 1e-4  # against row 2's truth: 0.2 mm off

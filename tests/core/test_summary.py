"""Sweep figures: the largest interval under a threshold, the table and the plot."""

from __future__ import annotations

from cosim.summary import largest_below, sweep_plot, sweep_table
from figure_checks import assert_labelled


def row(interval, est, mean, status="ok"):
    return {"interval_s": interval, "estimator": est, "status": status,
            "tracking_error_mm": {"mean": mean, "std": 1.0, "max": 2 * mean}}


ROWS = [row(0.02, "none", 2.0), row(0.1, "none", 4.0), row(0.2, "none", 9.0), row(0.4, "none", 3.0),
        row(0.02, "kf", 1.5), row(0.1, "kf", 2.0), row(0.2, "kf", 3.0), row(0.4, "kf", 4.0, "failed")]


def test_largest_below_stops_at_the_first_value_over_the_threshold():
    got = {r["estimator"]: r["largest_below"] for r in largest_below(ROWS, 4.6)}
    # 0.4 s without an estimator is under 4.6 mm again, but 0.2 s was not: the answer is 0.1 s.
    # A failed run never counts.
    assert got == {"none": 0.1, "kf": 0.2}


def test_table_and_plot(tmp_path, saved_figures):
    table = sweep_table(ROWS)
    assert table.splitlines()[0].startswith("| interval_s | estimator | tracking error [mm]")
    assert "| 0.1 | kf | 2.00 ± 1.00 | 4.00 |" in table
    files = sweep_plot(ROWS, tmp_path, 4.6, "fig6")
    assert [f.name for f in files] == ["sweep_interval_s.png"] and files[0].stat().st_size > 10_000
    assert_labelled(saved_figures)
    assert saved_figures["sweep_interval_s.png"]["axes"] == [("interval [s]", "mean tracking error [mm]")]
    assert saved_figures["sweep_interval_s.png"]["title"].startswith("fig6: ")

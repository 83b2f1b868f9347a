"""A sweep's report on the figure its scenario names (``report: {figure, part, threshold}``): units
from the figure's key, a part of a figure, the old ``threshold_mm`` refused with the new spelling,
and the swimmer's feedback sweep still reporting its largest interval below 4.6 mm."""

from __future__ import annotations

import json

import pytest

from cosim.contract.errors import ScenarioError
from cosim.contract.figures import Figure, unit_of
from cosim.record.sweep_report import (
    figure_label,
    figure_missing,
    largest_below,
    largest_below_lines,
    pool_replicates,
    pooled_table,
    report_figure,
)
from cosim.scale.sweep import SweepRecord
from cosim.scenario.schema import load_scenario
from cosim_plugins.resources import SCENARIOS_DIR

SPEED = Figure("speed_error_rad_s", "rms")


def motor_row(kp, seed, rms, status="ok"):
    """A sweep row as the sweep makes it: labels, status, then a component's own figures."""
    return {"kp": kp, "seed": seed, "status": status, "speed_error_rad_s": {"rms": rms, "max_abs": 3 * rms}}


def test_a_keys_unit_is_its_longest_suffix():
    assert unit_of("speed_error_rad_s") == ("speed_error", "rad/s")
    assert unit_of("interval_s") == ("interval", "s")
    assert unit_of("tracking_error_mm") == ("tracking_error", "mm")
    assert unit_of("saturated_fraction") == ("saturated_fraction", "")
    assert unit_of("_s") == ("_s", "")  # a suffix alone is no unit of anything


def test_a_part_of_a_figure_is_pooled_tabled_and_thresholded_in_its_own_unit():
    rows = [motor_row(0.1, 1, 10.0), motor_row(0.1, 2, 12.0), motor_row(0.2, 1, 30.0), motor_row(0.2, 2, 34.0),
            motor_row(0.4, 1, 20.0), motor_row(0.4, 2, 20.0)]
    pooled = pool_replicates(rows, SPEED)
    assert pooled[0]["speed_error_rad_s.rms"] == {"mean": 11.0, "std": pytest.approx(1.4142, abs=1e-4),
                                                  "max": 12.0, "min_mean": 10.0, "max_mean": 12.0, "n": 2}
    table = pooled_table(pooled, SPEED)
    assert table.splitlines()[0] == ("| kp | seeds | rms speed error [rad/s] | spread over seeds (std) [rad/s] "
                                     "| min / max of the seeds' means [rad/s] | max [rad/s] | status |")
    # 0.4 is below 25 rad/s again, but 0.2 was not: the walk along the axis stops at 0.2
    found = largest_below(rows, SPEED, 25.0)
    assert found == [{"axis": "kp", "largest_below": 0.1, "figure": "speed_error_rad_s.rms", "threshold": 25.0}]
    label = figure_label(rows, SPEED)
    assert largest_below_lines(found, label, SPEED, 25.0) == ["largest kp with rms speed error below 25 rad/s: 0.1"]
    text = table + "\n".join(largest_below_lines(found, label, SPEED, 25.0))
    assert "mm" not in text.replace("summary", "") and "tracking" not in text


def test_a_run_without_the_figure_or_a_failed_one_ends_the_walk():
    rows = [motor_row(0.1, 0, 1.0), {"kp": 0.2, "seed": 0, "status": "ok"}, motor_row(0.4, 0, 1.0)]
    assert largest_below(rows, SPEED, 5.0)[0]["largest_below"] == 0.1
    rows[1] = motor_row(0.2, 0, 1.0, status="failed")
    assert largest_below(rows, SPEED, 5.0)[0]["largest_below"] == 0.1


def test_the_report_figure_defaults_to_the_tracking_error_only_when_runs_have_it():
    plain = [{"kp": 0.1, "status": "ok", "saturated_fraction": 0.0}]
    assert report_figure(None, None, plain, default="tracking_error_mm") is None
    tracked = [{"interval_s": 0.1, "tracking_error_mm": {"mean": 1.0}, "status": "ok"}]
    assert report_figure(None, None, tracked, default="tracking_error_mm") == Figure("tracking_error_mm")
    assert report_figure("saturated_fraction", None, plain, default="tracking_error_mm") == Figure("saturated_fraction")
    assert figure_missing(plain, Figure("saturated_fraction")) is None
    assert figure_label(plain, Figure("saturated_fraction")) == "saturated fraction"  # one run's number
    seeded = [{"kp": 0.1, "seed": 1, "status": "ok", "saturated_fraction": 0.0}]
    assert figure_label(seeded, Figure("saturated_fraction")) == "mean saturated fraction"  # over the seeds
    assert figure_missing(plain, Figure("saturation")) == (
        "report: figure 'saturation': no run of the sweep has it; its runs' figures: saturated_fraction")


def _write(tmp_path, report: str):
    text = (SCENARIOS_DIR / "feedback_sweep.yaml").read_text()
    lines = [line for line in text.splitlines() if not line.startswith("report:")]
    file = tmp_path / "sweep.yaml"
    file.write_text("\n".join([*lines, report]) + "\n")
    return file


def test_the_old_threshold_mm_is_refused_naming_the_new_spelling(tmp_path):
    with pytest.raises(ScenarioError, match=r"threshold_mm is no longer read: .*"
                                            r"report: \{figure: tracking_error_mm, threshold: 4.6\}"):
        load_scenario(_write(tmp_path, "report: {threshold_mm: 4.6}"))


def test_a_threshold_or_part_without_its_figure_is_refused(tmp_path):
    with pytest.raises(ScenarioError, match="threshold and part need the figure they apply to"):
        load_scenario(_write(tmp_path, "report: {threshold: 4.6}"))


def test_the_feedback_sweep_still_reports_its_largest_interval_below_4_6_mm(tmp_path, capsys):
    """The swimmer's scenario names its figure and threshold; the framework's sweep reports on them."""
    scenario = load_scenario(SCENARIOS_DIR / "feedback_sweep.yaml")
    assert (scenario.report.figure, scenario.report.part, scenario.report.threshold) == ("tracking_error_mm", None, 4.6)
    record = SweepRecord(scenario, tmp_path, 4)
    for i, (interval, mean) in enumerate([(0.02, 2.0), (0.2, 4.0), (0.5, 5.0), (1.0, 3.0)]):
        record.rows[i] = {"estimator": "none", "interval_s": interval, "status": "ok", "dir": f"runs/{i:03d}",
                          "tracking_error_mm": {"mean": mean, "std": 0.5, "max": 2 * mean}}
    summary = record.finish(stopped=False, progress=True)
    assert summary["largest_below_threshold"] == [{"estimator": "none", "axis": "interval_s", "largest_below": 0.2,
                                                   "figure": "tracking_error_mm", "threshold": 4.6}]
    assert "largest interval_s with mean tracking error below 4.6 mm: 0.2 (estimator=none)" in capsys.readouterr().out
    assert json.loads((tmp_path / "summary.json").read_text())["plots"] == ["sweep_interval_s.png"]

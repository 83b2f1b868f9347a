"""The DC motor's two-point sweep (examples/dc_motor/gains.yaml): every numeric figure of a run's
summary reaches its sweep row, summary.md shows the motor's own figures, its report's threshold is
on the motor's saturation, and nothing the sweep writes or prints speaks of millimetres or tracking."""

from __future__ import annotations

import contextlib
import io
import json
import re
from pathlib import Path

import pytest

from cosim.api import RunRequest, run
from cosim.contract import plugins
from cosim.record.summary import BOOKKEEPING_KEYS, RUN_KEYS, is_figure

SWEEP = Path(__file__).parents[2] / "examples" / "dc_motor" / "gains.yaml"


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("dc_motor_gains")
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed), contextlib.redirect_stderr(printed):
        summary = run(RunRequest(SWEEP, out, ["duration_s=0.3"], progress=True))
    yield out, summary, printed.getvalue()
    plugins.reset()  # forget the example's plugin file


def test_a_row_carries_every_numeric_figure_of_its_runs_summary(sweep):
    out, summary, _ = sweep
    assert [row["status"] for row in summary["sweep"]] == ["ok", "ok"]
    for row in summary["sweep"]:
        run_summary = json.loads((out / row["dir"] / "summary.json").read_text())
        figures = {k: v for k, v in run_summary.items()
                   if k not in (*RUN_KEYS, *BOOKKEEPING_KEYS) and v is not None and is_figure(v)}
        assert {"speed_error_rad_s", "saturated_fraction"} <= set(figures)
        assert {k: row.get(k) for k in figures} == figures


def test_the_table_shows_the_motors_own_figures(sweep):
    out, summary, _ = sweep
    table = (out / "summary.md").read_text().splitlines()
    assert table[0] == "| kp_V_s_per_rad | speed_error_rad_s rms / max_abs | saturated_fraction | status |"
    first = summary["sweep"][0]
    assert table[2] == (f"| 0.05 | {first['speed_error_rad_s']['rms']:.4g}/{first['speed_error_rad_s']['max_abs']:.4g}"
                        f" | {first['saturated_fraction']:.4g} | ok |")


def test_the_threshold_is_the_motors_saturation_and_no_millimetre_shows(sweep):
    out, summary, printed = sweep
    fractions = [row["saturated_fraction"] for row in summary["sweep"]]
    expected = None
    for kp, fraction in zip((0.05, 0.1), fractions):
        if fraction >= 0.005:
            break
        expected = kp
    assert summary["largest_below_threshold"] == [{"axis": "kp_V_s_per_rad", "largest_below": expected,
                                                   "figure": "saturated_fraction", "threshold": 0.005}]
    assert f"largest kp_V_s_per_rad with saturated fraction below 0.005: {expected}" in printed
    assert summary["plots"] == ["sweep_kp_V_s_per_rad.png"] and (out / "sweep_kp_V_s_per_rad.png").is_file()
    written = (out / "summary.md").read_text() + (out / "summary.json").read_text() + printed
    assert not re.search(r"(?<![a-z])mm(?![a-z])", written, re.I)  # no mm, _mm or [mm] ("summary" is fine)
    assert "tracking" not in written

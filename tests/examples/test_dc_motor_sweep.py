"""The DC motor's two-point sweep (examples/dc_motor/gains.yaml): every numeric figure of a run's
summary reaches its sweep row, and summary.md shows the motor's own figures."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cosim.api import RunRequest, run
from cosim.contract import plugins
from cosim.record.summary import BOOKKEEPING_KEYS, RUN_KEYS, is_figure

SWEEP = Path(__file__).parents[2] / "examples" / "dc_motor" / "gains.yaml"


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("dc_motor_gains")
    summary = run(RunRequest(SWEEP, out, ["duration_s=0.3"], progress=False))
    yield out, summary
    plugins.reset()  # forget the example's plugin file


def test_a_row_carries_every_numeric_figure_of_its_runs_summary(sweep):
    out, summary = sweep
    assert [row["status"] for row in summary["sweep"]] == ["ok", "ok"]
    for row in summary["sweep"]:
        run_summary = json.loads((out / row["dir"] / "summary.json").read_text())
        figures = {k: v for k, v in run_summary.items()
                   if k not in (*RUN_KEYS, *BOOKKEEPING_KEYS) and v is not None and is_figure(v)}
        assert {"speed_error_rad_s", "saturated_fraction"} <= set(figures)
        assert {k: row.get(k) for k in figures} == figures


def test_the_table_shows_the_motors_own_figures(sweep):
    out, summary = sweep
    table = (out / "summary.md").read_text().splitlines()
    assert table[0] == "| kp_V_s_per_rad | speed_error_rad_s rms / max_abs | saturated_fraction | status |"
    first = summary["sweep"][0]
    assert table[2] == (f"| 0.05 | {first['speed_error_rad_s']['rms']:.4g}/{first['speed_error_rad_s']['max_abs']:.4g}"
                        f" | {first['saturated_fraction']:.4g} | ok |")
    assert summary["plots"] == []  # no tracking error: no plot of it

"""The default scenario end to end on the real plant FMU: the PI loop on the paper's racetrack."""

from __future__ import annotations

import json

from cosim.cli import main
from cosim_plugins.resources import SCENARIOS_DIR

SCENARIO = SCENARIOS_DIR / "racetrack.yaml"


def test_pi_follows_the_racetrack_within_3_mm(tmp_path, capsys):
    assert main(["run", str(SCENARIO), "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    err = summary["tracking_error_mm"]
    assert err["mean"] <= 3.0, err
    assert summary["steps"] == 3000 and summary["realtime_factor"] > 0
    assert (tmp_path / "log.csv").read_text().startswith("t_ms,omega_x,omega_y,omega_z,p_x,p_y,p_z\n")
    assert (tmp_path / "recording.rrd").is_file()
    assert f"recording: {tmp_path / 'recording.rrd'}" in capsys.readouterr().out


def test_plant_loop_is_byte_identical_across_process_layouts(tmp_path):
    short = ["--set", "duration_s=6", "--quiet"]
    assert main(["run", str(SCENARIO), "--out", str(tmp_path / "a"), *short]) == 0
    assert main(["run", str(SCENARIO), "--out", str(tmp_path / "b"), *short, "--processes"]) == 0
    assert main(["run", str(SCENARIO), "--out", str(tmp_path / "c"), *short, "--processes", "--node-cpus", "none"]) == 0
    log = (tmp_path / "a" / "log.csv").read_bytes()
    assert log == (tmp_path / "b" / "log.csv").read_bytes() == (tmp_path / "c" / "log.csv").read_bytes()

"""The blind bench flies a designed experiment on the circle its experiment.yaml names (the driver reads the
path; the simulator's physics and controller stay its own): a wall drag and a flow differ only where the
swimmer is, so the log must come from where the design put the circle. Seconds: one 8 s log."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from cosim_plugins.diagnose.excitation import Excitation
from cosim_plugins.diagnose.experiment import Experiment
from cosim_plugins.raw_log import read_log

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import blind  # noqa: E402
import blind_sim  # noqa: E402

CENTRE_MM, RADIUS_MM = [-20.0, 15.0, 55.0], 18.0  # near the lid (75 mm), off the tank's centre


def test_the_experiment_is_flown_on_the_scenarios_circle(tmp_path):
    case = blind_sim.draw_case(5, "library", "wall_drag", duration_s=30.0, logs=1, noise_mm=0.1, dt_s=0.02)
    lo, hi = case.regime["band_hz"]
    exp = Experiment(members=["wall_drag", "background_flow"], excitation=Excitation("stop", lo, hi, 8.0, period_s=2.0),
                     dt_s=0.02, center_mm=CENTRE_MM, radius_mm=RADIUS_MM, place="+z", separation_mm=1.0, floor_mm=0.2)
    yaml_path, csv_path = exp.write(tmp_path)
    path = blind._scenario_path(yaml_path)
    assert path["kind"] == "circle" and path["offset_mm"] == CENTRE_MM and path["radius_mm"] == RADIUS_MM
    log = read_log(blind_sim.simulate_experiment(case, csv_path, tmp_path, path=path))
    p = log.p_mm[np.all(np.isfinite(log.p_mm), axis=1)]
    assert np.linalg.norm(p[0] - (np.array(CENTRE_MM) + [RADIUS_MM, 0, 0])) < 3.0  # starts where the design did
    r = np.linalg.norm(p[:, :2] - CENTRE_MM[:2], axis=1)
    assert abs(np.median(r) - RADIUS_MM) < 5.0 and abs(np.median(p[:, 2]) - CENTRE_MM[2]) < 5.0
    spin = np.linalg.norm(log.omega_hz, axis=1)  # the schedule's rests reach the simulator (its command noise on)
    rest = (log.t_s % 2.0) >= 1.0 + 0.05
    going = (log.t_s % 2.0) < 1.0 - 0.05
    assert np.median(spin[rest]) < 0.25 * np.median(spin[going]), (np.median(spin[rest]), np.median(spin[going]))


def test_a_scenario_whose_path_is_not_a_circle_is_refused(tmp_path):
    bad = tmp_path / "experiment.yaml"
    bad.write_text("path: {plugin: helix, params: {radius_mm: 10}}\n")
    with pytest.raises(ValueError, match=r"experiment\.yaml: the bench flies a circle"):
        blind._scenario_path(bad)

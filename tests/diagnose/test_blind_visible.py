"""The blind bench's visibility measure (benchmarks/blind_visible.py): the simulator's own, on short logs (seconds).

The replay of the full plant from the recorded true states is the closed loop itself; a flow of 5 mm/s is visible
and a lag of a millisecond is not; the bench's floor grows with the camera noise."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import blind_sim  # noqa: E402
import blind_visible  # noqa: E402

SHORT = {"duration_s": 20.0, "logs": 1, "noise_mm": 0.1, "dt_s": 0.02, "outlier_rate": 0.0, "lost_rate": 0.0,
         "near_wall": False}


def _case(**truth):
    return blind_sim.draw_multi_case(5, ["background_flow", "actuation_lag"], **SHORT, **truth)


def test_replaying_the_full_plant_from_the_recorded_states_is_the_closed_loop():
    case = _case(tau_s=0.2)
    res = blind_sim.run_case(case, states=True)
    h = 50
    logs, starts = blind_visible._windows(res["rows"], 2, h, res["p_true_mm"])
    assert len(starts) > 10
    got = blind_visible._replay(case, res, logs, starts, [h], 0, True)[:, -1]
    assert np.abs(got - res["p_true_mm"][starts + h, logs]).max() < 0.01  # mm, over 1 s


def test_a_strong_flow_is_visible_and_a_millisecond_lag_is_not():
    vis = blind_visible.visibility(_case(speed_mm_s=5.0, tau_s=0.001), check_s=20.0)
    assert vis["background_flow"]["visible"] and vis["background_flow"]["ratio"] > 3.0
    assert not vis["actuation_lag"]["visible"] and vis["actuation_lag"]["ratio"] < 0.5


def test_the_bench_floor_grows_with_the_camera_noise():
    quiet, noisy = _case(), blind_sim.draw_multi_case(5, ["background_flow", "actuation_lag"],
                                                      **{**SHORT, "noise_mm": 0.3})
    assert blind_visible.bench_floor_mm(noisy) == pytest.approx(3.0 * blind_visible.bench_floor_mm(quiet))

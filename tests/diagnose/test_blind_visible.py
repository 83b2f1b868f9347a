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


def test_a_pair_that_never_shows_is_drawn_anew_of_the_same_kind(monkeypatch):
    hidden = "anisotropic_drag"  # stands for an effect these logs never show, whatever its draw

    def visibility(case):
        return {e: {"ratio": 0.2 if e == hidden else 3.0, "visible": e != hidden} for e in case.effects}

    monkeypatch.setattr(blind_visible, "visibility", visibility)
    case = blind_sim.draw_multi_case(7, [hidden, "background_flow"], index=4)
    got, draw = blind_visible.visible_case(case, attempts=3)
    assert draw["all_visible"] and hidden not in got.effects and got.index == 4
    assert draw["pairs"][0] == [hidden, "background_flow"] and draw["pairs"][-1] == got.effects
    assert all(e in blind_sim.LIBRARY for e in got.effects)  # two library effects stay two library effects
    assert draw["attempts"] == 3 + 3 * (len(draw["pairs"]) - 2) + 1  # every draw of each invisible pair tried
    outside = blind_sim.draw_multi_case(7, [hidden, "shear_flow"], index=1)
    got, draw = blind_visible.visible_case(outside, attempts=2)
    assert draw["all_visible"] and hidden not in got.effects and any(e not in blind_sim.LIBRARY for e in got.effects)


def test_a_lookalike_case_is_drawn_anew_until_its_effect_shows(monkeypatch):
    seen = []

    def visibility(case):  # the third draw shows it
        seen.append(case)
        return {case.effect: {"ratio": 0.5 * len(seen), "visible": len(seen) == 3}}

    monkeypatch.setattr(blind_visible, "visibility", visibility)
    case = blind_sim.draw_lookalike_case(11, "heading_lag", index=2)
    got, draw = blind_visible.visible_lookalike_case(case, attempts=5)
    assert draw["all_visible"] and draw["attempts"] == draw["chosen_attempt"] == 3 and got is seen[2]
    assert got.effect == "heading_lag" and got.index == 2 and got.truth != case.truth  # the magnitude drawn anew
    seen.clear()
    monkeypatch.setattr(blind_visible, "visibility",
                        lambda c: seen.append(c) or {c.effect: {"ratio": [0.2, 0.9, 0.4][len(seen) - 1],
                                                                "visible": False}})
    got, draw = blind_visible.visible_lookalike_case(case, attempts=3)
    assert not draw["all_visible"] and draw["chosen_attempt"] == 2 and got is seen[1]  # the one that shows most

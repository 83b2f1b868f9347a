"""The blind bench's scoring: joint detectability of several effects, and a discovery on top of chosen effects."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import blind  # noqa: E402


def test_drop_given_the_others_is_what_the_last_form_adds(monkeypatch):
    """Alone, a wall drag lowers the error by 60 % and a latency by 2 %; together by 70 %: given the wall drag, the
    latency takes 1 - 0.30 / 0.40 = 25 % of what remains, and the wall drag 1 - 0.30 / 0.98 of it."""
    forms = {"wall_drag": ("src", "true_wall_drag", Path("a.py")),
             "sensor_latency": ("src", "true_sensor_latency", Path("b.py"))}
    monkeypatch.setattr(blind, "_true_refit", lambda logs, fs: (0.70, {}) if len(fs) == 2 else pytest.fail("refit"))
    given = blind._given_others([], forms, {"wall_drag": 0.60, "sensor_latency": 0.02})
    assert given["sensor_latency"] == pytest.approx(0.25)
    assert given["wall_drag"] == pytest.approx(1 - 0.30 / 0.98)


def test_jointly_detectable_cases_are_scored_apart():
    base = {"group": "multi", "effects": ["wall_drag", "sensor_latency"], "laws": ["exp", ""],
            "hidden_library": ["wall_drag", "sensor_latency"], "lookalikes": [], "seconds": 1.0, "after": None,
            "true_reductions": {"wall_drag": 0.6, "sensor_latency": 0.02}, "draw": {"all_visible": True}}
    masked = {**base, "named_effects": ["wall_drag"], "true_given_others": {"wall_drag": 0.7, "sensor_latency": 0.05}}
    shown = {**base, "named_effects": ["wall_drag"], "true_given_others": {"wall_drag": 0.7, "sensor_latency": 0.25}}
    found = {**shown, "named_effects": ["wall_drag", "sensor_latency"]}
    m = blind.summarise([masked, shown, found])["multi"]
    assert m["detectable"] == 0 and m["detectable_jointly"] == 2  # alone, the latency's 2 % never counts
    assert m["all_named"] == pytest.approx(1 / 3, abs=1e-3) and m["all_named_detectable_jointly"] == pytest.approx(0.5)


def test_each_named_effect_records_the_path_that_named_it():
    """A flow chosen in the rounds, a wall drag weighed given the discovered form, a lag chosen on top of it: the
    record says which, and the case counts among those an effect was named only given a form."""
    diag = {"stepwise": {
        "steps": [{"effects": ["background_flow"], "given": []},
                  {"effects": ["wall_drag"], "given": ["background_flow", "discovered"]}],
        "given_discovered": {"steps": [{"effects": ["actuation_lag", "heading_lag"], "given": ["discovered"]}]}}}
    named = ["background_flow", "wall_drag", "actuation_lag", "quadratic_drag"]
    assert blind._named_by(diag, named) == {"background_flow": "stepwise", "wall_drag": "given_form",
                                            "actuation_lag": "on_top", "quadratic_drag": "other"}
    base = {"group": "multi", "effects": ["wall_drag", "background_flow"], "laws": ["", ""],
            "hidden_library": ["wall_drag", "background_flow"], "lookalikes": [], "seconds": 1.0, "after": None,
            "named_effects": ["background_flow", "wall_drag"], "true_reductions": {}, "draw": {}}
    plain = {**base, "named_by": {"background_flow": "stepwise", "wall_drag": "stepwise"}}
    beside = {**base, "named_by": {"background_flow": "stepwise", "wall_drag": "given_form"}}
    assert blind.summarise([plain, beside, base])["multi"]["named_given_form"] == 1


def test_a_discovery_on_top_of_a_chosen_effect_is_judged_with_it():
    """A water turning about a vertical axis: a background flow takes 80 % of the error, the discovered form 40 %
    of what it leaves (88 % together, against the true form's 90 %). Alone, 40 % would be under half of 90 %."""
    rec = {"group": "outside", "effect": "rotating_flow", "law": "", "named": "background_flow",
           "named_effects": ["background_flow"], "true_reduction": 0.9, "seconds": 1.0, "chosen_reduction": 0.8,
           "discovered": {"status": "found", "reduction": 0.4, "t_stat": 5.0}}
    assert blind.summarise([rec])["outside"]["discovered_ok"] == 1.0
    assert blind.summarise([{**rec, "chosen_reduction": 0.0}])["outside"]["discovered_ok"] == 0.0


def test_resume_keeps_a_multi_case_whose_pair_was_replaced(tmp_path):
    """Seed 57's multi_003 was drawn as an anisotropic drag and an actuation lag, which never showed, and ran as a
    wall drag and a camera latency: --resume keeps it, diagnoses an errored case again, and refuses a record of
    another draw."""
    import json

    import blind_sim

    case = blind_sim.draw_multi_cases(10, 57)[3]
    assert case.effect == "anisotropic_drag+actuation_lag"
    ran = {"group": "multi", "index": 3, "effect": "wall_drag+sensor_latency", "seed": case.seed,
           "draw": {"pairs": [["anisotropic_drag", "actuation_lag"], ["wall_drag", "sensor_latency"]]}}
    lines = tmp_path / "cases.jsonl"
    lines.write_text(json.dumps(ran) + "\n")
    assert blind._finished(lines, [case], ["multi"]) == [ran]
    lines.write_text(json.dumps({**ran, "error": "LinAlgError: Singular matrix"}) + "\n")
    assert blind._finished(lines, [case], ["multi"]) == []
    lines.write_text(json.dumps({**ran, "seed": case.seed + 1}) + "\n")
    with pytest.raises(SystemExit, match="not in this draw"):
        blind._finished(lines, [case], ["multi"])

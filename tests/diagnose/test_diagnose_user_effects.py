"""User effects: a file registering an effect through the hook is ranked like the library's."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim_plugins.diagnose.pipeline import Settings, run

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).parent / "data"


def test_example_effect_file_explains_the_plant_wall_drag(plant_logs, fresh_plugins):
    r = run(plant_logs("wall_drag"), settings=Settings(effects_files=[ROOT / "examples" / "my_effect.py"],
                                                       candidates=["wall_drag", "wall_drag_exp"])).json
    assert r["file_effects"] == ["wall_drag_exp"]
    ranked = {e["effect"]: e for e in r["ranking"]}
    assert ranked["wall_drag_exp"]["reduction"] >= 0.30
    assert r["verdict"]["effect"] in ("wall_drag_exp", "wall_drag")
    # the plant's law is exponential with an 8 mm decay length
    assert ranked["wall_drag_exp"]["params"]["wall_drag_exp.ell"]["value"] == pytest.approx(8.0, rel=0.35)


@pytest.fixture(scope="module")
def swirl_logs(tmp_path_factory):
    """Synthetic logs (the paper's model as the plant) with water turning about z at 0.12 rad/s."""
    from cosim.contract import plugins
    from cosim.contract.plugins import lookup
    from cosim_plugins.identify import synthetic as syn
    from cosim_plugins.identify.effect import load_effect_files, resolve

    plugins.reset()
    load_effect_files([DATA / "swirl_effect.py"])
    physical = lookup("model", "physical")
    plant = physical.from_params({**syn.TRUE_PARAMS, "swirl.omega": 0.12}, terms=resolve(["swirl"]))
    plugins.reset()
    cases = syn.paper_cases()
    cases = {k: cases[k] for k in ("circle_+0", "racetrack_+0", "circle_+45")}
    return syn.write_cases(tmp_path_factory.mktemp("swirl"), plant.predict, 2500, cases, seed=5,
                           bias_hz=(0.0, 0.0, 2.4), defects=syn.Defects(noise_mm=0.1))


def test_effect_not_in_the_library_is_found_through_a_user_file(swirl_logs, fresh_plugins):
    lib = run(swirl_logs, settings=Settings(candidates=["background_flow", "gradient_force", "wall_drag"])).json
    assert lib["verdict"]["effect"] is None  # no library effect explains a swirl
    assert lib["ranking"][0]["reduction"] < 0.3
    mine = run(swirl_logs, settings=Settings(effects_files=[DATA / "swirl_effect.py"],
                                             candidates=["swirl", "background_flow", "gradient_force"])).json
    best = mine["ranking"][0]
    assert best["effect"] == "swirl" and mine["verdict"]["effect"] == "swirl"
    assert best["reduction"] >= 0.30
    assert best["params"]["swirl.omega"]["value"] == pytest.approx(0.12, rel=0.15)

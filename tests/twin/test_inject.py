"""Injected against native on the racetrack (short runs): the FMU's background flow and wall drag vs the
same laws applied through its external force input by twin.effect; mean distance within 0.05 mm."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from cosim.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = ROOT / "cosim_plugins" / "scenarios"
TARGET_MM = 0.05
ISO = {"anisotropic_drag_on": False}  # the library's scalar-drag forms equal the FMU's laws only then


def _run(tmp: Path, name: str, scenario: dict) -> np.ndarray:
    """Run a scenario dict for 2 s; the plant's true positions (n, 3) [m]."""
    scenario["duration_s"] = 2.0
    path = tmp / f"{name}.yaml"
    path.write_text(yaml.safe_dump(scenario))
    assert main(["run", str(path), "--out", str(tmp / name), "--quiet"]) == 0
    return np.load(tmp / name / "trace.npz")["plant.position"]


def _pair(tmp, plant, native, effects, values, coupling="linear", plugins=(), floor=False, component=None):
    nat = yaml.safe_load((SCENARIOS / "racetrack.yaml").read_text())
    inj = yaml.safe_load((SCENARIOS / "twin_racetrack.yaml").read_text())
    for sc in (nat, inj):
        sc["components"]["plant"]["params"].update(plant)
        if floor:  # 3-5 mm above the floor, where the wall drag acts
            sc["path"]["params"]["z_mm"] = -70.0
            sc["components"]["plant"]["params"]["p0_z"] = -0.070
    nat["components"]["plant"]["params"].update(native)
    inj["components"]["effect"]["params"].update(effects=effects, effect_params=values, coupling=coupling)
    if plugins:
        inj["plugins"] = list(plugins)
    if component:  # another effect component, with the plant's axis wired in
        inj["components"]["effect"]["plugin"] = component["plugin"]
        inj["components"]["effect"]["inputs"]["axis"] = component["axis"]
    a, b = _run(tmp, "native", nat), _run(tmp, "injected", inj)
    return np.linalg.norm(a - b, axis=1) * 1e3


def test_the_forced_plant_with_nothing_applied_is_the_plant(use_fmu, tmp_path):
    d = _pair(tmp_path, {}, {}, ["background_flow"], {"background_flow": {"w_x": 0.0}})
    assert np.all(d == 0.0)


def test_background_flow_injected_matches_the_fmus_own(use_fmu, tmp_path):
    d = _pair(tmp_path, ISO, {"background_flow_on": True, "flow_x": 0.002}, ["background_flow"],
              {"background_flow": {"w_x": 2.0, "w_y": 0.0}})
    assert d.mean() < TARGET_MM
    # the flow matters: without it the runs part by far more than the target
    none = _pair(tmp_path, ISO, {"background_flow_on": True, "flow_x": 0.002}, ["background_flow"],
                 {"background_flow": {"w_x": 0.0}})
    assert none.mean() > 10 * TARGET_MM


def test_wall_drag_injected_matches_the_fmus_own_near_the_floor(use_fmu, tmp_path):
    from cosim_plugins.twin.match import wall_drag_exp_like_fmu

    exp = wall_drag_exp_like_fmu()
    d = _pair(tmp_path, ISO, {"wall_drag_on": True}, ["wall_drag_exp"], {"wall_drag_exp": exp},
              plugins=[str(ROOT / "examples" / "my_effect.py")], floor=True)
    assert d.mean() < TARGET_MM
    none = _pair(tmp_path, ISO, {"wall_drag_on": True}, ["wall_drag_exp"], {"wall_drag_exp": {"c": 0.0}},
                 plugins=[str(ROOT / "examples" / "my_effect.py")], floor=True)
    assert none.mean() > 10 * TARGET_MM


def test_the_fmus_own_laws_injected_on_the_plants_axis_match_the_anisotropic_plant(use_fmu, tmp_path):
    """The plant as shipped (anisotropic drag, heading dynamics): the FMU-law effects through twin.effect_on_axis."""
    from cosim_plugins.twin.fmu_laws import BACKGROUND_FLOW, WALL_DRAG, effect_params

    values = effect_params({"flow_x": 0.002})
    on_axis = {"plugin": "twin.effect_on_axis", "axis": "plant.axis"}
    for native, name, floor in (({"background_flow_on": True, "flow_x": 0.002}, BACKGROUND_FLOW, False),
                                ({"wall_drag_on": True}, WALL_DRAG, True)):
        d = _pair(tmp_path, {}, native, [name], {name: values[name]}, floor=floor, component=on_axis)
        assert d.mean() < 0.1 * TARGET_MM
        none = _pair(tmp_path, {}, native, [name], {name: {**values[name], "drag_axial": 0.0}}, floor=floor,
                     component=on_axis)
        assert none.mean() > 10 * TARGET_MM

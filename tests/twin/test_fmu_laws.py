"""The FMU-law effects (cosim_plugins/twin/fmu_laws.py) equal plant.c's own wall drag and background flow at
sample states, in SI, the law computed here independently from the C source's formulas; and
twin.effect_on_axis evaluates them about the plant's axis, not the command's."""

from __future__ import annotations

import numpy as np
import pytest

from cosim_plugins.identify.effect import known_effects
from cosim_plugins.twin.component import EffectInjector, EffectOnPlantAxis
from cosim_plugins.twin.fmu_laws import BACKGROUND_FLOW, WALL_DRAG, effect_params
from cosim_plugins.twin.units import fmu_defaults

RNG = np.random.default_rng(7)
#: sample states [m], [m/s], axes (unit): near the floor, in a corner, at the centre, near +x, random
P = np.array([[0.01, -0.02, -0.070], [0.071, 0.0705, -0.069], [0.0, 0.0, 0.0], [0.0726, 0.03, 0.0],
              *RNG.uniform(-0.0737, 0.0737, (4, 3))])
V = RNG.normal(0.0, 0.02, (len(P), 3))
A = RNG.normal(size=(len(P), 3))
A /= np.linalg.norm(A, axis=1, keepdims=True)


def plant_c_force(p, v, a, prm, wall_on, flow_on):
    """plant.c's drag term [N]: -fw (c_ax v_ax a + c_perp (vr - v_ax a)), vr = v - flow, fw = wall_factor."""
    fw = 1.0
    if wall_on:
        lim, s = prm["tank_half"] - prm["wall_margin"], 0.0
        for k in range(3):
            s += np.exp(-max(lim - p[k], 0.0) / prm["wall_drag_length"])
            s += np.exp(-max(lim + p[k], 0.0) / prm["wall_drag_length"])
        fw = 1.0 + prm["wall_drag_gain"] * s
    vr = v - (np.array([prm["flow_x"], prm["flow_y"], prm["flow_z"]]) if flow_on else 0.0)
    c_ax = prm["drag_axial"]
    c_perp = c_ax * prm["anisotropy_ratio"] if prm["anisotropic_drag_on"] else c_ax
    v_ax = vr @ a
    return -fw * (c_ax * v_ax * a + c_perp * (vr - v_ax * a))


def _injector(cls, name, fmu):
    comp = cls()
    comp.setup({"dt": 0.02, "effects": [name], "effect_params": {name: effect_params(fmu)[name]}},
               np.random.default_rng(0))
    return comp


FMUS = [{}, {"anisotropic_drag_on": 0.0}, {"flow_x": -0.003, "flow_y": 0.001, "flow_z": 0.0005,
                                             "wall_drag_gain": 3.0, "wall_drag_length": 0.004, "drag_axial": 6e-5}]


@pytest.mark.parametrize("fmu", FMUS)
@pytest.mark.parametrize("name", [WALL_DRAG, BACKGROUND_FLOW])
def test_the_effect_is_the_fmus_law_less_its_law_without_the_switch(name, fmu):
    prm = {**fmu_defaults(), **fmu}
    if name == BACKGROUND_FLOW and not fmu:
        prm["flow_y"], fmu = 0.0015, {"flow_y": 0.0015}  # a flow across x too
    comp = _injector(EffectInjector, name, fmu)
    wall, flow = name == WALL_DRAG, name == BACKGROUND_FLOW
    for p, v, a in zip(P, V, A):
        omega = 2 * np.pi * 12.0 * a * (-1.0 if p[0] > 0 else 1.0)  # the command along the axis, either sign
        out = comp.step(0.0, {"position": p, "velocity": v, "omega": omega})
        want = plant_c_force(p, v, a, prm, wall, flow) - plant_c_force(p, v, a, prm, False, False)
        assert np.allclose(out["force"], want, rtol=1e-9, atol=1e-18)
        # linear coupling: dF/dv is the law's own (the force is linear in v)
        dfdv = np.array([(plant_c_force(p, v + e, a, prm, wall, flow) - plant_c_force(p, v + e, a, prm, False, False)
                          - want) / 1e-6 for e in np.eye(3) * 1e-6]).T
        assert np.allclose(out["force_dv"].reshape(3, 3), dfdv, rtol=1e-5, atol=1e-12)
    assert np.abs(out["force"]).max() > 0  # not a vacuous zero


def test_the_wall_drag_is_large_near_a_wall_and_its_position_derivative_follows_the_law():
    prm = fmu_defaults()
    comp = _injector(EffectInjector, WALL_DRAG, {})
    p, v, a = np.array([0.0, 0.0, -0.0705]), np.array([0.01, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])
    out = comp.step(0.0, {"position": p, "velocity": v, "omega": a})
    assert out["force"][0] < -0.3 * prm["drag_axial"] * v[0]  # a third of the drag or more, 4.5 mm off the floor
    h = 1e-6
    dz = (plant_c_force(p + [0, 0, h], v, a, prm, True, False) - plant_c_force(p - [0, 0, h], v, a, prm, True, False))
    assert out["force_dp"].reshape(3, 3)[0, 2] == pytest.approx(dz[0] / (2 * h), rel=1e-4)


def test_on_axis_the_law_turns_with_the_plants_axis_not_the_command():
    prm = {**fmu_defaults(), "flow_y": 0.0015}
    cmd, axis = np.array([0.0, 60.0, 0.0]), np.array([np.sqrt(0.5), np.sqrt(0.5), 0.0])
    state = {"position": np.zeros(3), "velocity": np.zeros(3), "omega": cmd, "axis": axis}
    on_axis = _injector(EffectOnPlantAxis, BACKGROUND_FLOW, {"flow_y": 0.0015}).step(0.0, state)["force"]
    on_cmd = _injector(EffectInjector, BACKGROUND_FLOW, {"flow_y": 0.0015}).step(0.0, state)["force"]
    assert np.allclose(on_axis, plant_c_force(np.zeros(3), np.zeros(3), axis, prm, False, True)
                       - plant_c_force(np.zeros(3), np.zeros(3), axis, prm, False, False), rtol=1e-9)
    assert not np.allclose(on_axis, on_cmd, rtol=1e-3)  # the command's axis gives another force
    # a zero command keeps the axis
    zero = _injector(EffectOnPlantAxis, BACKGROUND_FLOW, {"flow_y": 0.0015}).step(0.0, {**state, "omega": np.zeros(3)})
    assert np.allclose(zero["force"], on_axis, rtol=1e-9)


def test_the_fmu_laws_are_the_twins_not_the_effect_librarys():
    assert WALL_DRAG not in known_effects() and BACKGROUND_FLOW not in known_effects()  # diagnose never ranks them


def test_on_axis_at_midpoint_the_law_sees_the_axis_half_a_step_on():
    prm = {**fmu_defaults(), "flow_y": 0.0015}
    law = {"flow_y": 0.0015}
    first, second = np.array([1.0, 0.0, 0.0]), np.array([np.cos(0.1), np.sin(0.1), 0.0])  # turned 0.1 rad
    comp = _injector(EffectOnPlantAxis, BACKGROUND_FLOW, law)
    start = _injector(EffectOnPlantAxis, BACKGROUND_FLOW, law)
    start.setup({"dt": 0.02, "effects": [BACKGROUND_FLOW], "axis_at": "start",
                 "effect_params": {BACKGROUND_FLOW: effect_params(law)[BACKGROUND_FLOW]}}, np.random.default_rng(0))
    state = {"position": np.zeros(3), "velocity": np.zeros(3), "omega": np.array([0.0, 60.0, 0.0])}
    for c in (comp, start):
        c.step(0.0, {**state, "axis": first})
    mid, at_start = (c.step(0.02, {**state, "axis": second})["force"] for c in (comp, start))
    a = np.array([np.cos(0.15), np.sin(0.15), 0.0])  # half a step on: 0.15 rad (to second order)
    zero = np.zeros(3)
    assert np.allclose(mid, plant_c_force(zero, zero, a, prm, False, True), rtol=1e-3)
    assert np.allclose(at_start, plant_c_force(zero, zero, second, prm, False, True), rtol=1e-9)


def test_on_axis_rejects_a_bad_axis_at_and_a_non_unit_axis():
    from cosim.contract.component import ComponentError

    with pytest.raises(ComponentError, match="axis_at='end'"):
        EffectOnPlantAxis.validate_params({"dt": 0.02, "effects": [BACKGROUND_FLOW], "axis_at": "end"})
    comp = _injector(EffectOnPlantAxis, BACKGROUND_FLOW, {})
    with pytest.raises(ComponentError, match="not a unit vector"):
        comp.step(0.0, {"position": np.zeros(3), "velocity": np.zeros(3), "omega": np.ones(3), "axis": np.zeros(3)})

"""twin.effect: what it applies (units at the edge, a saved model's effects) and its errors (an unknown
effect, a transform, a model file whose code is not trusted)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cosim.contract.component import ComponentError
from cosim_plugins.twin.component import EffectInjector
from cosim_plugins.twin.units import host_params_from_fmu


def _setup(**params):
    comp = EffectInjector()
    comp.setup({"dt": 0.02, **params}, np.random.default_rng(0))
    return comp


def test_the_background_flow_force_is_drag_times_flow_in_newtons():
    comp = _setup(effects=["background_flow"], effect_params={"background_flow": {"w_x": 2.0, "w_y": -1.0}})
    out = comp.step(0.02, {"position": np.zeros(3), "velocity": np.array([1e-3, 0, 0]),
                           "omega": np.array([2 * np.pi * 10, 0, 0])})
    # Cd1 = drag_axial = 8e-5 N s/m; w = (2, -1, 0) mm/s -> 8e-5 * (0.002, -0.001, 0) N
    assert np.allclose(out["force"], [1.6e-7, -0.8e-7, 0.0], rtol=1e-9, atol=1e-15)
    assert np.allclose(out["force_dv"], 0.0, atol=1e-12)


def test_the_wall_drag_derivative_is_minus_its_drag_coefficient_in_si():
    comp = _setup(effects=["wall_drag"], effect_params={"wall_drag": {"c": 0.4, "ell": 2.0}})
    p = np.array([0.0, 0.0, -0.071])   # 4 mm from the floor
    out = comp.step(0.02, {"position": p, "velocity": np.array([1e-3, 0, 0]), "omega": np.zeros(3)})
    kappa = 0.4 * 2.0 / (4.0 + 2.0) * 1e-3   # uN s/mm -> N s/m
    assert np.allclose(out["force_dv"].reshape(3, 3), -kappa * np.eye(3), rtol=1e-6)
    assert out["force"][0] == pytest.approx(-kappa * 1e-3, rel=1e-9)
    held = _setup(effects=["wall_drag"], effect_params={"wall_drag": {"c": 0.4, "ell": 2.0}}, coupling="held")
    assert np.all(held.step(0.02, {"position": p, "velocity": np.ones(3), "omega": np.zeros(3)})["force_dv"] == 0)


def test_host_parameters_come_from_the_fmus_law():
    host = host_params_from_fmu()
    assert host["Cd1"] == pytest.approx(0.08)                  # 8e-5 N s/m in uN s/mm
    assert host["k"] == pytest.approx(3.2e-8 * 2 * np.pi * 1e6)  # N per rad/s of spin -> uN/Hz
    assert host["Fvs"] == pytest.approx(-(12.4e-6 - 998.2 * 12.38e-9) * 9.81 * 1e6)


def test_an_unknown_effect_name_is_refused_with_the_known_ones():
    with pytest.raises(ComponentError, match=r"unknown effect 'swril'.*background_flow"):
        EffectInjector.validate_params({"effects": ["swril"]})


@pytest.mark.parametrize("params, match", [
    ({"effects": ["sensor_latency"]}, "not a force"),
    ({"effects": ["wall_drag"], "effect_params": {"wall_drag": {"cc": 1.0}}}, r"unknown effect parameter.*wall_drag.c"),
    ({"effects": ["wall_drag"], "effect_params": {"wall_drag": {"c": -1.0}}}, "outside the effect's range"),
    ({"effects": ["wall_drag"], "coupling": "cubic"}, "coupling"),
    ({}, "give the effects"),
    ({"effects": ["wall_drag"], "host": {"Cd2": 1.0}}, "host: unknown"),
])
def test_bad_parameters_are_refused_naming_them(params, match):
    with pytest.raises(ComponentError, match=match):
        EffectInjector.validate_params(params)


def _physical_model(path):
    from cosim_plugins.identify.effect import resolve
    from cosim_plugins.models.physical import PhysicalModel

    model = PhysicalModel.from_params({"k": 0.2, "Cd1": 0.07, "background_flow.w_x": 1.5},
                                      terms=resolve(["background_flow"]))
    return model.save(path)


def test_a_saved_model_applies_its_effects_with_its_own_parameters(tmp_path):
    comp = _setup(model=str(_physical_model(tmp_path / "m.npz")))
    out = comp.step(0.02, {"position": np.zeros(3), "velocity": np.zeros(3), "omega": np.zeros(3)})
    assert np.allclose(out["force"], [0.07 * 1.5 * 1e-6, 0.0, 0.0], rtol=1e-9)  # the model's Cd1 and w_x


def test_a_model_file_whose_code_is_not_trusted_is_refused_and_its_code_never_runs(tmp_path, monkeypatch):
    monkeypatch.delenv("COSIM_TRUST_MODEL_CODE", raising=False)
    path = _physical_model(tmp_path / "m.npz")
    marker = tmp_path / "ran"
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    header = json.loads(str(arrays.pop("__meta__")))
    header["meta"]["terms"] = ["swirl_x"]
    header["meta"]["effect_sources"] = {"swirl_x": f"open({str(marker)!r}, 'w').write('ran')\n"}
    np.savez(tmp_path / "edited.npz", __meta__=np.array(json.dumps(header)), **arrays)
    with pytest.raises(ComponentError, match=r"edited.npz.*--trust-model-code"):
        EffectInjector.validate_params({"model": str(tmp_path / "edited.npz")})
    assert not marker.exists()


def test_a_model_without_effects_is_refused(tmp_path):
    from cosim_plugins.models.physical import PhysicalModel

    path = PhysicalModel.from_params({"k": 0.2}).save(tmp_path / "plain.npz")
    with pytest.raises(ComponentError, match="no force effects"):
        EffectInjector.validate_params({"model": str(path)})

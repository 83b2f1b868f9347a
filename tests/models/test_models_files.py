"""Model files: round trip for every built-in model, clear errors for the wrong kind or version."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.contract.errors import UserError
from cosim.contract.plugins import registry
from cosim_plugins.identify.model import load_model
from cosim_plugins.models.mlp import MLPModel
from cosim_plugins.models.physical import PhysicalModel
from cosim_plugins.models.sindy import SindyLinear, SindyNonlinear

QUICK = {"physical": dict(max_windows=200, max_nfev=3), "mlp": dict(epochs=2)}


def test_registered_models():
    assert {"physical", "sindy-linear", "sindy-nonlinear", "mlp"} <= set(registry("model"))


@pytest.mark.parametrize("cls", [PhysicalModel, SindyLinear, SindyNonlinear, MLPModel], ids=lambda c: c.name)
def test_round_trip_gives_identical_predictions(rich_data, tmp_path, cls):
    train, test = rich_data
    model = cls(**QUICK.get(cls.name, {})).fit(train)
    path = model.save(tmp_path / f"{cls.name}.npz")
    loaded = load_model(path)
    assert type(loaded) is cls
    X, U, _ = test.pairs()
    np.testing.assert_array_equal(loaded.predict(X, U, 0.02), model.predict(X, U, 0.02))
    np.testing.assert_array_equal(loaded.predict(X[0], U[0], 0.02), model.predict(X[0], U[0], 0.02))
    assert loaded.params() == model.params() and loaded.n_params == model.n_params
    assert loaded.train_time_s == model.train_time_s


def test_wrong_kind_version_or_file(rich_data, tmp_path, monkeypatch):
    train, _ = rich_data
    path = SindyLinear().fit(train).save(tmp_path / "lin.npz")
    with pytest.raises(UserError, match="holds a 'sindy-linear' model, not 'mlp'"):
        MLPModel.load(path)
    monkeypatch.setattr(SindyLinear, "version", 2)
    with pytest.raises(UserError, match="format version 1 is not supported .*reads version 2"):
        SindyLinear.load(path)
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip")
    with pytest.raises(UserError, match="is not a cosim model file"):
        load_model(junk)
    with pytest.raises(UserError, match="does not exist"):
        load_model(tmp_path / "missing.npz")


def test_a_model_with_an_effect_from_a_users_file_opens_without_that_file(tmp_path, monkeypatch):
    """The file's source travels inside the model: a fresh process (here: a reset plugin manager, the file moved
    away) opens it, when the user trusts the code it carries, and predicts the same; a built-in effect needs no
    source (tests/security/test_model_files.py: without trust it refuses)."""
    import shutil
    from pathlib import Path

    from cosim.contract import plugins
    from cosim_plugins.identify.effect import load_effect_files, resolve

    src = tmp_path / "swirl_effect.py"
    shutil.copy(Path(__file__).parents[1] / "diagnose" / "data" / "swirl_effect.py", src)
    plugins.reset()
    try:
        load_effect_files([src])
        terms = resolve(["swirl", "background_flow"])
        model = PhysicalModel.from_params({"k": 0.2, "Cd1": 0.07, "swirl.omega": 0.3, "background_flow.w_x": 2.0},
                                          terms=terms)
        path = model.save(tmp_path / "swirl.npz")
        src.unlink()
        plugins.reset()
        with pytest.raises(UserError, match="effect 'swirl' is Python code carried inside the model file"):
            load_model(path)
        plugins.reset()
        monkeypatch.setenv("COSIM_TRUST_MODEL_CODE", "1")
        loaded = load_model(path)
        assert [t.name for t in loaded.terms] == ["swirl", "background_flow"]
        x = np.array([[10.0, -20.0, 5.0, 1.0, 2.0, 0.0]])
        u = np.array([[3.0, 0.0, 4.0]])
        np.testing.assert_array_equal(loaded.predict(x, u, 0.02), model.predict(x, u, 0.02))
        assert loaded.params()["swirl.omega"] == 0.3
    finally:
        plugins.reset()


def test_an_effect_file_written_before_the_rename_still_loads(tmp_path):
    """Effect files (and the sources saved models carry) written when the class was called ``Param`` load as they
    did: the old name is the same class as :class:`EffectParam`."""
    from pathlib import Path

    from cosim.contract import plugins
    from cosim_plugins.identify.effect import EffectParam, load_effect_files, resolve

    text = (Path(__file__).parents[1] / "diagnose" / "data" / "swirl_effect.py").read_text()
    assert "EffectParam" in text
    src = tmp_path / "old_swirl.py"
    src.write_text(text.replace("EffectParam", "Param"))
    plugins.reset()
    try:
        load_effect_files([src])
        (swirl,) = resolve(["swirl"])
        assert swirl.params and all(type(p) is EffectParam for p in swirl.params)
    finally:
        plugins.reset()

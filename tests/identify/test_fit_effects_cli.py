"""`cosim fit --effects NAME` and `--effects-file FILE.py` end to end: logs of a plant with a known extra
force, fitted with that effect, give back its parameter; the saved model carries the effect."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.contract import plugins
from cosim_plugins.identify import synthetic as syn
from cosim_plugins.identify.effect import load_effect_files, resolve
from cosim_plugins.identify.model import load_model
from cosim_plugins.identify.synthetic import TRUE_PARAMS
from cosim_plugins.models.physical import PhysicalModel

PUSH_FILE = Path(__file__).parent / "data" / "push_effect.py"
BIAS_HZ = (0.0, 0.0, 2.4)


@pytest.fixture
def fresh_plugins():
    plugins.reset()
    yield
    plugins.reset()


def _logs(folder: Path, effect_name: str, params: dict) -> list[Path]:
    """Two 600-row logs of the paper's plant plus ``effect_name`` with ``params`` (by full name)."""
    plant = PhysicalModel.from_params({**TRUE_PARAMS, **params}, terms=resolve([effect_name]))
    cases = {k: syn.paper_cases()[k] for k in ("circle_+0", "racetrack_+45")}
    return syn.write_cases(folder, plant.predict, 600, cases, seed=4, bias_hz=BIAS_HZ)


def _fit(tmp_path, logs, *args) -> dict:
    out = tmp_path / "models"
    assert main(["fit", *map(str, logs), "--model", "physical", "--out", str(out), *args]) == 0
    return {"dir": out, "params": json.loads((out / "fit.json").read_text())["models"]["physical"]["params"]}


def test_fit_with_a_built_in_effect_recovers_its_parameters(tmp_path, capsys, fresh_plugins):
    truth = {"background_flow.w_x": 6.0, "background_flow.w_y": -4.0}  # mm/s
    logs = _logs(tmp_path / "logs", "background_flow", truth)
    fitted = _fit(tmp_path, logs, "--effects", "background_flow")
    for name, value in truth.items():
        assert fitted["params"][name] == pytest.approx(value, abs=0.5), (name, fitted["params"])
    model = load_model(fitted["dir"] / "physical.npz")
    assert [t.name for t in model.terms] == ["background_flow"]
    assert "background_flow.w_x=" in capsys.readouterr().out


def test_fit_with_an_effect_from_a_file_recovers_its_parameter(tmp_path, capsys, fresh_plugins):
    load_effect_files([PUSH_FILE])  # to simulate the logs; the command loads it again from --effects-file
    logs = _logs(tmp_path / "logs", "test_push", {"test_push.f_x": 3.0})
    plugins.reset()
    fitted = _fit(tmp_path, logs, "--effects-file", str(PUSH_FILE), "--effects", "test_push")
    assert fitted["params"]["test_push.f_x"] == pytest.approx(3.0, abs=0.4), fitted["params"]
    without = _fit(tmp_path / "plain", logs)
    assert "test_push.f_x" not in without["params"]


@pytest.mark.parametrize("args, message", [
    (["--effects", "no_such_effect"], "no_such_effect"),
    (["--effects", "background_flow", "--model", "sindy-linear"],
     "none of the models sindy-linear can include effects"),
    (["--effects-file", "missing_effects.py", "--effects", "test_push"], "missing_effects.py"),
])
def test_fit_effect_errors_are_named(tmp_path, capsys, fresh_plugins, args, message):
    logs = _logs(tmp_path / "logs", "background_flow", {})
    args = [a if a != "missing_effects.py" else str(tmp_path / a) for a in args]
    model = [] if "--model" in args else ["--model", "physical"]
    assert main(["fit", *map(str, logs), *model, "--out", str(tmp_path / "m"), *args]) == 2
    assert message in capsys.readouterr().err

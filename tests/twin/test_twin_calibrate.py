"""cosim twin calibrate: a parameter of the FMU recovered from logs the FMU wrote (within its reported standard
error), the twin.yaml it writes runs, and bad input names the problem."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cosim.cli.main import main
from cosim.contract.errors import UserError
from cosim_plugins.plant.build import ENV_FMU
from cosim_plugins.twin.calibrate import Settings, calibrate
from cosim_plugins.twin.scenario import DEFAULT_SCENARIO as RACETRACK
from cosim_plugins.twin.scenario import write_twin

TRUE_DRAG = 1.2e-4  # N s/m; the FMU's default is 8e-5


@pytest.fixture(scope="module")
def fmu_log(tmp_path_factory, twin_fmu):
    """A 30 s racetrack log of the lab's loop on the FMU with drag_axial = TRUE_DRAG (everything else default)."""
    out = tmp_path_factory.mktemp("fmu_log")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(ENV_FMU, str(twin_fmu))
        assert main(["run", str(RACETRACK), "--out", str(out / "run"), "--quiet", "--set", "duration_s=30",
                     "--set", f"components.plant.params.drag_axial={TRUE_DRAG}"]) == 0
    return out / "run" / "log.csv"


@pytest.fixture(scope="module")
def calibration(fmu_log, twin_fmu):
    """The drag and the propulsion calibrated from the FMU's defaults (no host fit), the rest held at the truth."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(ENV_FMU, str(twin_fmu))
        return calibrate([fmu_log], settings=Settings(host_fit=False, paper_forces=False,
                                                      free=["drag_axial", "prop_coeff"], train_chunks=10, max_nfev=5))


def test_the_drag_the_fmu_wrote_its_log_with_is_recovered_within_its_standard_error(calibration):
    value, std = calibration.values["drag_axial"], calibration.std["drag_axial"]
    assert 0.0 < std < 0.1 * value  # determined, so the check below can fail
    assert abs(value - TRUE_DRAG) <= 3.0 * std, (value, std)
    # the default 8e-5 is far outside: the fit moved it
    assert abs(8e-5 - TRUE_DRAG) > 3.0 * std
    r = calibration.result
    assert r["held_out_error_mm"]["1.0"] < r["uncalibrated_error_mm"]["1.0"]
    assert calibration.switches == {"actuation_lag_on": True, "heading_dynamics_on": True}  # the FMU's own


def test_twin_yaml_runs_the_lab_loop_on_the_calibrated_twin(calibration, tmp_path, use_fmu):
    path = write_twin(calibration, tmp_path / "twin")
    text = path.read_text()
    assert "drag_axial: " in text and "# +- " in text  # every calibrated value with its uncertainty
    assert main(["run", str(path), "--out", str(tmp_path / "run"), "--quiet", "--set", "duration_s=1"]) == 0
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["status"] == "ok"
    assert np.isfinite(summary["tracking_error_mm"]["mean"])


def test_a_missing_log_is_named(tmp_path, capsys):
    missing = tmp_path / "nope.csv"
    assert main(["twin", "calibrate", str(missing), "--out", str(tmp_path / "o")]) == 2
    assert f"log {missing}: no such file" in capsys.readouterr().err


def test_an_unknown_effect_is_named_with_the_known_ones(fmu_log):
    with pytest.raises(UserError, match="no_such_effect"):
        calibrate([fmu_log], settings=Settings(effects=["no_such_effect"]))


def test_a_transform_without_a_twin_counterpart_and_effects_with_a_model_are_refused(fmu_log, tmp_path):
    with pytest.raises(UserError, match="--effects or --model, not both"):
        calibrate([fmu_log], settings=Settings(effects=["wall_drag"], model=str(tmp_path / "m.npz")))
    with pytest.raises(UserError, match="--jobs 0"):
        calibrate([fmu_log], settings=Settings(jobs=0))


def test_an_unknown_free_parameter_is_named(fmu_log):
    with pytest.raises(UserError, match="free: unknown parameter.*drag_sideways"):
        calibrate([fmu_log], settings=Settings(host_fit=False, free=["drag_sideways"]))


def test_a_saved_model_starts_the_calibration_and_its_effects_reach_twin_yaml(fmu_log, tmp_path, use_fmu,
                                                                               monkeypatch):
    """cosim twin calibrate --model M.npz end to end: the model's effect (a flow the FMU's log does not have)
    starts at the model's value, is calibrated, and the written twin.yaml applies it in cosim run."""
    import functools

    from cosim_plugins.identify.effect import resolve
    from cosim_plugins.models.physical import PhysicalModel
    from cosim_plugins.twin import calibrate as calmod

    model = PhysicalModel.from_params({"k": 0.2, "Cd1": 0.12, "Fvs": -0.3, "background_flow.w_x": 0.8},
                                      terms=resolve(["background_flow"])).save(tmp_path / "m.npz")
    # a short polish: the test checks the wiring, not the figures
    monkeypatch.setattr(calmod, "Settings", functools.partial(calmod.Settings, train_chunks=6, max_nfev=2))
    monkeypatch.setattr(calmod, "SWITCH_NFEV", 1)
    out = tmp_path / "twin"
    assert main(["twin", "calibrate", str(fmu_log), "--model", str(model), "--jobs", "1", "--out", str(out)]) == 0
    r = json.loads((out / "twin.json").read_text())
    assert r["effects"] == ["background_flow"]
    assert r["host_model"] == f"model file {model}"
    flow = r["params"]["background_flow.w_x"]
    assert flow["start"] == pytest.approx(0.8)  # the model's value started the fit
    assert flow["value"] != pytest.approx(0.8)  # and the polish moved it
    assert r["params"]["drag_axial"]["start"] == pytest.approx(1.2e-4)  # the model's Cd1 [uN s/mm] in N s/m
    text = (out / "twin.yaml").read_text()
    assert "effects: [background_flow, twin_paper_forces]" in text
    written = float(f"{flow['value']:.6g}")
    assert f"w_x: {written!r}" in text
    assert main(["run", str(out / "twin.yaml"), "--out", str(tmp_path / "run"), "--quiet", "--set",
                 "duration_s=1"]) == 0
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["status"] == "ok"

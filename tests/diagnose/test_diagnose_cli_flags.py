"""`cosim diagnose --validate --discover --model` from the command line, end to end on two short synthetic logs
(the plain paper model as the plant, 0.1 mm camera noise; one diagnosis of ~20 s for the module): the flags reach
the pipeline and its outputs, and bad values are refused by name."""

from __future__ import annotations

import contextlib
import io
import json

import pytest

from cosim.cli import main
from cosim.contract.plugins import lookup
from cosim_plugins.identify import synthetic as syn


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """(training log, validation log): circle and racetrack, 1200 rows of 20 ms each."""
    plant = lookup("model", "physical").from_params(syn.TRUE_PARAMS)
    cases = syn.paper_cases()
    cases = {k: cases[k] for k in ("circle_+0", "racetrack_+45")}
    return syn.write_cases(tmp_path_factory.mktemp("logs"), plant.predict, 1200, cases, seed=3,
                           bias_hz=(0.0, 0.0, 2.4), defects=syn.Defects(noise_mm=0.1))


@pytest.fixture(scope="module")
def diagnosed(logs, tmp_path_factory):
    """(printed text, progress lines, diagnosis.json, output folder) of `cosim diagnose TRAIN --validate VALID
    --model physical --discover --jobs 2`."""
    out = tmp_path_factory.mktemp("diag")
    printed, progress = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(printed), contextlib.redirect_stderr(progress):
        code = main(["diagnose", str(logs[0]), "--validate", str(logs[1]), "--model", "physical",
                     "--effects", "background_flow", "--discover", "--jobs", "2", "--out", str(out)])
    assert code == 0
    return printed.getvalue(), progress.getvalue(), json.loads((out / "diagnosis.json").read_text()), out


def test_validate_logs_are_held_out_whole(diagnosed, logs):
    printed, _, r, _ = diagnosed
    assert r["logs"] == [str(logs[0])] and r["validate"] == [str(logs[1])]
    assert r["split"] == {"kind": "validate", "train_logs": 1, "validate_logs": 1}
    assert "drift: not tested (the held-out data are --validate logs" in printed


def test_the_model_named_is_the_baseline_and_only_the_effects_named_are_ranked(diagnosed):
    printed, _, r, _ = diagnosed
    assert r["baseline"]["model"] == "physical" and "physical (baseline)" in printed
    assert [e["effect"] for e in r["ranking"]] == ["background_flow"]


def test_discover_runs_and_reports_on_a_plant_without_a_hidden_force(diagnosed):
    """The plant is the baseline's own form: discovery runs on the held-out windows and chooses nothing."""
    _, progress, r, _ = diagnosed
    assert ".. discover: sensitivities of" in progress
    found = r["discovered"]
    assert found["status"] == "none" and found["explanation"].startswith("no combination of the candidate terms")
    assert found["path"][0][0] == 0 and len(found["path"]) > 1  # the forward path it tried, from no term
    assert r["verdict"]["status"] in ("noise_floor", "unexplained") and r["verdict"]["effect"] is None


def test_the_plots_drawn_over_two_processes_are_all_written(diagnosed):
    *_, out = diagnosed
    for name in ("error_over_time.png", "error_by_condition.png", "ranking.png", "before_after.png"):
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000, name
        assert f"({name})" in (out / "report.md").read_text()


def test_an_unknown_model_is_refused_by_name(logs, tmp_path, capsys):
    code = main(["diagnose", str(logs[0]), "--model", "no_such_model", "--out", str(tmp_path / "d")])
    assert code != 0
    assert "no_such_model" in capsys.readouterr().err

"""`cosim fit` then `cosim compare` end to end on small synthetic logs, and their errors."""

from __future__ import annotations

import json

import pytest
from figure_checks import assert_labelled

from cosim.cli import main


def test_fit_then_compare(small_logs, tmp_path, capsys, saved_figures):
    out = tmp_path / "models"
    code = main(["fit", *map(str, small_logs["train"]), "--model", "all", "--out", str(out), "--seed", "3"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "data quality:" in printed and "circle_+0.csv" in printed and "sindy-nonlinear" in printed
    summary = json.loads((out / "fit.json").read_text())
    assert summary["seed"] == 3 and len(summary["data"]) == 4
    models = summary["models"]
    assert list(models) == ["physical", "sindy-linear", "sindy-nonlinear", "mlp"]
    assert [models[m]["n_params"] for m in models] == [6, 60, 330, 276]
    assert set(models["physical"]["params"]) == {"k", "Cd0", "Cd1", "Cl0", "Fvs", "Fmax"}
    for name, entry in models.items():
        assert entry["train_time_s"] > 0 and (out / entry["file"]).is_file()

    result_path = tmp_path / "cmp.json"
    plots = tmp_path / "plots"
    code = main(["compare", *map(str, small_logs["test"]), "--models", str(out), "--json", str(result_path),
                 "--plots", str(plots), "--split", "test"])
    assert code == 0
    result = json.loads(result_path.read_text())
    assert result["split"] == "test"
    assert set(result["models"]) == set(models)
    for name, r in result["models"].items():
        assert set(r["one_step_mm"]) == {"x", "y", "z", "norm"}
        assert list(r["rollout_mm"]) == ["0.1", "0.42", "1.0"]
        assert 0 < r["one_step_mm"]["norm"] < 1.0, name  # noise is 0.1 mm per axis
        assert 0 < r["rollout_mm"]["0.1"] <= r["rollout_mm"]["1.0"] < 30.0, name
    rrd = (plots / "compare.rrd").read_bytes()
    assert rrd[:3] == b"RRF" and len(rrd) > 1000
    assert (plots / "errors.png").is_file() and (plots / "one_step_physical.png").is_file()
    assert "rollout end error" in capsys.readouterr().out
    assert_labelled(saved_figures)
    assert "test split" in saved_figures["rollouts_physical.png"]["title"]


def test_fit_single_model_and_errors(small_logs, tmp_path, capsys):
    logs = list(map(str, small_logs["train"][:2]))
    out = tmp_path / "lin"
    assert main(["fit", *logs, "--model", "sindy-linear", "--out", str(out)]) == 0
    assert list(json.loads((out / "fit.json").read_text())["models"]) == ["sindy-linear"]
    capsys.readouterr()

    assert main(["fit", *logs, "--model", "kalman", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "unknown model 'kalman'" in err and "physical" in err and "sindy-nonlinear" in err

    assert main(["compare", *logs, "--models", str(tmp_path / "nowhere"), "--json", str(tmp_path / "c.json")]) == 2
    assert "model directory" in capsys.readouterr().err

    bad = tmp_path / "bad.csv"
    bad.write_text("t,wx,wy,wz,x,y,z\n0,0,0,0,0,0,0\n")
    assert main(["fit", str(bad), "--model", "sindy-linear", "--out", str(tmp_path / "y")]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "wrong header" in err and err.count("\n") == 1


@pytest.mark.parametrize("model", ["sindy-linear"])
def test_compare_reads_models_without_summary(small_logs, tmp_path, model):
    out = tmp_path / "m"
    assert main(["fit", *map(str, small_logs["train"][:1]), "--model", model, "--out", str(out)]) == 0
    (out / "fit.json").unlink()
    res = tmp_path / "r.json"
    assert main(["compare", *map(str, small_logs["test"][:1]), "--models", str(out), "--json", str(res)]) == 0
    assert list(json.loads(res.read_text())["models"]) == [model]

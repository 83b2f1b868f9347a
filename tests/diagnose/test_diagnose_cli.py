"""The `cosim diagnose` command: outputs, --add before/after, the JSON contract."""

from __future__ import annotations

import json

from cosim.cli import main


def test_cli_add_shows_error_before_and_after_at_every_horizon(plant_logs, tmp_path, capsys):
    out = tmp_path / "diag"
    logs = [str(p) for p in plant_logs("background_flow")]
    code = main(["diagnose", *logs, "--add", "background_flow", "--effects", "wall_drag,quadratic_drag",
                 "--out", str(out)])
    assert code == 0
    printed = capsys.readouterr().out
    assert "+ background_flow" in printed and "verdict:" in printed
    for name in ("diagnosis.json", "report.md", "diagnosis.rrd", "error_over_time.png", "error_by_condition.png",
                 "ranking.png", "before_after.png"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    assert (out / "diagnosis.rrd").read_bytes()[:3] == b"RRF"
    r = json.loads((out / "diagnosis.json").read_text())
    assert set(r["baseline"]["rollout_mm"]) == {"0.1", "0.2", "0.42", "1.0"}
    assert isinstance(r["noise_floor_mm"], float)
    added = r["added"]
    assert added["effects"] == ["background_flow"]
    for h in ("0.1", "0.2", "0.42", "1.0"):
        assert added["rollout_mm"][h] < added["before_mm"][h]
    assert added["reduction"]["1.0"] > 0.3
    # what remains is ranked on top of the added effect; no listed effect explains much more
    assert [e["effect"] for e in r["ranking"]] and all(e["effect"] != "background_flow" for e in r["ranking"])
    for e in r["ranking"]:
        assert set(e) >= {"effect", "rollout_mm", "reduction", "params"}
    assert set(r["verdict"]) >= {"effect", "explanation"}
    report = (out / "report.md").read_text()
    assert "![before_after](before_after.png)" in report and "Ranking" in report


def test_validate_logs_are_the_held_out_data(plant_logs, tmp_path):
    from cosim.identify.diagnose import Settings, run

    logs = plant_logs("background_flow")
    r = run(logs[:3], logs[3:], Settings(candidates=["background_flow", "quadratic_drag"])).result
    assert r["split"]["kind"] == "validate" and r["validate"] == [str(p) for p in logs[3:]]
    assert r["ranking"][0]["effect"] == "background_flow" and r["ranking"][0]["reduction"] > 0.3

"""Small commands: plugins, validate's wiring table, replay's and node's errors."""

from __future__ import annotations

from pathlib import Path

from cosim.cli import main
from cosim_plugins.resources import SCENARIOS_DIR

REPO = Path(__file__).parents[2]


def test_plugins_lists_every_kind(capsys):
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    for name in ("plant.fmu", "camera.emulator", "estimator.passthrough", "controller.pi",
                 "coil_driver.inverse", "racetrack", "rotating_circle", "physical", "sindy-linear"):
        assert f"  {name} " in out


def test_validate_prints_the_wiring_table(capsys):
    assert main(["validate", str(SCENARIOS_DIR / "racetrack.yaml")]) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("plant.coil_voltage_amp "))
    assert row.split() == ["plant.coil_voltage_amp", "coil_driver.coil_voltage_amp", "(6,)", "V", "1"]
    assert "step order: plant -> camera -> estimator -> controller -> coil_driver" in out
    assert "unused outputs: plant.velocity" in out


def test_validate_names_a_wrong_port(tmp_path, capsys):
    text = (SCENARIOS_DIR / "racetrack.yaml").read_text().replace("{omega: controller.omega}",
                                                                       "{omega: controller.omegaa}")
    (tmp_path / "s.yaml").write_text(text)
    assert main(["validate", str(tmp_path / "s.yaml")]) == 2
    err = capsys.readouterr().err
    assert "components.coil_driver.inputs.omega: controller has no output 'omegaa'" in err


def test_replay_without_a_recording_is_a_clear_error(tmp_path, capsys):
    assert main(["replay", str(tmp_path)]) == 2
    assert f"no recording at {tmp_path / 'recording.rrd'}" in capsys.readouterr().err


def test_node_with_a_bad_endpoint_is_a_clear_error(capsys):
    args = ["node", "plant", str(SCENARIOS_DIR / "racetrack.yaml"), "--run-id", "x", "--connect", "tcp/127.0.0.1:1",
            "--listen", "garbage"]
    assert main(args) == 2
    assert "bad zenoh endpoint in --listen garbage" in capsys.readouterr().err

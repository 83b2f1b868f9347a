"""Scenario files: validation errors name the field and the line; overrides and sweeps."""

from __future__ import annotations

import json
import textwrap

import pytest

from cosim.cli import main
from cosim.scenario.schema import ScenarioError, load_scenario, sweep_overrides
from cosim_plugins.resources import SCENARIOS_DIR

GOOD = textwrap.dedent("""\
    name: t
    duration_s: 1
    components:
      a:
        plugin: camera.emulator
        inputs: {position: a.position}
""")


def write(tmp_path, text, name="s.yaml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_unknown_field_is_named_with_its_line(tmp_path):
    path = write(tmp_path, GOOD.replace("duration_s: 1", "duration_s: 1\nspeedup: 3"))
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    assert "speedup (line 3): unknown field" in str(err.value)


def test_a_recorded_role_is_the_frameworks_or_a_registered_views(tmp_path):
    bound = load_scenario(write(tmp_path, GOOD + "record: {omega: a.position, truth: null}\n"))
    assert bound.record.ports()["omega"] == "a.position" and bound.record.ports()["truth"] is None
    assert bound.record.ports()["axis"] == "plant.axis"  # the swimmer's view's default
    with pytest.raises(ScenarioError) as err:
        load_scenario(write(tmp_path, GOOD + "record: {omegaa: a.position}\n"))
    assert "unknown role 'omegaa'" in str(err.value) and "omega, " in str(err.value)


def test_bad_value_is_named_with_its_line(tmp_path):
    path = write(tmp_path, GOOD.replace("duration_s: 1", "duration_s: -2"))
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    assert "duration_s (line 2)" in str(err.value) and "greater than 0" in str(err.value)


def test_yaml_syntax_error_names_the_line(tmp_path):
    path = write(tmp_path, "name: t\ncomponents: [a\n")
    with pytest.raises(ScenarioError, match=r"line \d+: not valid YAML"):
        load_scenario(path)


def test_wire_to_missing_component(tmp_path):
    path = write(tmp_path, GOOD.replace("a.position}", "ghost.position}"))
    with pytest.raises(ScenarioError, match="source component 'ghost' is not in the scenario"):
        load_scenario(path)


def test_set_overrides_and_rejects_garbage(tmp_path):
    path = write(tmp_path, GOOD)
    s = load_scenario(path, ["duration_s=2.5", "components.a.params.interval_s=0.1"])
    assert s.duration_s == 2.5 and s.components["a"].params == {"interval_s": 0.1}
    with pytest.raises(ScenarioError, match="expected key=value"):
        load_scenario(path, ["duration_s"])


def test_exponent_numbers_are_numbers_in_files_overrides_and_sweeps(tmp_path):
    """YAML 1.1 reads 5e-8 as a string; a scenario, --set and a sweep's runs read it as 5e-8."""
    path = write(tmp_path, GOOD.replace("inputs:", "params: {noise_px: 2e-1}\n    inputs:") + textwrap.dedent("""\
        sweep:
          components.a.params.interval_s: [5.0e-8, 1E-2]
    """))
    s = load_scenario(path, ["components.a.params.outlier_mm=-3e+0"])
    assert s.components["a"].params == {"noise_px": 0.2, "outlier_mm": -3.0}
    runs = [load_scenario(path, overrides) for _, overrides in sweep_overrides(s)]
    assert [r.components["a"].params["interval_s"] for r in runs] == [5e-8, 0.01]


def test_sweep_product_and_labels(tmp_path):
    path = write(tmp_path, GOOD + textwrap.dedent("""\
        sweep:
          components.a.params.interval_s: [0.02, 0.04]
          variant:
            - {label: quiet, components.a.params.noise_px: 0.0}
            - {label: noisy, components.a.params.noise_px: 2.0}
    """))
    combos = sweep_overrides(load_scenario(path))
    assert [labels for labels, _ in combos] == [
        {"interval_s": 0.02, "variant": "quiet"}, {"interval_s": 0.02, "variant": "noisy"},
        {"interval_s": 0.04, "variant": "quiet"}, {"interval_s": 0.04, "variant": "noisy"}]
    assert combos[3][1] == ["components.a.params.interval_s=0.04", "components.a.params.noise_px=2.0"]


def test_cli_exit_codes_and_messages(tmp_path, capsys):
    bad = write(tmp_path, GOOD.replace("camera.emulator", "camera.nonexistent"))
    assert main(["validate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "unknown component 'camera.nonexistent'" in err and "camera.emulator" in err  # lists known ones
    assert main(["validate", str(tmp_path / "missing.yaml")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_schema_is_json_schema(capsys):
    assert main(["schema"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert schema["additionalProperties"] is False and "components" in schema["required"]


def test_every_shipped_scenario_and_each_of_its_sweep_runs_validates():
    """What `cosim validate` checks (fields, plugins, their parameters, the wiring), on every file in
    scenarios/ and on each run of its sweep, so a typo in a shipped sweep row fails here, not an
    hour into a reproduction."""

    from cosim.runtime.wiring import build_wiring

    root = SCENARIOS_DIR
    # cameras/ holds camera set-ups; flow_kf_sweep names model files the docs' flow example fits first
    files = [p for p in sorted(root.rglob("*.yaml")) if p.parent.name != "cameras" and p.name != "flow_kf_sweep.yaml"]
    assert len(files) >= 10
    for path in files:
        base = load_scenario(path)
        for _, overrides in sweep_overrides(base) or [({}, [])]:
            build_wiring(load_scenario(path, overrides))

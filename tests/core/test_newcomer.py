"""What a newcomer hits first: shipped scenarios by name, `cosim validate` checking what `cosim run`
checks, nothing written before a scenario validates, `--set` errors naming the flag, the profiles
listed with what they are, one address for the web viewer, `python -m cosim` without the
dependencies, a sweep pointing at its summary."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.cli import commands
from cosim.cli.main import main
from cosim.contract.errors import UserError
from cosim.runtime.check import check_scenario
from cosim.scenario.catalog import resolve_scenario
from cosim.scenario.schema import load_scenario
from cosim_plugins.resources import SCENARIOS_DIR

ROOT = Path(commands.__file__).resolve().parents[2]
TOY = Path(__file__).parent / "data" / "toy.yaml"


def test_shipped_scenarios_run_by_name_and_are_listed_with_their_description(capsys):
    assert resolve_scenario("racetrack") == SCENARIOS_DIR / "racetrack.yaml"
    assert resolve_scenario("paper/training.yaml") == SCENARIOS_DIR / "paper" / "training.yaml"
    assert resolve_scenario(TOY) == TOY  # a file stays a file
    with pytest.raises(UserError, match="racetrack"):  # a near miss is suggested
        resolve_scenario("racetrak")
    with pytest.raises(UserError, match="scenario file nowhere/x.yaml does not exist"):
        resolve_scenario("nowhere/x.yaml")
    assert main(["scenarios"]) == 0
    lines = capsys.readouterr().out.splitlines()
    racetrack = next(line for line in lines if line.startswith("racetrack "))
    assert "PI + pure pursuit on the racetrack" in racetrack
    listed = {line.split()[0] for line in lines if line and not line.startswith((" ", "run one"))}
    assert {"controllers_racetrack", "controllers_helix", "paper/training", "diagnose/plain"} <= listed


#: flow_kf_sweep's filter reads the model files its walkthrough fits first: here, the filter without one
RUNNABLE = {"flow_kf_sweep": ["components.estimator.params.model=physical"]}


@pytest.mark.parametrize("path", sorted(SCENARIOS_DIR.rglob("*.yaml")), ids=lambda p: p.stem)
def test_validate_refuses_a_misspelt_parameter_of_every_shipped_component(path):
    """`cosim run` refuses an unknown parameter at set-up; `cosim validate` must refuse it first."""
    base = ["sweep={}", *RUNNABLE.get(path.stem, [])]
    check_scenario(load_scenario(path, base))
    for name in load_scenario(path, base).components:
        with pytest.raises(UserError, match="intervall_s"):
            check_scenario(load_scenario(path, [*base, f"components.{name}.params.intervall_s=1"]))


@pytest.mark.parametrize("override, message", [
    ("components.camera.params.intervall_s=0.1", "unknown parameter(s) intervall_s"),
    ("components.camera.plugin=camera.emulatr", "unknown component 'camera.emulatr'"),
    ("path.plugin=racetrak", "unknown path 'racetrak'"),
    ("path.params.straight_mm=-3", "straight_mm must be >= 0"),
])
def test_nothing_is_written_before_the_scenario_validates(tmp_path, capsys, override, message):
    out = tmp_path / "run"
    assert main(["run", str(TOY), "--out", str(out), "--set", override]) == 2
    assert message in capsys.readouterr().err
    assert main(["validate", str(TOY), "--set", override]) == 2  # validate says the same
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_a_sweep_with_one_bad_run_writes_nothing_and_names_the_run(tmp_path, capsys):
    out = tmp_path / "sweep"
    args = ["--set", "sweep={components.camera.params.interval_s: [0.04, 0.05]}"]
    assert main(["run", str(TOY), "--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert "sweep run interval_s=0.05" in err and "not a multiple of the step" in err
    assert not out.exists()
    assert main(["validate", str(TOY), *args]) == 2


def test_set_errors_name_the_flag_not_the_file(capsys):
    assert main(["validate", "racetrack", "--set", "components.camra.params.interval_s=0.1"]) == 2
    err = capsys.readouterr().err
    assert "--set components.camra.params.interval_s=0.1: no component 'camra'" in err
    assert "did you mean camera?" in err and "Field required" not in err
    assert main(["validate", "racetrack", "--set", "durationn_s=5"]) == 2
    err = capsys.readouterr().err
    assert "durationn_s (--set durationn_s=5): unknown field" in err and "line" not in err
    # a whole new component is still an override one may write
    scenario = load_scenario(TOY, ['components.extra={"plugin": "estimator.passthrough", '
                                   '"inputs": {"position": "camera.position"}}'])
    assert "extra" in scenario.components


def test_plugins_lists_every_profile_with_what_it_is(capsys):
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    profiles = out.split("profiles:\n", 1)[1].split("\n", 3)[:2]
    assert profiles[0].split()[0] == "ideal" and "the default" in out.split("ideal", 1)[1].split("lab ", 1)[0]
    lab = out.split("\n  lab ", 1)[1].split("\n  ", 1)[0]
    assert "40 ms" in lab and "cruise" in lab


def test_python_m_cosim_without_the_dependencies_says_what_to_do():
    """`python -S` has no site-packages: as a Python without the venv's packages."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    done = subprocess.run([sys.executable, "-S", "-m", "cosim", "--help"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    assert "lacks cosim's dependency" in done.stderr and ".venv/bin/cosim" in done.stderr


def test_a_sweep_prints_its_summary_files_not_a_folder(tmp_path, capsys):
    commands._print_run({"sweep": [{"status": "ok"}]}, tmp_path)
    lines = capsys.readouterr().out.splitlines()
    assert lines == [f"table:     {tmp_path / 'summary.md'}", f"summary:   {tmp_path / 'summary.json'}"]

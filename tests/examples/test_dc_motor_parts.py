"""The DC motor example's parts: the pythonfmu FMU run by fmpy in its component, the build cache,
the parameter errors, and that the example stands on cosim's public names alone."""

from __future__ import annotations

import ast
import gc
import importlib.util
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from cosim import ComponentError

EXAMPLE = Path(__file__).parents[2] / "examples" / "dc_motor"
PARAMS = {"R_ohm": 1.5, "L_H": 1.0e-3, "k_Nm_per_A": 0.04, "J_kgm2": 3.0e-5, "b_Nms_per_rad": 1.0e-4}


def _transition(p: dict, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, Gamma): the exact state map over ``h`` [s], x(t + h) = Phi x(t) + Gamma u, for
    x = (current_A, speed_rad_s, angle_rad) and u = (voltage_V, load_torque_Nm) held over it."""
    R, L, k, J, b = (p[n] for n in ("R_ohm", "L_H", "k_Nm_per_A", "J_kgm2", "b_Nms_per_rad"))
    A = np.array([[-R / L, -k / L, 0.0], [k / J, -b / J, 0.0], [0.0, 1.0, 0.0]])
    B = np.array([[1 / L, 0.0], [0.0, -1 / J], [0.0, 0.0]])
    M = expm(np.block([[A, B], [np.zeros((2, 5))]]) * h)
    return M[:3, :3], M[:3, 3:]


def _max_error(dc_motor, max_substep_s: float) -> np.ndarray:
    """Largest |FMU - exact| of (current_A, speed_rad_s, angle_rad) over 200 steps of 0.05-5 ms in a
    random order, each with a random voltage (+-24 V) and load torque (+-0.05 N m) held over it."""
    steps_s = (0.05e-3, 0.37e-3, 1e-3, 2.3e-3, 5e-3)
    maps = {h: _transition(PARAMS, h) for h in steps_s}
    motor = dc_motor.motor.MotorFmu()
    motor.setup({"dt": 1e-3, **PARAMS, "speed0_rad_s": 10.0, "max_substep_s": max_substep_s},
                np.random.default_rng(0))
    try:
        x = np.array([0.0, 10.0, 0.0])
        assert np.array_equal(motor.initial_outputs()["state"], x)
        t, rng, error = 0.0, np.random.default_rng(1), np.zeros(3)
        for _ in range(200):
            h = steps_s[rng.integers(len(steps_s))]
            u = np.array([rng.uniform(-24, 24), rng.uniform(-0.05, 0.05)])
            x = maps[h][0] @ x + maps[h][1] @ u
            t += h
            out = motor.step(t, {"voltage_V": u[0], "load_torque_Nm": u[1]})
            assert (out["current_A"], out["speed_rad_s"], out["angle_rad"]) == tuple(out["state"])
            error = np.maximum(error, np.abs(out["state"] - x))
    finally:
        motor.close()
        motor.close()  # idempotent
    return error


def test_the_fmu_matches_the_exact_solution_to_fourth_order(dc_motor):
    """Over uneven steps with inputs switching at each, the FMU's RK4 at its default 0.1 ms sub-step
    stays within 1e-4 A, rad/s and rad of the exact solution (matrix exponential), and halving the
    sub-step divides the error by about 2^4 (17 here)."""
    coarse, fine = _max_error(dc_motor, 1e-4), _max_error(dc_motor, 5e-5)
    assert np.all(coarse < 1e-4), coarse
    assert np.all((10 < coarse / fine) & (coarse / fine < 22)), coarse / fine


def test_bad_parameters_are_named(dc_motor):
    with pytest.raises(ComponentError, match=r"unknown parameter\(s\) R\b.*valid: fmu, dt, R_ohm, L_H"):
        dc_motor.motor.MotorFmu().setup({"dt": 1e-3, "R": 2.0}, np.random.default_rng(0))
    with pytest.raises(ComponentError, match="times must be finite and increasing"):
        dc_motor.steps.Steps.validate_params({"dt": 1e-3, "setpoint_rad_s": [[0.5, 1.0], [0.1, 2.0]]})
    with pytest.raises(ComponentError, match="ki_V_per_rad=-1 out of range"):
        dc_motor.controller.SpeedPi.validate_params({"dt": 1e-3, "ki_V_per_rad": -1})


def test_the_fmu_reports_bad_parameters_and_steps_and_the_process_survives(dc_motor):
    """The FMU logs the problem with status error (the component raises it) and never lets a Python
    exception reach pythonfmu's wrapper, which would free the model's objects twice and crash this
    process later in the garbage collector (it did, on the second failing instance)."""
    for _ in range(4):
        motor = dc_motor.motor.MotorFmu()
        with pytest.raises(ComponentError, match=r"initialisation failed: bad parameter\(s\) R_ohm=-1.0, "
                                                 r"L_H=nan: .* must be > 0"):
            motor.setup({"dt": 1e-3, "R_ohm": -1.0, "L_H": float("nan")}, np.random.default_rng(0))
        motor.close()
        motor = dc_motor.motor.MotorFmu()
        motor.setup({"dt": 1e-3, "max_substep_s": 1e-9}, np.random.default_rng(0))
        with pytest.raises(ComponentError, match=r"step to t=0.01 s failed: cannot step 0.01 s in sub-steps "
                                                 r"of at most 1e-09 s"):
            motor.step(0.01, {"voltage_V": 1.0, "load_torque_Nm": 0.0})
        motor.close()
    gc.collect()


def test_the_models_fmi_calls_never_raise(dc_motor):
    spec = importlib.util.spec_from_file_location("dc_motor_fmu_under_test", EXAMPLE / "dc_motor_fmu.py")
    source = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(source)
    model = source.DcMotor(instance_name="test")
    model.J_kgm2, model.speed0_rad_s = 0.0, math.inf
    model.exit_initialization_mode()
    assert "J_kgm2=0.0, speed0_rad_s=inf" in model.problem and model.do_step(0.0, 1e-3) is False
    model = source.DcMotor(instance_name="test")
    model.exit_initialization_mode()
    for step in (math.nan, -1e-3, math.inf, 1e3):
        assert model.do_step(0.0, step) is False
    assert model.do_step(0.0, 0.0) is True and model.do_step(0.0, 1e-3) is True
    assert [m.status.name for m in model.log_queue] == ["error"] * 4 and model.speed_rad_s == 0.0


def test_the_fmu_is_built_once_per_source_and_pythonfmu_version(dc_motor, tmp_path, monkeypatch):
    build = dc_motor.build
    source = tmp_path / "src" / "dc_motor_fmu.py"
    source.parent.mkdir()
    shutil.copy(build.SOURCE, source)
    monkeypatch.setattr(build, "SOURCE", source)
    monkeypatch.setattr(build, "BUILD_DIR", tmp_path / "build")
    first = build.ensure_fmu()
    assert first.parent == tmp_path / "build" and first.name == f"dc_motor-{build.source_hash()}.fmu"
    built_at = first.stat().st_mtime_ns

    def no_build(*args, **kwargs):
        raise AssertionError("rebuilt an FMU that was cached")

    with monkeypatch.context() as m:
        m.setattr(subprocess, "run", no_build)
        assert build.ensure_fmu() == first and first.stat().st_mtime_ns == built_at
    source.write_text(source.read_text() + "\n# an edit\n")
    second = build.ensure_fmu()
    assert second != first and second.is_file() and not first.exists()  # the stale build is removed
    monkeypatch.setattr(build, "pythonfmu_version", lambda: "0.0.0")
    assert build.fmu_path() != second  # another pythonfmu builds anew


def test_prepare_builds_the_fmu_and_artifacts_name_what_it_is_built_from(dc_motor, tmp_path, monkeypatch):
    motor, build = dc_motor.motor.MotorFmu, dc_motor.build
    monkeypatch.setattr(build, "BUILD_DIR", tmp_path / "build")
    motor.prepare({"dt": 1e-3, "R_ohm": 2.0})
    assert [p.name for p in (tmp_path / "build").iterdir()] == [build.fmu_path().name]
    motor.prepare({"dt": 1e-3, "fmu": str(tmp_path / "theirs.fmu")})  # a given FMU is never built
    assert len(list((tmp_path / "build").iterdir())) == 1
    assert motor.artifacts({"dt": 1e-3}) == [build.SOURCE]
    assert motor.artifacts({"dt": 1e-3, "fmu": "x/theirs.fmu"}) == [Path("x/theirs.fmu")]


def test_the_fmu_cache_is_ignored_by_git(dc_motor):
    repo = EXAMPLE.parents[1]
    if not (repo / ".git").exists() or shutil.which("git") is None:
        pytest.skip("not a git work tree")
    path = dc_motor.build.fmu_path().relative_to(repo)
    assert subprocess.run(["git", "-C", str(repo), "check-ignore", "-q", str(path)]).returncode == 0


def test_the_example_imports_only_the_frameworks_public_names():
    allowed = {"cosim", "cosim.contract.views"}
    files = sorted(EXAMPLE.rglob("*.py"))
    assert len(files) >= 7
    for file in files:
        if "build" in file.relative_to(EXAMPLE).parts[:-1]:
            continue
        text = file.read_text()
        assert "cosim_plugins" not in text, file
        for node in ast.walk(ast.parse(text)):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 else []
            for name in names:
                if name == "cosim" or name.startswith("cosim."):
                    assert name in allowed, f"{file.name} imports {name}"

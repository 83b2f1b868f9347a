"""The DC motor example end to end: one process and one process per component give the same bytes,
the run is recorded, and the loop is the sampled-data system its equations say."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from recording_checks import recorded_entities
from scipy.linalg import expm

from cosim.cli import main
from cosim.contract import plugins

SCENARIO = Path(__file__).parents[2] / "examples" / "dc_motor" / "scenario.yaml"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The scenario run in one process and with --processes: {layout: run folder}."""
    out = tmp_path_factory.mktemp("dc_motor")
    dirs = {"one": out / "one", "processes": out / "processes"}
    assert main(["run", str(SCENARIO), "--out", str(dirs["one"]), "--quiet"]) == 0
    assert main(["run", str(SCENARIO), "--out", str(dirs["processes"]), "--quiet", "--processes"]) == 0
    yield dirs
    plugins.reset()  # forget the example's plugin file, registered by the runs


@pytest.fixture(scope="module")
def trace(runs):
    with np.load(runs["one"] / "trace.npz") as data:
        return {k: data[k] for k in data.files}


@pytest.fixture(scope="module")
def scenario():
    return yaml.safe_load(SCENARIO.read_text())


def test_both_process_layouts_write_the_same_log_and_trace(runs):
    one, procs = runs["one"], runs["processes"]
    assert (one / "log.csv").read_bytes() == (procs / "log.csv").read_bytes()
    assert len((one / "log.csv").read_text().splitlines()) == 1 + 1000
    with np.load(one / "trace.npz") as a, np.load(procs / "trace.npz") as b:
        assert sorted(a.files) == sorted(b.files)
        for key in a.files:
            assert np.array_equal(a[key], b[key], equal_nan=True), key
    for run in runs.values():
        summary = json.loads((run / "summary.json").read_text())
        assert summary["status"] == "ok" and summary["steps"] == 1000


def test_the_runs_are_recorded_with_the_scopes_plots(runs):
    expected = {"/scope/speed_rad_s/measured", "/scope/speed_rad_s/setpoint", "/scope/voltage_V",
                "/scope/current_A", "/scope/load_torque_Nm"}
    for run in runs.values():
        assert expected <= recorded_entities(run / "recording.rrd")
        assert not list(run.glob("recording.*.rrd"))  # the scope's part was folded into recording.rrd


def _motor_matrices(p: dict) -> tuple[np.ndarray, np.ndarray]:
    """Continuous-time x' = A x + B u for x = (current_A, speed_rad_s, angle_rad), u = (voltage_V, load_torque_Nm)."""
    R, L, k, J, b = (p[n] for n in ("R_ohm", "L_H", "k_Nm_per_A", "J_kgm2", "b_Nms_per_rad"))
    A = np.array([[-R / L, -k / L, 0.0], [k / J, -b / J, 0.0], [0.0, 1.0, 0.0]])
    B = np.array([[1 / L, 0.0], [0.0, -1 / J], [0.0, 0.0]])
    return A, B


def _held(table: list, t_s: np.ndarray) -> np.ndarray:
    """A piecewise-constant profile [[t_s, value], ...] at the times t_s (0 before its first time)."""
    out = np.zeros_like(t_s)
    for start, value in table:
        out[t_s >= start - 1e-9] = value
    return out


def test_the_loop_is_the_sampled_data_system_of_its_equations(trace, scenario):
    """An independent simulation of the same loop, the motor integrated exactly over each tick (matrix
    exponential, inputs held) and the PI with clipping and conditional integration, gives the run's
    trajectory: the voltage computed at t is applied over [t, t + dt)."""
    dt, n = scenario["dt_s"], len(trace["t_s"])
    A, B = _motor_matrices(scenario["components"]["motor"]["params"])
    M = expm(np.block([[A, B], [np.zeros((2, 5))]]) * dt)
    Phi, Gamma = M[:3, :3], M[:3, 3:]
    profile, pi = scenario["components"]["profile"]["params"], scenario["components"]["controller"]["params"]
    t = np.arange(n) * dt
    setpoint, load = _held(profile["setpoint_rad_s"], t), _held(profile["load_torque_Nm"], t)
    x, integral = np.zeros(3), 0.0
    states, volts = np.zeros((n, 3)), np.zeros(n)
    v_max = pi["voltage_max_V"]
    for i in range(n):
        states[i] = x
        error = setpoint[i] - x[1]
        trial = integral + pi["ki_V_per_rad"] * error * dt
        demand = pi["kp_V_s_per_rad"] * error + trial
        volts[i] = np.clip(demand, -v_max, v_max)
        if volts[i] == demand or np.sign(error) != np.sign(demand):
            integral = trial
        x = Phi @ x + Gamma @ np.array([volts[i], load[i]])
    assert np.allclose(trace["motor.state"], states, rtol=0, atol=[1e-4, 1e-4, 1e-5])  # A, rad/s, rad
    assert np.allclose(trace["controller.voltage_V"], volts, rtol=0, atol=1e-5)
    assert np.abs(volts).max() == v_max  # the speed step and the reversal saturate the supply


def test_steady_states_obey_the_motor_equations_with_zero_speed_error(trace, scenario):
    """At the end of each plateau (no load, under load, reversed): V = R i + k w (no L di/dt),
    k i = b w + load torque (no J dw/dt), and the integral action leaves no speed error."""
    p = scenario["components"]["motor"]["params"]
    t, i, w = trace["t_s"], trace["motor.current_A"], trace["motor.speed_rad_s"]
    # the voltage applied over the tick before each state (the delayed edge), and the load then
    v, load = trace["controller.voltage_V"][:-1], trace["profile.load_torque_Nm"][:-1]
    t, i, w, setpoint = t[1:], i[1:], w[1:], trace["profile.setpoint_rad_s"][1:]
    plateaus = [(0.30, 0.35, 300.0, 0.0), (0.60, 0.65, 300.0, 0.1), (0.95, 1.0, -150.0, 0.0)]
    for start, stop, speed, torque in plateaus:
        s = (t >= start) & (t < stop)
        assert np.all(setpoint[s] == speed) and np.all(load[s] == torque)
        assert np.allclose(w[s], speed, rtol=1e-4)
        assert np.allclose(v[s], p["R_ohm"] * i[s] + p["k_Nm_per_A"] * w[s], rtol=1e-5, atol=1e-6)
        assert np.allclose(p["k_Nm_per_A"] * i[s], p["b_Nms_per_rad"] * w[s] + torque, rtol=1e-4, atol=1e-7)


def test_each_setpoint_step_settles_within_60_ms(trace):
    """Within 2 % of the step from 60 ms after it on (a closed-loop time constant of ~8 ms below
    saturation, longer while the 24 V supply limits), and the reversal does not overshoot."""
    t, w = trace["t_s"], trace["motor.speed_rad_s"]
    for at, before, after, until in [(0.05, 0.0, 300.0, 0.35), (0.65, 300.0, -150.0, 1.0)]:
        late = (t >= at + 0.060) & (t < until)
        assert np.all(np.abs(w[late] - after) <= 0.02 * abs(after - before))
    reversed_ = t >= 0.65
    assert w[reversed_].min() >= -150.0 * (1 + 1e-4)

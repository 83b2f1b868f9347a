"""A NaN (or out-of-range) controller output never reaches the coils: the run stops cleanly.

The throwaway controller in ``nan_plugin.py`` (registered through the scenario's
``plugins:`` field, like a user's own file) follows the path with PI and outputs
NaN from t = 1 s. The coil driver refuses it (zero field + fault): the run
stops at that tick with status "fault", and everything recorded stays readable.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cosim.api import RunRequest, run
from cosim.contract import plugins
from cosim.runtime.scheduler import RunError
from cosim_plugins.raw_log import read_log

SCENARIO = Path(__file__).parent / "data" / "nan_racetrack.yaml"
NAN_AT_S, DT = 1.0, 0.02


@pytest.fixture
def fresh_plugins():
    plugins.reset()
    yield
    plugins.reset()


def run_faulty(out: Path, *overrides, processes: bool = False):
    with pytest.raises(RunError) as err:
        run(RunRequest(SCENARIO, out, list(overrides), processes=processes, progress=False))
    return json.loads((out / "summary.json").read_text()), str(err.value)


@pytest.mark.parametrize("value,processes", [
    ("nan", False), ("inf", False),
    ("400.0", False),  # (400, 400, 400) rad/s: 110 Hz > the 60 Hz limit
    ("nan", True),  # nodes run ahead of the record: it still ends exactly at the fault
])
def test_unsafe_command_stops_the_run_cleanly(tmp_path, fresh_plugins, value, processes):
    summary, message = run_faulty(tmp_path, f"components.controller.params.value={value}", processes=processes)
    assert summary["status"] == "fault"
    assert "coil_driver" in message and "unsafe command" in message
    ticks = int(round(NAN_AT_S / DT)) + 1  # the faulty tick is recorded, nothing after it
    assert summary["steps"] == ticks

    log = read_log(tmp_path / "log.csv")  # the raw log is readable
    assert len(log.t_s) == ticks
    with np.load(tmp_path / "trace.npz") as trace:
        omega = trace["controller.omega"]
        volts = trace["coil_driver.coil_voltage_amp"]
        position = trace["plant.position"]
    assert len(omega) == ticks and np.all(np.isfinite(omega[:-1]))
    assert np.all(volts[-1] == 0)  # the unsafe command became zero field, never a voltage
    assert np.all(np.isfinite(volts)) and np.all(volts <= 40.0 + 1e-9)
    assert np.all(np.isfinite(position))


@pytest.mark.parametrize("bad", [[np.nan, 0.0, 0.0], [0.0, np.inf, 0.0], [0.0, 0.0, -np.inf],
                                 [0.0, 0.0, 2 * np.pi * 61], [0.0, 0.0, 2 * np.pi * 60 * (1 + 1e-6)]],
                         ids=["nan", "inf", "-inf", "61 Hz", "just above 60 Hz"])
def test_coil_driver_answers_an_unsafe_command_with_zero_voltages(bad):
    """What the plant receives at the faulty tick; each case on a fresh driver (a latched fault
    from an earlier case would zero the output whatever the command)."""
    from cosim_plugins.coil_driver.inverse import InverseMagnetics

    driver = InverseMagnetics()
    driver.setup({"dt": DT}, np.random.default_rng(0))
    ok = driver.step(0.0, {"omega": np.array([0.0, 0.0, 2 * np.pi * 8])})
    assert ok["coil_voltage_amp"].max() > 0 and driver.fault is None and driver.tripped is None
    out = driver.step(DT, {"omega": np.array(bad)})
    assert driver.tripped is not None and driver.tripped.name == "unsafe_command"
    assert np.all(out["coil_voltage_amp"] == 0) and float(out["drive_freq"]) == 0
    driver.close()


def test_a_command_at_the_spin_limit_still_drives_the_coils():
    """The other side of the boundary: 60 Hz itself, and just below it, are safe commands."""
    from cosim_plugins.coil_driver.inverse import InverseMagnetics

    for f_hz in (60.0 * (1 - 1e-6), 59.0):
        driver = InverseMagnetics()
        driver.setup({"dt": DT}, np.random.default_rng(0))
        out = driver.step(0.0, {"omega": np.array([0.0, 0.0, 2 * np.pi * f_hz])})
        assert driver.fault is None and out["coil_voltage_amp"].max() > 0
        assert float(out["drive_freq"]) == pytest.approx(f_hz)
        driver.close()


def test_recorded_trace_ends_with_zero_coil_voltages(tmp_path, fresh_plugins):
    run_faulty(tmp_path)
    with np.load(tmp_path / "trace.npz") as trace:
        assert np.all(trace["coil_driver.coil_voltage_amp"][-1] == 0)

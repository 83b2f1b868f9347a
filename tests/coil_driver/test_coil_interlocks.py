"""The bridge's interlocks, backend by backend alike: shaping limits, thermal budget, watchdog, safe stop."""

from __future__ import annotations

import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from coil_fakes import DT, RecordingReference, spin

from cosim import ComponentError
from cosim.cli import main
from cosim_plugins.coil_driver.actuation import impedance_ohm
from cosim_plugins.coil_driver.backends import Rig
from cosim_plugins.coil_driver.interlocks import Limits, ThermalBudget, limit_scale
from cosim_plugins.coil_driver.inverse import InverseMagnetics
from cosim_plugins.coil_driver.params import PARAMS
from cosim_plugins.resources import SCENARIOS_DIR

ROOT = Path(__file__).parents[2]

R, L, C = 12.9, 0.411, 430e-6
LOOSE = {"v_max": 1e4, "i_max_a": 1e3, "i_trip_a": 1e3, "slew_v_per_s": 1e9}


def z_abs(f_hz: float) -> float:
    return abs(impedance_ohm(f_hz, R, L, C))


# ---------------------------------------------------------------- shaping limits


def test_limit_scale_takes_the_tightest_limit_for_all_coils_together():
    amp = np.array([30.0, 30.0, 10.0, 10.0, 50.0, 50.0])
    prev = amp.copy()  # no rise: the slew limit is idle
    assert limit_scale(amp, prev, 10.0, DT, Limits(40.0, 100.0, 1e9)) == pytest.approx(40.0 / 50.0)
    # 2 A through 10 ohm allows 20 V on the largest coil
    assert limit_scale(amp, prev, 10.0, DT, Limits(40.0, 2.0, 1e9)) == pytest.approx(20.0 / 50.0)
    # a rise of at most 100 V/s * 20 ms = 2 V above the previous amplitudes
    rise = limit_scale(amp, np.zeros(6), 10.0, DT, Limits(1e4, 1e3, 100.0))
    assert rise == pytest.approx(2.0 / 50.0)
    assert limit_scale(amp / 2, amp, 10.0, DT, Limits(1e4, 1e3, 100.0)) == 1.0  # falls are not limited


@pytest.mark.parametrize("limit", ["v_max", "i_max_a"])
def test_a_command_beyond_a_limit_is_scaled_down_keeping_the_field_direction(make_driver, limit):
    omega = spin(9.0, (1.0, 1.0, 0.5))
    free = make_driver(**LOOSE).step(0.0, {"omega": omega})
    bound = 0.5 * (free["coil_voltage_amp"].max() if limit == "v_max" else free["coil_voltage_amp"].max() / z_abs(9.0))
    limited = make_driver(**{**LOOSE, limit: bound}).step(0.0, {"omega": omega})

    peak = limited["coil_voltage_amp"].max() / (1.0 if limit == "v_max" else z_abs(9.0))
    assert peak == pytest.approx(bound, rel=1e-12)
    ratio = limited["coil_voltage_amp"] / free["coil_voltage_amp"]
    assert np.allclose(ratio, 0.5, rtol=1e-12)  # one common factor: same field direction, half the field
    assert np.allclose(limited["coil_voltage_phase"], free["coil_voltage_phase"])
    assert float(limited["drive_freq"]) == pytest.approx(9.0)


def test_the_slew_limit_ramps_a_rise_and_never_a_fall(make_driver):
    slew = 200.0  # V/s: at most 4 V more per 20 ms tick
    driver = make_driver(**{**LOOSE, "slew_v_per_s": slew})
    omega = spin(9.0, (1.0, 0.0, 0.0))
    target = make_driver(**LOOSE).step(0.0, {"omega": omega})["coil_voltage_amp"].max()
    peaks = [driver.step(k * DT, {"omega": omega})["coil_voltage_amp"].max() for k in range(40)]
    rises = np.diff([0.0, *peaks])
    assert np.all(rises <= slew * DT + 1e-9)
    assert peaks[0] == pytest.approx(slew * DT)  # from zero, one tick's worth
    assert peaks[-1] == pytest.approx(target)  # reaches the command once the ramp is done
    assert driver.fault is None
    slower = driver.step(40 * DT, {"omega": spin(9.0, (1.0, 0.0, 0.0)) * 0.0})  # field off: at once
    assert np.all(slower["coil_voltage_amp"] == 0)


# ---------------------------------------------------------------- thermal budget


def test_thermal_budget_trips_when_the_window_energy_exceeds_it(make_driver):
    omega = spin(9.0, (1.0, 0.0, 0.0))
    current = make_driver().step(0.0, {"omega": omega})["coil_voltage_amp"] / z_abs(9.0)
    per_tick = current.max() ** 2 * R / 2 * DT  # J in the hottest coil per tick
    budget = 10.5 * per_tick  # the 11th tick exceeds it
    driver = make_driver(thermal_budget_j=budget, thermal_window_s=1.0)
    for k in range(10):
        out = driver.step(k * DT, {"omega": omega})
        assert driver.fault is None and out["coil_voltage_amp"].max() > 0
    out = driver.step(10 * DT, {"omega": omega})
    assert driver.fault.startswith("thermal_budget: coil ")
    assert f"(budget {budget:g} J)" in driver.fault and "in the last 1 s" in driver.fault
    assert np.all(out["coil_voltage_amp"] == 0)
    out = driver.step(11 * DT, {"omega": omega})  # latched
    assert np.all(out["coil_voltage_amp"] == 0) and driver.fault.startswith("thermal_budget")


def test_thermal_window_slides():
    """Within budget per window, however long: energy leaves the window as it ages."""
    budget = ThermalBudget(r_ohm=10.0, dt_s=0.1, window_s=1.0, budget_j=5.5)  # 10 ticks of 0.5 J fit
    one_amp = np.array([1.0, 0, 0, 0, 0, 0])  # 1 A in 10 ohm: 5 W mean, 0.5 J per tick
    assert all(budget.add(one_amp) is None for _ in range(100))
    assert budget.energy_j[0] == pytest.approx(5.0)
    fault = budget.add(one_amp * 1.3)  # 0.845 J replaces 0.5 J: 5.345 J, still within
    assert fault is None
    fault = budget.add(one_amp * 1.3)  # 5.69 J
    assert fault is not None and fault.name == "thermal_budget" and "coil +x" in fault.message


# ---------------------------------------------------------------- watchdog


def test_watchdog_on_step_times_trips_after_more_than_n_ticks_without_a_command(make_driver):
    driver = make_driver(watchdog_ticks=5)
    omega = spin(8.0)
    driver.step(0.0, {"omega": omega})
    assert driver.fault is None
    driver.step(5 * DT, {"omega": omega})  # five ticks since the last: still within
    assert driver.fault is None
    out = driver.step(11 * DT, {"omega": omega})  # six ticks
    assert driver.fault.startswith("watchdog: no new command for 5 ticks (120 ms")
    assert np.all(out["coil_voltage_amp"] == 0) and float(out["drive_freq"]) == 0


class FakeClock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_watchdog_on_the_wall_clock_ramps_the_outputs_down_between_steps(make_driver):
    log = []
    reference = RecordingReference(log)
    driver = make_driver(rig=Rig(reference), watchdog_ticks=5)
    assert driver.wall_clock  # 'auto' with hardware
    clock = driver.now = FakeClock()
    driver.use_monitor = False  # the test calls the monitor's check itself
    omega = spin(8.0)
    for k in range(20):  # a constant command, delivered every tick, is no timeout
        clock.t = 100.0 + k * DT
        driver.step(k * DT, {"omega": omega})
        assert driver.check_watchdog() is None
    clock.t += 5 * DT - 1e-6
    assert driver.check_watchdog() is None
    clock.t += 2e-6 + 0.001
    fault = driver.check_watchdog()
    assert fault is not None and fault.name == "watchdog"
    assert log[-1] == "reference.stop"  # ramped to zero at once, not at the next step
    delivered = len(reference.delivered)
    out = driver.step(20 * DT, {"omega": omega})  # the next step reports it and delivers nothing
    assert driver.fault.startswith("watchdog: no new command for 5 ticks")
    assert np.all(out["coil_voltage_amp"] == 0) and len(reference.delivered) == delivered
    assert log.count("reference.stop") == 1


def test_watchdog_monitor_thread_trips_when_steps_stop(make_driver):
    log = []
    driver = make_driver(rig=Rig(RecordingReference(log)), watchdog_ticks=3)  # 60 ms
    driver.step(0.0, {"omega": spin(8.0)})
    deadline = time.monotonic() + 5.0
    while driver.tripped is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert driver.tripped is not None and driver.tripped.name == "watchdog"
    assert "reference.stop" in log


# ---------------------------------------------------------------- faults and stop reach the hardware


def test_an_unsafe_command_never_reaches_the_hardware_and_stops_it(make_driver):
    log = []
    reference = RecordingReference(log)
    driver = make_driver(rig=Rig(reference), watchdog_clock="sim")  # a busy machine's 100 ms must not trip it
    driver.step(0.0, {"omega": spin(8.0)})
    out = driver.step(DT, {"omega": np.array([np.nan, 0.0, 0.0])})
    assert driver.fault.startswith("unsafe_command: unsafe command omega")
    assert np.all(out["coil_voltage_amp"] == 0)
    assert [tick for tick, _ in reference.delivered] == [0]  # the NaN tick was never handed over
    assert log == ["reference.open", "reference.start", "reference.deliver", "reference.stop"]


def test_close_stops_the_hardware_once_and_later_steps_deliver_nothing(make_driver):
    log = []
    reference = RecordingReference(log)
    driver = make_driver(rig=Rig(reference))
    driver.step(0.0, {"omega": spin(8.0)})
    driver.close()
    driver.close()
    assert log[-2:] == ["reference.stop", "reference.close"] and log.count("reference.stop") == 1
    out = driver.step(DT, {"omega": spin(8.0)})  # a worker thread still stepping after Ctrl-C
    assert np.all(out["coil_voltage_amp"] == 0) and len(reference.delivered) == 1


# ---------------------------------------------------------------- parameters


@pytest.mark.parametrize("params,message", [
    ({"backend": "serial"}, "backend 'serial' unknown; known: fmu, visa, daq, visa+daq"),
    ({"backend": "visa"}, "visa_resources lists 0 addresses; 6 coils x 2 supplies_per_coil need 12"),
    ({"backend": "daq", "daq_rate_hz": 1234.5}, "daq_rate_hz=1234.5 gives 24.69 samples per 0.02 s tick"),
    ({"backend": "daq", "daq_gain_v_per_v": 2.0}, "v_max=40 V needs a 20 V reference, beyond daq_ao_max_v=10 V"),
    ({"i_trip_a": 2.0}, "i_trip_a=2 A is below i_max_a=3 A"),
    ({"watchdog_clock": "cpu"}, "watchdog_clock 'cpu' unknown; known: auto, sim, wall"),
    ({"watchdog_ticks": 2.5}, "parameter watchdog_ticks=2.5: expected a whole number"),
])
def test_bad_parameters_are_named_before_any_hardware_opens(params, message):
    with pytest.raises(ComponentError) as err:
        InverseMagnetics.validate_params({"dt": DT, **params})
    assert message in str(err.value)


@pytest.mark.parametrize("overrides,message", [
    (["components.coil_driver.params.backend=visa", "components.coil_driver.params.visa_resources=[GPIB0::1::INSTR]"],
     "visa_resources lists 1 addresses; 6 coils x 2 supplies_per_coil need 12"),
    (["dt_s=0.01", "components.coil_driver.params.backend=daq", "components.coil_driver.params.daq_rate_hz=150"],
     "daq_rate_hz=150 gives 1.5 samples per 0.01 s tick"),  # the scenario's dt, not the default
])
def test_cosim_validate_names_a_bad_backend_parameter_in_one_line(capsys, overrides, message):
    args = ["validate", str(SCENARIOS_DIR / "racetrack.yaml")]
    for item in overrides:
        args += ["--set", item]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("cosim validate: error: components.coil_driver.params (coil_driver.inverse): ")
    assert message in err and len(err.splitlines()) == 1


def test_the_rig_page_lists_every_interlock_and_backend_parameter_with_its_default():
    section = (ROOT / "docs" / "rig.md").read_text()
    rows = dict(re.findall(r"^\| `(\w+)` \| `([^`]*)` \|", section, flags=re.M))
    actuation = {"field_mT", "turns", "r_inner_mm", "r_outer_mm", "z_near_mm", "thickness_mm", "r_ohm", "l_h",
                 "c_f", "f_min_hz"}  # the driver's model of the coils, documented in its own module
    assert set(rows) == set(PARAMS) - actuation
    assert {key: yaml.safe_load(text) for key, text in rows.items()} == {key: PARAMS[key].default for key in rows}


# ---------------------------------------------------------------- a trip, the monitor, close


def _refuse_to_stop():
    raise RuntimeError("AO task already released")


class CountingRig(Rig):
    """A rig of one recording reference that counts the driver's calls to stop()."""

    def __init__(self, on_stop=None):
        super().__init__(reference=RecordingReference([], on_stop=on_stop))
        self.stops = 0

    def stop(self):
        self.stops += 1
        return super().stop()


def test_a_trip_whose_stop_fails_names_both_and_keeps_the_first_name(make_driver):
    driver = make_driver(rig=CountingRig(on_stop=_refuse_to_stop), watchdog_clock="sim")
    driver.step(0.0, {"omega": spin(9.0)})
    driver.step(0.02, {"omega": np.array([np.nan, 0.0, 0.0])})
    assert driver.tripped.name == "unsafe_command"
    assert driver.fault.startswith("unsafe_command: unsafe command omega")
    assert driver.fault.endswith("; stopping the outputs: daq_error: RuntimeError: AO task already released")


def test_a_trip_a_step_reported_is_not_reported_again_at_close(make_driver):
    driver = make_driver(rig=CountingRig(), watchdog_clock="sim")
    driver.step(0.0, {"omega": np.array([np.inf, 0.0, 0.0])})
    reported = driver.fault
    driver.close()
    assert driver.fault == reported  # not "(after the last step)": the run saw it at its step


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_the_monitor_stops_the_rig_once_and_checks_nothing_after_close(make_driver):
    rig = CountingRig()
    driver = make_driver(rig=rig, watchdog_clock="wall", watchdog_ticks=5)
    driver.use_monitor = False  # this test is the monitor: it calls check_watchdog() itself
    driver.now = clock = Clock()
    driver.step(0.0, {"omega": spin(9.0)})
    clock.now += 0.2  # 10 ticks without a command
    assert driver.check_watchdog().name == "watchdog" and rig.stops == 1
    clock.now += 1.0
    assert driver.check_watchdog() is None and rig.stops == 1  # latched: the rig is not stopped again

    rig = CountingRig()
    closed = make_driver(rig=rig, watchdog_clock="wall", watchdog_ticks=5)
    closed.use_monitor = False
    closed.now = clock = Clock()
    closed.step(0.0, {"omega": spin(9.0)})
    closed.close()
    clock.now += 1.0
    assert closed.check_watchdog() is None and rig.stops == 1 and closed.fault is None


NEVER_CLOSED = """
import sys
import threading
import numpy as np
sys.path.insert(0, {tests!r})
from coil_fakes import RecordingReference, spin
from cosim_plugins.coil_driver.backends import Rig
from cosim_plugins.coil_driver.inverse import InverseMagnetics

driver = InverseMagnetics()
driver.setup({{"dt": 0.02, "watchdog_clock": "wall"}}, np.random.default_rng(0), rig=Rig(RecordingReference([])))
driver.step(0.0, {{"omega": spin(9.0)}})
assert driver._monitor.is_alive()
print("leaving without close()")
"""


def test_a_driver_never_closed_does_not_keep_its_process_alive():
    """The wall-clock monitor is a daemon thread: a script that forgets close() still ends."""
    script = NEVER_CLOSED.format(tests=str(Path(__file__).parent))
    try:
        proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail("the process did not end: the watchdog monitor kept it alive")
    assert proc.returncode == 0 and proc.stdout.strip() == "leaving without close()", proc.stderr


# ---------------------------------------------------------------- what reaches the hardware at a trip, the monitor


def test_a_thermal_trip_on_hardware_delivers_nothing_at_its_tick(make_driver):
    """The tick whose energy exceeds the budget is refused before the hardware sees it: ten ticks delivered, the
    eleventh trips, and the reference is stopped."""
    omega = spin(9.0, (1.0, 0.0, 0.0))
    current = make_driver().step(0.0, {"omega": omega})["coil_voltage_amp"] / z_abs(9.0)
    budget = 10.5 * current.max() ** 2 * R / 2 * DT
    log = []
    reference = RecordingReference(log)
    driver = make_driver(rig=Rig(reference), thermal_budget_j=budget, thermal_window_s=1.0, watchdog_clock="sim")
    for k in range(11):
        out = driver.step(k * DT, {"omega": omega})
    assert driver.fault.startswith("thermal_budget: coil ") and np.all(out["coil_voltage_amp"] == 0)
    assert [tick for tick, _ in reference.delivered] == list(range(10))
    assert log[-1] == "reference.stop"


def test_the_wall_clock_monitor_is_a_daemon_thread_and_a_simulated_clock_starts_none(make_driver):
    sim = make_driver(watchdog_clock="sim")
    sim.step(0.0, {"omega": spin(5.0)})
    assert sim._monitor is None  # steps on simulated time are checked in step() alone
    wall = make_driver(watchdog_clock="wall")
    wall.step(0.0, {"omega": spin(5.0)})
    assert wall._monitor is not None and wall._monitor.daemon and wall._monitor.is_alive()


class _QuietSupplies(RecordingReference):
    """Supplies that read nothing back and, like the reference, may refuse to stop."""

    def poll(self, tick):
        return []


def test_a_trip_whose_two_parts_fail_to_stop_names_both(make_driver):
    rig = Rig(reference=RecordingReference([], on_stop=_refuse_to_stop),
              supplies=_QuietSupplies([], on_stop=_refuse_to_stop))
    driver = make_driver(rig=rig, watchdog_clock="sim")
    driver.step(0.0, {"omega": spin(9.0)})
    driver.step(DT, {"omega": np.array([np.nan, 0.0, 0.0])})
    assert driver.fault.endswith("; stopping the outputs: daq_error: RuntimeError: AO task already released; "
                                 "supply_error: RuntimeError: AO task already released")


def test_the_driver_takes_the_scenarios_period():
    """dt = 10 ms: the step-time watchdog's limit is its ticks at 10 ms each, not at a default 20 ms."""
    driver = InverseMagnetics()
    driver.setup({"dt": 0.01, "watchdog_ticks": 5, "watchdog_clock": "sim"}, np.random.default_rng(0))
    try:
        assert driver.dt == 0.01 and driver.watchdog.timeout_s == pytest.approx(0.05)
    finally:
        driver.close()


def test_a_close_whose_two_parts_fail_to_stop_names_both(make_driver):
    rig = Rig(reference=RecordingReference([], on_stop=_refuse_to_stop),
              supplies=_QuietSupplies([], on_stop=_refuse_to_stop))
    driver = make_driver(rig=rig, watchdog_clock="sim")
    driver.step(0.0, {"omega": spin(9.0)})
    driver.close()
    assert driver.fault == ("daq_error: RuntimeError: AO task already released; "
                            "supply_error: RuntimeError: AO task already released")


# ---------------------------------------------------------------- the monitor's pace, close()'s waits, the coils' field


class _LooksOnce:
    """Stands in for the monitor's stop event: records the period of its first wait and stops it there."""

    def __init__(self):
        self.periods = []

    def wait(self, period_s):
        self.periods.append(period_s)
        return True

    def set(self):
        pass


@pytest.mark.parametrize("ticks, period_s", [(5, 0.010), (1, 0.005)])
def test_the_monitor_looks_every_half_period_or_quarter_time_out_if_shorter(make_driver, ticks, period_s):
    """At 20 ms: every 10 ms when the watchdog allows 100 ms; every 5 ms when it allows 20 ms."""
    driver = make_driver(watchdog_clock="sim", watchdog_ticks=ticks)
    driver._monitor_stop = stop = _LooksOnce()
    driver._watch()
    assert stop.periods == [pytest.approx(period_s, rel=1e-12)]


class _Waits:
    """Stands in for the monitor thread and the driver's lock: records the time-outs close() waits with."""

    def __init__(self):
        self.joins, self.acquires, self.released = [], [], 0

    def join(self, timeout=None):
        self.joins.append(timeout)

    def acquire(self, timeout=-1):
        self.acquires.append(timeout)
        return True

    def release(self):
        self.released += 1


def test_close_waits_two_seconds_at_most_for_the_monitor_and_for_a_step_in_progress(make_driver):
    rig = CountingRig()
    driver = make_driver(rig=rig, watchdog_clock="sim")
    driver._monitor = driver._lock = waits = _Waits()
    driver.close()
    assert waits.joins == [2.0] and waits.acquires == [2.0] and waits.released == 1 and rig.stops == 1


def test_close_called_on_the_monitor_thread_does_not_wait_for_itself(make_driver):
    rig = CountingRig()
    driver = make_driver(rig=rig, watchdog_clock="sim")
    errors = []

    def close_here():
        try:
            driver.close()
        except Exception as exc:  # joining the current thread raises RuntimeError
            errors.append(exc)

    driver._monitor = threading.Thread(target=close_here)
    driver._monitor.start()
    driver._monitor.join(timeout=10.0)
    assert not driver._monitor.is_alive() and errors == [] and driver.closed and rig.stops == 1


def test_a_monitor_trip_after_the_last_step_is_named_at_close(make_driver):
    driver = make_driver(rig=CountingRig(), watchdog_clock="wall", watchdog_ticks=5)
    driver.use_monitor = False  # this test is the monitor
    driver.now = clock = Clock()
    driver.step(0.0, {"omega": spin(9.0)})
    clock.now += 0.2
    assert driver.check_watchdog().name == "watchdog" and driver.fault is None  # no step has reported it
    driver.close()
    assert driver.fault == ("watchdog: no new command for 5 ticks (200 ms since the last, limit 100 ms): outputs "
                            "ramped to zero (after the last step)")


def test_the_centre_field_is_the_winding_average_of_every_turn(make_driver):
    """The current in each coil of the rotation plane against the loop law integrated over the winding's
    cross-section (r 180-215 mm, z 150-190 mm from the centre, 795 turns): B = N mu0 <r^2 / (2 (r^2 + z^2)^1.5)>;
    two opposite coils share the field, so each carries B / (2 g) amplitude."""
    from scipy import integrate

    def loop(z, r):
        return 4e-7 * np.pi * r**2 / (2 * (r**2 + z**2) ** 1.5)

    g = 795 * integrate.dblquad(loop, 0.180, 0.215, 0.150, 0.190)[0] / (0.035 * 0.040)  # [T/A]
    out = make_driver(**LOOSE, field_mT=3.0).step(0.0, {"omega": spin(9.0, (1.0, 0.0, 0.0))})
    current_a = out["coil_voltage_amp"] / z_abs(9.0)
    assert np.allclose(current_a[2:], 3e-3 / (2 * g), rtol=2e-3)  # coils +-y, +-z
    assert np.allclose(current_a[:2], 0.0, atol=1e-12)  # +-x: along the axis of rotation

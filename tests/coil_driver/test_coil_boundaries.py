"""Each interlock at its boundary, from both sides, each side on a fresh driver.

A fresh driver per case: a latched fault from an earlier case would make
every later check pass (the output is zero whatever the command). The
margin is one part in a million (``EPS``), so a limit moved by even 0.01 %
fails one side.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from coil_fakes import DT, RecordingReference, spin

from cosim_plugins.coil_driver.backends import Rig
from cosim_plugins.coil_driver.interlocks import ThermalBudget
from cosim_plugins.coil_driver.visa_backend import Reading
from cosim_plugins.vec3 import length

R, L, C = 12.9, 0.411, 430e-6  # the driver's default coil
LOOSE = {"v_max": 1e4, "i_max_a": 1e3, "i_trip_a": 1e3, "slew_v_per_s": 1e9}
EPS = 1e-6
BELOW, ABOVE = 1 - EPS, 1 + EPS


def z_abs(f_hz: float) -> float:
    w = 2 * math.pi * f_hz
    return math.hypot(R, w * L - 1 / (w * C))


def free_peak(make_driver, f_hz: float = 9.0, axis=(1.0, 1.0, 0.5)) -> float:
    """The largest coil voltage amplitude [V] the command asks for, no limit binding."""
    return float(make_driver(**LOOSE).step(0.0, {"omega": spin(f_hz, axis)})["coil_voltage_amp"].max())


# ---------------------------------------------------------------- trip: unsafe command (spin frequency)


@pytest.mark.parametrize("f_limit_hz", [5.0, 25.0, 60.0])
def test_spin_frequency_limit_from_both_sides(make_driver, f_limit_hz):
    omega = spin(f_limit_hz, (0.3, -0.4, 1.0))
    at = length(tuple(omega.tolist())) / (2 * math.pi)  # the frequency exactly as the driver computes it
    for factor, trips in ((1.0, False), (BELOW, False), (ABOVE, True)):
        driver = make_driver(**{**LOOSE, "f_limit_hz": at})
        out = driver.step(0.0, {"omega": omega * factor})
        if trips:
            assert driver.tripped is not None and driver.tripped.name == "unsafe_command", factor
            assert np.all(out["coil_voltage_amp"] == 0) and float(out["drive_freq"]) == 0
        else:
            assert driver.fault is None, factor
            assert out["coil_voltage_amp"].max() > 0 and float(out["drive_freq"]) == pytest.approx(at * factor)


def test_the_default_spin_limit_is_60_hz(make_driver):
    assert make_driver().step(0.0, {"omega": spin(60.0 * BELOW)})["coil_voltage_amp"].max() > 0
    driver = make_driver()
    driver.step(0.0, {"omega": spin(60.0 * ABOVE)})
    assert driver.tripped is not None and driver.tripped.name == "unsafe_command"


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_non_finite_component_trips_a_fresh_driver(make_driver, value, axis):
    driver = make_driver()
    omega = spin(8.0, (1.0, 1.0, 1.0))
    omega[axis] = value
    out = driver.step(0.0, {"omega": omega})
    assert driver.fault.startswith("unsafe_command: unsafe command omega")
    assert np.all(out["coil_voltage_amp"] == 0) and float(out["drive_freq"]) == 0


def test_below_f_min_the_field_is_off_without_a_fault(make_driver):
    low = make_driver(f_min_hz=2.0)
    out = low.step(0.0, {"omega": spin(2.0 * BELOW)})
    assert np.all(out["coil_voltage_amp"] == 0) and float(out["drive_freq"]) == 0 and low.fault is None
    high = make_driver(f_min_hz=2.0)
    out = high.step(0.0, {"omega": spin(2.0 * ABOVE)})
    assert out["coil_voltage_amp"].max() > 0 and float(out["drive_freq"]) == pytest.approx(2.0 * ABOVE)


# ---------------------------------------------------------------- shaping limits


@pytest.mark.parametrize("limit", ["v_max", "i_max_a", "slew_v_per_s"])
def test_each_shaping_limit_from_both_sides(make_driver, limit):
    """Just above the command the limit is idle (output = command); just below, the peak sits on the limit."""
    f_hz, axis = 9.0, (1.0, 1.0, 0.5)
    free = make_driver(**LOOSE).step(0.0, {"omega": spin(f_hz, axis)})["coil_voltage_amp"]
    peak = free.max()
    # the value of the limit that the free command just meets, in the limit's own unit
    meets = {"v_max": peak, "i_max_a": peak / z_abs(f_hz), "slew_v_per_s": peak / DT}[limit]  # V, A, V/s
    idle = make_driver(**{**LOOSE, limit: meets * ABOVE}).step(0.0, {"omega": spin(f_hz, axis)})
    np.testing.assert_array_equal(idle["coil_voltage_amp"], free)
    bound = make_driver(**{**LOOSE, limit: meets * BELOW}).step(0.0, {"omega": spin(f_hz, axis)})
    assert bound["coil_voltage_amp"].max() == pytest.approx(peak * BELOW, rel=1e-12)
    np.testing.assert_allclose(bound["coil_voltage_amp"], free * BELOW, rtol=1e-12)  # all coils together


def test_the_slew_limit_counts_from_the_previous_tick(make_driver):
    """A rise of exactly one tick's slew from a held amplitude passes; a larger one is cut to it."""
    slew = 100.0  # V/s: 2 V per 20 ms tick
    driver = make_driver(**{**LOOSE, "slew_v_per_s": slew})
    omega = spin(9.0, (1.0, 0.0, 0.0))
    peaks = [driver.step(k * DT, {"omega": omega})["coil_voltage_amp"].max() for k in range(3)]
    assert peaks == pytest.approx([2.0, 4.0, 6.0], rel=1e-12)


# ---------------------------------------------------------------- trip: thermal budget


def test_thermal_budget_exactly_met_is_within_and_above_it_trips():
    one_amp = [1.0, 0, 0, 0, 0, 0]  # 1 A amplitude in 2 ohm for 1 s: 1 J
    assert ThermalBudget(r_ohm=2.0, dt_s=1.0, window_s=1.0, budget_j=1.0).add(one_amp) is None
    fault = ThermalBudget(r_ohm=2.0, dt_s=1.0, window_s=1.0, budget_j=1.0 * BELOW).add(one_amp)
    assert fault is not None and fault.name == "thermal_budget" and "coil +x" in fault.message
    other = ThermalBudget(r_ohm=2.0, dt_s=1.0, window_s=1.0, budget_j=1.0 * BELOW).add([0, 0, 0, 0, 0, 1.0])
    assert other is not None and "coil -z" in other.message  # the coil over budget is the one named


@pytest.mark.parametrize("ticks", [1, 4])
def test_thermal_budget_of_a_driver_from_both_sides(make_driver, ticks):
    omega = spin(9.0, (1.0, 0.0, 0.0))
    current = make_driver().step(0.0, {"omega": omega})["coil_voltage_amp"].max() / z_abs(9.0)  # A
    per_tick = current**2 * R / 2 * DT  # J in the hottest coil per tick
    window = {"thermal_window_s": 10.0}
    within = make_driver(thermal_budget_j=ticks * per_tick * ABOVE, **window)
    for k in range(ticks):
        within.step(k * DT, {"omega": omega})
    assert within.fault is None
    over = make_driver(thermal_budget_j=ticks * per_tick * BELOW, **window)
    for k in range(ticks):
        out = over.step(k * DT, {"omega": omega})
        assert (over.fault is None) == (k < ticks - 1)
    assert over.fault.startswith("thermal_budget: coil ") and np.all(out["coil_voltage_amp"] == 0)


# ---------------------------------------------------------------- trip: watchdog


@pytest.mark.parametrize("ticks", [1, 3, 5])
def test_watchdog_from_both_sides(make_driver, ticks):
    for late, trips in ((ticks, False), (ticks + 1, True)):
        driver = make_driver(watchdog_ticks=ticks, watchdog_clock="sim")
        driver.step(0.0, {"omega": spin(8.0)})
        out = driver.step(late * DT, {"omega": spin(8.0)})
        if trips:
            assert driver.tripped is not None and driver.tripped.name == "watchdog"
            assert np.all(out["coil_voltage_amp"] == 0)
        else:
            assert driver.fault is None and out["coil_voltage_amp"].max() > 0


# ---------------------------------------------------------------- trip: measured overcurrent


class ReadingSupplies:
    """Stands in for the supplies: every poll reads ``current_a`` on coil -y's second supply."""

    def __init__(self, current_a: float):
        self.current_a, self.stops = current_a, 0

    def open(self):
        pass

    def start(self):
        pass

    def poll(self, tick):
        return [Reading(coil=3, supply=1, address="GPIB0::8::INSTR", current_a=self.current_a)]

    def stop(self):
        self.stops += 1

    def close(self):
        pass


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_overcurrent_from_both_sides(make_driver, sign):
    trip = 3.6
    for factor, trips in ((1.0, False), (BELOW, False), (ABOVE, True)):
        supplies = ReadingSupplies(sign * trip * factor)
        driver = make_driver(rig=Rig(RecordingReference([]), supplies), i_trip_a=trip, watchdog_clock="sim")
        out = driver.step(0.0, {"omega": spin(8.0)})
        if trips:
            assert driver.fault.startswith("overcurrent: supply GPIB0::8::INSTR (coil -y, supply 2)")
            assert np.all(out["coil_voltage_amp"] == 0) and supplies.stops == 1
        else:
            assert driver.fault is None and supplies.stops == 0


class StoppedClock:
    """A wall clock that moves only when the test sets ``t`` [s]."""

    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


@pytest.mark.parametrize("ticks", [1, 5])
def test_watchdog_on_the_wall_clock_from_both_sides(make_driver, ticks):
    """Between ticks the monitor's check trips just after ``ticks`` periods, not before."""
    for elapsed, trips in ((ticks * DT * BELOW, False), (ticks * DT * ABOVE + 2e-9, True)):
        driver = make_driver(rig=Rig(RecordingReference([])), watchdog_ticks=ticks, watchdog_clock="wall")
        driver.now = clock = StoppedClock()
        driver.use_monitor = False  # the test calls the monitor's check itself
        driver.step(0.0, {"omega": spin(8.0)})
        clock.t += elapsed
        fault = driver.check_watchdog()
        assert (fault is not None and fault.name == "watchdog") == trips, elapsed


# ---------------------------------------------------------------- the interlocks' parts, at their edges


def test_limit_scale_is_one_when_nothing_binds_even_for_tiny_amplitudes():
    from cosim_plugins.coil_driver.interlocks import Limits, limit_scale

    assert limit_scale([0.0] * 6, [0.0] * 6, 10.0, DT, Limits(40.0, 3.0, 2000.0)) == 1.0  # no field at all
    small = [0.3, 0.1, 0.2, 0.0, 0.05, 0.3]  # V, all within a 0.5 V limit
    assert limit_scale(small, small, 10.0, DT, Limits(0.5, 100.0, 1e9)) == 1.0
    assert limit_scale(small, small, 10.0, DT, Limits(0.15, 100.0, 1e9)) == pytest.approx(0.5)


def test_a_one_tick_thermal_window_forgets_the_previous_tick():
    """window_s = dt: only the current tick counts; 1 J per tick against 1.5 J never trips."""
    budget = ThermalBudget(r_ohm=2.0, dt_s=0.5, window_s=0.5, budget_j=0.75)  # 1 A: 0.5 J per tick
    assert budget.window_ticks == 1
    assert all(budget.add([1.0, 0, 0, 0, 0, 0]) is None for _ in range(5))
    two = ThermalBudget(r_ohm=2.0, dt_s=0.5, window_s=1.0, budget_j=0.75)  # two ticks: the second trips
    assert two.add([1.0, 0, 0, 0, 0, 0]) is None and two.add([1.0, 0, 0, 0, 0, 0]) is not None


def test_the_thermal_fault_names_the_hottest_coil():
    budget = ThermalBudget(r_ohm=2.0, dt_s=1.0, window_s=1.0, budget_j=0.5)
    fault = budget.add([2.0, 1.5, 0, 0, 1.0, 0])  # +x 4 J, -x 2.25 J, +z 1 J: all over 0.5 J
    assert fault.message == "coil +x dissipated 4.0 J in the last 1 s (budget 0.5 J)"


def test_the_watchdog_at_its_exact_limit_and_its_message():
    from cosim_plugins.coil_driver.interlocks import Watchdog

    dog = Watchdog(timeout_s=0.1, ticks=5)
    assert dog.check(50.0) is None  # never kicked: nothing to time
    dog.kick(0.0)
    assert dog.check(0.1 + 1e-9) is None  # exactly the limit (and its nanosecond of slack)
    fault = dog.check(2.0)
    assert fault.name == "watchdog"
    assert fault.message == ("no new command for 5 ticks (2000 ms since the last, limit 100 ms): "
                             "outputs ramped to zero")
    slow = Watchdog(timeout_s=2.0, ticks=100)
    slow.kick(0.0)
    assert "(3000 ms since the last, limit 2000 ms)" in slow.check(3.0).message


def test_a_fault_reported_by_the_hardware_trips_the_driver(make_driver):
    from cosim_plugins.coil_driver.interlocks import BackendFault, Fault

    class FailingReference(RecordingReference):
        def deliver(self, tick, amp_v, phase_rad, freq_hz):
            raise BackendFault(Fault("daq_error", "task stopped: buffer underflow"))

    error = BackendFault(Fault("daq_error", "task stopped: buffer underflow"))
    assert str(error) == "daq_error: task stopped: buffer underflow" and error.fault.name == "daq_error"
    driver = make_driver(rig=Rig(FailingReference([])), watchdog_clock="sim")
    out = driver.step(0.0, {"omega": spin(8.0)})
    assert driver.fault == "daq_error: task stopped: buffer underflow"
    assert np.all(out["coil_voltage_amp"] == 0)


def test_an_unknown_fault_name_is_refused_naming_the_known_ones():
    from cosim_plugins.coil_driver.interlocks import FAULT_NAMES, Fault

    with pytest.raises(ValueError) as err:
        Fault("melted", "coil +x")
    assert str(err.value) == f"unknown fault 'melted'; known: {', '.join(FAULT_NAMES)}"
    assert "unsafe_command, thermal_budget, watchdog" in str(err.value)


# ---------------------------------------------------------------- which spins get a field


def amp(out) -> float:
    return float(out["coil_voltage_amp"].max())


def test_a_spin_exactly_at_f_min_and_a_slow_1_hz_one_are_driven(make_driver):
    at = make_driver(f_min_hz=2.0).step(0.0, {"omega": spin(2.0)})  # |omega| / 2 pi is exactly 2.0
    assert amp(at) > 0 and float(at["drive_freq"]) == 2.0
    slow = make_driver().step(0.0, {"omega": spin(1.0)})
    assert amp(slow) > 0 and float(slow["drive_freq"]) == 1.0


def test_a_1_mt_field_is_driven_and_a_zero_field_is_no_field(make_driver):
    one = make_driver(field_mT=1.0).step(0.0, {"omega": spin(9.0)})
    three = make_driver(field_mT=3.0).step(0.0, {"omega": spin(9.0)})
    np.testing.assert_allclose(three["coil_voltage_amp"], 3.0 * one["coil_voltage_amp"], rtol=1e-9)  # linear in B
    off = make_driver(field_mT=0.0).step(0.0, {"omega": spin(9.0)})
    assert amp(off) == 0.0 and float(off["drive_freq"]) == 0.0  # nothing to drive: no frequency either


def test_a_steady_spin_keeps_its_phases_in_absolute_time(make_driver):
    """The coils are driven as cos(2 pi f t + phase): a spin that does not change keeps the same phases, tick
    after tick, over several turns of 2 pi f t (9 Hz: a turn every 111 ms, so 2 pi f t passes 2 pi, 3 pi...)."""
    driver = make_driver()
    outs = [driver.step(0.02 * k, {"omega": spin(9.0, (1.0, 0.5, 0.25))}) for k in range(40)]
    phasors = np.array([o["coil_voltage_amp"] * np.exp(1j * o["coil_voltage_phase"]) for o in outs])
    np.testing.assert_allclose(phasors, np.repeat(phasors[:1], 40, axis=0), rtol=0, atol=1e-9 * np.abs(phasors).max())


def field_at(driver, out, t: float) -> np.ndarray:
    """The centre field [T] (3,) at time t of the outputs ``out``: coil i driven as amp_i cos(2 pi f t + phase_i)."""
    from cosim_plugins.coil_driver.actuation import impedance_ohm

    f = float(out["drive_freq"])
    current = out["coil_voltage_amp"] * np.exp(1j * out["coil_voltage_phase"]) / impedance_ohm(f, *driver.rlc)
    return np.real(np.linalg.pinv(driver.m_pinv) @ current * np.exp(2j * np.pi * f * t))


def test_a_new_spin_rate_starts_where_the_field_points(make_driver):
    """9 Hz, then 11 Hz about the same axis: at the change the field keeps its direction (the magnet
    would lose step otherwise); only the rate of its turning changes."""
    driver = make_driver()
    old = [driver.step(0.02 * k, {"omega": spin(9.0)}) for k in range(10)][-1]
    new = driver.step(0.2, {"omega": spin(11.0)})
    before, after = field_at(driver, old, 0.2), field_at(driver, new, 0.2)
    assert np.dot(before, after) / (np.linalg.norm(before) * np.linalg.norm(after)) > 0.9999

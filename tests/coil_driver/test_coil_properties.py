"""Safety properties of the coil driver, for any command sequence (hypothesis).

Whatever the controller sends (NaN, inf, huge, changing every tick, late),
and whatever the limits are set to, what the driver outputs stays within
every shaping limit, a command it refuses never becomes a voltage, and once
a fault latches every output is zero. The reference here is written from
the parameters' documentation, not from the driver's code: the impedance is
the series RLC's, the energy is ``I^2 R / 2`` per tick over the window.
"""

from __future__ import annotations

import math

import numpy as np
from coil_fakes import DT
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cosim_plugins.coil_driver.inverse import InverseMagnetics

R, L, C = 12.9, 0.411, 430e-6  # the driver's default coil: series R [ohm], L [H], C [F]
REL = 1e-9  # rounding slack of a limit comparison, relative


def z_abs(f_hz: float) -> float:
    """|R + j(wL - 1/(wC))| [ohm] at ``f_hz`` (> 0), written out independently of the driver's helper."""
    w = 2 * math.pi * f_hz
    return math.hypot(R, w * L - 1 / (w * C))


# one omega component [rad/s]: ordinary, huge, or not finite
component = st.one_of(
    st.floats(-500.0, 500.0),
    st.sampled_from([0.0, math.nan, math.inf, -math.inf, 1e300, -1e300, 2 * math.pi * 60.0]),
    st.floats(allow_nan=True, allow_infinity=True),
)
# a spin about some axis at a fraction of the spin limit: below it, or (rarely) just or far above it
axis = st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)).filter(
    lambda a: math.hypot(*a) > 1e-3)
safe = st.tuples(st.just("spin"), axis, st.one_of(st.floats(0.0, 1.0 - 1e-6), st.just(1.0 - 1e-6)))
over = st.tuples(st.just("spin"), axis,
                 st.one_of(st.sampled_from([1.0 + 1e-6, 1.01, 1.04]), st.floats(1.0 + 1e-6, 3.0)))
raw = st.tuples(st.just("raw"), st.tuples(component, component, component), st.just(0.0))
# mostly safe spins, changing every tick; now and then (one in twenty each) one over the limit, or anything
# at all (NaN, inf, huge): the choice is a middle value of 0..19, which hypothesis does not favour
command = st.tuples(st.integers(0, 19), safe, over, raw).map(lambda c: c[2] if c[0] == 9 else c[3] if c[0] == 10
                                                            else c[1])


def omega_of(cmd, f_limit_hz: float) -> tuple[float, float, float]:
    """omega [rad/s] of a drawn command."""
    kind, vec, fraction = cmd
    if kind == "raw":
        return vec
    norm = math.hypot(*vec)
    w = 2 * math.pi * fraction * f_limit_hz / norm
    return (vec[0] * w, vec[1] * w, vec[2] * w)




def _limits(d: dict) -> dict:
    """Driver parameters from drawn ones: the slew and the thermal budget relative to the other limits,
    so that each binds in some examples (a slew of ``slew_ticks`` ticks from 0 to v_max; a budget of
    ``budget_ticks`` ticks at i_max in one coil)."""
    d = dict(d)
    d["slew_v_per_s"] = d["v_max"] / (d.pop("slew_ticks") * DT)
    d["thermal_budget_j"] = d.pop("budget_ticks") * d["i_max_a"] ** 2 * R / 2 * DT
    return d


params = st.fixed_dictionaries({
    "v_max": st.floats(0.5, 80.0),
    "i_max_a": st.floats(0.05, 5.0),
    "slew_ticks": st.floats(0.5, 20.0),
    "f_limit_hz": st.floats(0.5, 100.0),
    "field_mT": st.floats(0.0, 20.0),
    "budget_ticks": st.floats(0.2, 30.0),
    "thermal_window_s": st.floats(0.02, 0.5),
    "watchdog_ticks": st.integers(1, 4),
    "f_min_hz": st.floats(0.0, 1.0),
}).map(_limits)

# ticks skipped before each command (0: the next tick, mostly); more than watchdog_ticks trips the watchdog
gaps = st.one_of(st.just(0), st.just(0), st.just(0), st.just(0), st.integers(0, 6))

# derandomized: the same examples on every run (CI and mutation runs see one verdict per code)
PROPERTY = settings(max_examples=150, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])


def fresh(**p) -> InverseMagnetics:
    """A driver set up at ``dt`` = 20 ms with simulated-plant backend, the step clock for its watchdog."""
    driver = InverseMagnetics()
    driver.setup({"dt": DT, "i_trip_a": 1e3, "watchdog_clock": "sim", **p}, np.random.default_rng(0))
    return driver


def unsafe(omega, f_limit_hz: float) -> bool:
    """What the parameters document as an unsafe command: not finite, or spinning above the limit."""
    if not all(math.isfinite(w) for w in omega):
        return True
    return math.sqrt(sum(w * w for w in omega)) / (2 * math.pi) > f_limit_hz


@PROPERTY
@given(p=params, commands=st.lists(st.tuples(command, gaps), min_size=1, max_size=25))
def test_any_command_sequence_stays_within_every_limit_and_a_fault_zeroes_everything(p, commands):
    driver = fresh(**p)
    try:
        tick, prev_amp, fault_at = 0, np.zeros(6), None
        window = max(1, int(round(p["thermal_window_s"] / DT)))
        energies = []  # delivered energy [J] of each coil per step, (steps, 6)
        for i, (cmd, gap) in enumerate(commands):
            omega = omega_of(cmd, p["f_limit_hz"])
            tick += gap if i else 0
            out = driver.step(tick * DT, {"omega": np.array(omega, dtype=float)})
            amp, phase, freq = out["coil_voltage_amp"], out["coil_voltage_phase"], float(out["drive_freq"])
            assert amp.shape == (6,) and phase.shape == (6,)
            assert np.all(np.isfinite(amp)) and np.all(np.isfinite(phase)) and math.isfinite(freq)
            assert np.all(amp >= 0.0)

            expected = None
            if fault_at is None and i and gap > p["watchdog_ticks"]:
                expected = "watchdog"
            elif fault_at is None and unsafe(omega, p["f_limit_hz"]):
                expected = "unsafe_command"
            if expected is not None:  # the first trip is named, whatever else happens later
                assert driver.tripped is not None and driver.tripped.name == expected, (i, driver.tripped)
            if fault_at is None and driver.tripped is not None:
                fault_at = i
                assert driver.fault and driver.fault.startswith(driver.tripped.name)
            if fault_at is not None:  # the faulty tick and every one after it: nothing at all
                assert np.all(amp == 0.0) and np.all(phase == 0.0) and freq == 0.0
            if unsafe(omega, p["f_limit_hz"]):
                assert np.all(amp == 0.0) and freq == 0.0  # a refused command never becomes a voltage

            # the shaping limits hold on what is delivered
            assert np.all(amp <= p["v_max"] * (1 + REL))
            if freq > 0.0:
                assert p["f_min_hz"] <= freq <= p["f_limit_hz"]
                assert np.all(amp / z_abs(freq) <= p["i_max_a"] * (1 + REL))
                energies.append((amp / z_abs(freq)) ** 2 * R / 2 * DT)
            else:
                assert np.all(amp == 0.0)
                energies.append(np.zeros(6))
            assert np.all(amp - prev_amp <= p["slew_v_per_s"] * DT * (1 + REL) + 1e-12)  # rises only
            prev_amp = amp
            # no window of delivered ticks ever exceeds the thermal budget
            recent = np.sum(energies[-window:], axis=0)
            assert np.all(recent <= p["thermal_budget_j"] * (1 + REL)), (recent, p["thermal_budget_j"])
        if fault_at is None:
            assert driver.fault is None and driver.tripped is None
    finally:
        driver.close()


@settings(max_examples=60, deadline=None, derandomize=True)
@given(good=st.lists(st.floats(0.1, 50.0), min_size=0, max_size=5),
       bad=st.sampled_from([math.nan, math.inf, -math.inf]), axis=st.integers(0, 2),
       after=st.lists(st.tuples(component, component, component), min_size=1, max_size=5))
def test_a_non_finite_component_trips_at_once_and_nothing_after_it_reaches_the_coils(good, bad, axis, after):
    driver = fresh()
    try:
        for k, f in enumerate(good):  # ordinary commands first (possibly none: a fresh driver)
            driver.step(k * DT, {"omega": np.array([0.0, 0.0, 2 * math.pi * f])})
            assert driver.fault is None
        omega = np.zeros(3)
        omega[axis] = bad
        out = driver.step(len(good) * DT, {"omega": omega})
        assert driver.tripped.name == "unsafe_command"
        assert np.all(out["coil_voltage_amp"] == 0.0) and float(out["drive_freq"]) == 0.0
        for k, later in enumerate(after, start=len(good) + 1):  # even a good command after it: latched
            out = driver.step(k * DT, {"omega": np.array(later, dtype=float)})
            assert np.all(out["coil_voltage_amp"] == 0.0) and float(out["drive_freq"]) == 0.0
            assert driver.tripped.name == "unsafe_command"
    finally:
        driver.close()

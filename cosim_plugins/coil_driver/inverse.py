"""Inverse magnetics: rotation vector omega -> coil voltage phasors, through the interlocks, to a backend.

omega [rad/s] -> a field of ``field_mT`` rotating about omega at
``|omega| / 2 pi`` Hz -> least-norm coil current phasors from the centre
field matrix -> voltage phasors through each coil's series RLC impedance ->
the shaping limits (voltage, current, slew: all coils scaled down together,
so the field keeps its direction and loses magnitude) -> the backend.

The field stays continuous when the command changes: the plant's coils are
driven as ``cos(2 pi f t + phase)`` in absolute time, so the driver starts
each new command's rotation where the field points now (projected onto the
new rotation plane) and offsets every phase by ``-2 pi f t``. Without that, a
frequency change of df would jump the field's angle by ``2 pi df t`` and the
magnet would lose step.

Safety (see :mod:`cosim_plugins.coil_driver.interlocks`): a non-finite omega,
or one above ``f_limit_hz``, never reaches the coils; neither does anything
after a trip (thermal budget, watchdog, measured overcurrent, a supply's or
the DAQ's error). On a trip the driver outputs zero field, the backend ramps
its reference to zero and switches the supplies off, and the driver sets
``fault`` (named: ``"thermal_budget: coil +x dissipated ..."``), which stops
the run cleanly with status ``fault``. ``close()`` makes the same safe stop,
at the end of every run, also after another component's failure.
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np

from cosim import Component, ComponentError, Port
from cosim_plugins.coil_driver import params as coil_params
from cosim_plugins.coil_driver.actuation import (
    centre_matrix,
    field_direction,
    impedance_ohm,
    loop_field_on_axis_t_per_a,
    plane_start,
    rotating_field_phasor,
)
from cosim_plugins.coil_driver.backends import Rig, uses
from cosim_plugins.coil_driver.daq_backend import DaqReference
from cosim_plugins.coil_driver.interlocks import (
    COIL_NAMES,
    BackendFault,
    Fault,
    Limits,
    ThermalBudget,
    Watchdog,
    limit_scale,
    unsafe_command,
)
from cosim_plugins.coil_driver.visa_backend import KepcoSupplies
from cosim_plugins.vec3 import Vec3, div, length

PARAMS = coil_params.PARAMS

#: Six zero amplitudes, as floats (never mutated).
ZERO_6 = (0.0,) * 6


def build_rig(p: dict, dt_s: float) -> Rig:
    """The backend's hardware parts from the checked parameters ``p`` (nothing opened yet)."""
    reference = supplies = None
    if uses(p["backend"], "daq"):
        reference = DaqReference(p["daq_channels"], p["daq_rate_hz"], dt_s, p["daq_gain_v_per_v"],
                                 p["daq_ao_max_v"], p["daq_prefill_chunks"], p["ramp_s"])
    if uses(p["backend"], "visa"):
        supplies = KepcoSupplies(p["visa_resources"], p["supplies_per_coil"], p["visa_library"],
                                 p["v_max"] / p["supplies_per_coil"], p["i_trip_a"], p["visa_idn"],
                                 p["visa_timeout_ms"], p["readback_ticks"])
    return Rig(reference, supplies)


class InverseMagnetics(Component):
    """omega -> rotating field -> least-norm coil currents -> RLC voltages -> interlocks -> backend."""

    inputs = (Port("omega", (3,), "rad/s", "commanded rotation vector"),)
    outputs = (
        Port("coil_voltage_amp", (6,), "V", "voltage amplitude per coil"),
        Port("coil_voltage_phase", (6,), "rad", "voltage phase per coil"),
        Port("drive_freq", (), "Hz", "drive frequency"),
    )

    #: The fault that tripped, if any (``fault`` holds its text once a step has reported it).
    tripped: Fault | None = None

    @classmethod
    def validate_params(cls, params):
        coil_params.read(params)

    def setup(self, params, rng, rig: Rig | None = None):
        """``rig``: the hardware to drive instead of the one ``backend`` names (tests pass fakes)."""
        p = self.p = coil_params.read(params)
        self.dt = float(params.get("dt", 0.02))
        g = loop_field_on_axis_t_per_a(p["turns"], p["r_inner_mm"] * 1e-3, p["r_outer_mm"] * 1e-3,
                                       p["z_near_mm"] * 1e-3, (p["z_near_mm"] + p["thickness_mm"]) * 1e-3)
        # (6, 3) A/T, complex like the field phasors it multiplies (numpy would cast it every step)
        self.m_pinv = np.linalg.pinv(centre_matrix(g)).astype(complex)
        self.zero = {"coil_voltage_amp": np.zeros(6), "coil_voltage_phase": np.zeros(6), "drive_freq": np.array(0.0)}
        self.rotation = None  # (n, e1, f_hz, t0_s) of the field being driven: angle 2 pi f (t - t0)
        self.limits = Limits(p["v_max"], p["i_max_a"], p["slew_v_per_s"])
        self.prev_amp = ZERO_6  # the six amplitudes [V] delivered at the previous step
        # the parameters step() reads, looked up once
        self.f_limit_hz, self.f_min_hz, self.field_mT = p["f_limit_hz"], p["f_min_hz"], p["field_mT"]
        self.field_t = self.field_mT * 1e-3
        self.rlc = (p["r_ohm"], p["l_h"], p["c_f"])  # series R [ohm], L [H], C [F]
        self.thermal = ThermalBudget(p["r_ohm"], self.dt, p["thermal_window_s"], p["thermal_budget_j"])
        self.watchdog = Watchdog(p["watchdog_ticks"] * self.dt, p["watchdog_ticks"])
        self.rig = rig if rig is not None else build_rig(p, self.dt)
        clock = p["watchdog_clock"]
        self.wall_clock = clock == "wall" or (clock == "auto" and self.rig.hardware)
        self.now = time.monotonic  # the wall clock, replaceable in tests
        self.use_monitor = self.wall_clock  # tests that call check_watchdog() themselves turn it off
        self.closed = False
        self._reported = False  # whether a step has reported the trip through ``fault``
        self._lock = threading.RLock()  # step, the watchdog monitor and close() each drive the rig
        self._monitor: threading.Thread | None = None
        self._monitor_stop = threading.Event()
        try:
            self.rig.open()
        except Exception as exc:  # one line, whatever the driver's message
            raise ComponentError(f"backend {p['backend']!r}: {' '.join(str(exc).split())}") from exc

    def initial_outputs(self):
        return self.zero

    def step(self, t, inputs):
        with self._lock:
            if self.closed:  # stopped (Ctrl-C, the end of a run): nothing reaches the coils any more
                return self.zero
            if self.tripped is not None:
                return self._report()
            fault = self._kick_watchdog(t)
            if fault is None:
                omega = inputs["omega"]
                omega_rad_s = tuple(omega.tolist())
                f_hz = length(omega_rad_s) / (2 * math.pi)
                fault = unsafe_command(omega, f_hz, self.f_limit_hz)
            if fault is not None:
                return self._trip(fault)
            out, amp_v, current_amp = self._phasors(t, omega_rad_s, f_hz)
            fault = self.thermal.add(current_amp)
            if fault is None and self.rig.hardware:
                fault = self._deliver(t, out)
            if fault is not None:
                return self._trip(fault)
            self.prev_amp = amp_v
            return out

    def _kick_watchdog(self, t: float) -> Fault | None:
        """A fault when the time since the previous command exceeds the watchdog's (step time or wall clock)."""
        now = self.now() if self.wall_clock else t
        fault = self.watchdog.check(now)
        self.watchdog.kick(now)
        if self.use_monitor and self._monitor is None:
            self._start_monitor()
        return fault

    def _phasors(self, t: float, omega_rad_s: Vec3, f_hz: float
                 ) -> tuple[dict[str, np.ndarray], list[float], list[float]]:
        """The outputs for ``omega_rad_s`` (spinning at ``f_hz`` = |omega| / 2 pi) at ``t`` within the
        shaping limits, with the six voltage amplitudes [V] and the six current amplitudes [A] as floats."""
        if f_hz < self.f_min_hz or f_hz == 0.0 or self.field_mT == 0.0:  # no rotation: no field
            self.rotation = None
            return self.zero, ZERO_6, ZERO_6
        n = div(omega_rad_s, 2 * math.pi * f_hz)
        now = None
        if self.rotation is not None:  # where the field points now, continued in the new plane
            n0, e10, f0, t0 = self.rotation
            now = field_direction(n0, e10, 2 * math.pi * f0 * (t - t0))
        e1 = plane_start(n, now)
        self.rotation = (n, e1, f_hz, t)
        # the complex products stay numpy's: its matrix product, complex multiply and abs round
        # differently from Python's complex arithmetic (BLAS, SIMD loops), and the bits must not change
        field = np.array(rotating_field_phasor(n, e1, self.field_t))
        current = self.m_pinv.dot(field)  # (6,) complex A
        z = impedance_ohm(f_hz, *self.rlc)
        z_abs = abs(z)
        volts = current * z
        amp = np.abs(volts)
        amp_v = amp.tolist()
        scale = limit_scale(amp_v, self.prev_amp, z_abs, self.dt, self.limits)
        if scale < 1.0:
            volts = volts * scale
            amp = np.abs(volts)
            amp_v = amp.tolist()
        # np.angle(volts), less its call overhead; angle 0 at t, in absolute time
        phase = np.arctan2(volts.imag, volts.real) - (2 * math.pi * f_hz * t) % (2 * math.pi)
        out = {"coil_voltage_amp": amp, "coil_voltage_phase": phase, "drive_freq": np.array(f_hz)}
        return out, amp_v, [a / z_abs for a in amp_v]

    def _deliver(self, t: float, out: dict[str, np.ndarray]) -> Fault | None:
        """Start the rig at the first command, hand it this tick's phasors, check its readings."""
        try:
            if not self.rig.running:
                self.rig.start()
            readings = self.rig.deliver(int(round(t / self.dt)), out["coil_voltage_amp"],
                                        out["coil_voltage_phase"], float(out["drive_freq"]))
        except BackendFault as exc:
            return exc.fault
        for r in readings:
            if abs(r.current_a) > self.p["i_trip_a"]:
                return Fault("overcurrent", f"supply {r.address} (coil {COIL_NAMES[r.coil]}, supply {r.supply + 1}) "
                                            f"measured {r.current_a:.3f} A (trip {self.p['i_trip_a']:g} A)")
        return None

    def _trip(self, fault: Fault) -> dict[str, np.ndarray]:
        """Latch ``fault``, stop the rig (reference to zero, then outputs off), report, output zero field."""
        self._latch(fault)
        return self._report()

    def _latch(self, fault: Fault) -> None:
        if self.tripped is None:
            self.tripped = fault
        self.rotation = None
        self.prev_amp = ZERO_6
        failures = self.rig.stop()
        if failures:
            self.tripped = Fault(self.tripped.name, f"{self.tripped.message}; stopping the outputs: "
                                                    + "; ".join(map(str, failures)))

    def _report(self) -> dict[str, np.ndarray]:
        self.fault = str(self.tripped)
        self._reported = True
        return self.zero

    # ------------------------------------------------------------------ watchdog monitor (wall clock)

    def _start_monitor(self) -> None:
        """Check the watchdog between steps too: a hung upstream never calls step() at all."""
        self._monitor = threading.Thread(target=self._watch, name="coil-driver-watchdog", daemon=True)
        self._monitor.start()

    def _watch(self) -> None:
        """Look every half period, or every quarter of the watchdog's time-out if that is shorter: a hung
        upstream is caught at most 1.25 time-outs after its last command."""
        period = min(self.dt / 2, self.watchdog.timeout_s / 4)
        while not self._monitor_stop.wait(period):
            self.check_watchdog()

    def check_watchdog(self) -> Fault | None:
        """The monitor's check: on expiry, ramp the outputs to zero and latch the fault for the next step."""
        with self._lock:
            if self.closed or self.tripped is not None:
                return None
            fault = self.watchdog.check(self.now())
            if fault is not None:
                self._latch(fault)
            return fault

    # ------------------------------------------------------------------ stop

    def close(self):
        """Safe stop: reference ramped to zero, then the supplies' outputs off, then disconnect.

        Called by the framework at the end of every run, on a stop and after a
        failure, possibly from another thread than step()'s; a step in
        progress is waited for (at most 2 s: a step stuck in a hardware call
        is not). Idempotent. A part that fails to stop, or a trip no step has
        reported yet (the watchdog monitor's, after the last step), sets
        ``fault``: the run ends with status ``fault`` and names it.
        """
        self._monitor_stop.set()
        if self._monitor is not None and self._monitor is not threading.current_thread():
            self._monitor.join(timeout=2.0)
        locked = self._lock.acquire(timeout=2.0)
        try:
            if self.closed:
                return
            self.closed = True
            failures = self.rig.stop()
            self.rig.close()
            problems = [str(f) for f in failures]
            if self.tripped is not None and not self._reported:
                problems.insert(0, f"{self.tripped} (after the last step)")
            if problems:
                self.fault = "; ".join(problems)
        finally:
            if locked:
                self._lock.release()

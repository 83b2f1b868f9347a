"""The coil driver's interlocks: what may reach the coils, and when to stop.

Every backend (``fmu``, ``visa``, ``daq``) sits below these; a backend only
delivers what passed them. Two kinds of rule:

*Shaping limits* bend the command and the run goes on. Each scales all six
voltage phasors by one common factor, so the field keeps its direction and
rotation and only loses magnitude:

* voltage: a coil's voltage amplitude above ``v_max`` [V];
* current: a coil's current amplitude (voltage / series RLC impedance)
  above ``i_max`` [A];
* slew: a coil's voltage amplitude rising faster than ``slew_v_per_s``
  [V/s] from one tick to the next. Falls are never limited: going towards
  zero is the safe direction, and a fault must be able to zero at once.

*Trips* latch a named :class:`Fault`; the bridge zeroes its outputs, the
backend ramps its reference to zero and switches the supplies off, and the
run stops with status ``fault``:

* ``unsafe_command``: omega not finite, or its spin frequency above the limit;
* ``thermal_budget``: a coil's dissipated energy ``I^2 R`` summed over the
  last ``window`` seconds above the budget [J];
* ``watchdog``: no new command for ``watchdog_ticks`` ticks (see :class:`Watchdog`);
* ``overcurrent``: a supply's measured current above the trip level [A];
* ``supply_error`` / ``daq_error``: the hardware reported an error.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cosim_plugins.vec3 import all_finite

#: Coil order of every (6,) array: the cube faces.
COIL_NAMES = ("+x", "-x", "+y", "-y", "+z", "-z")

#: Every fault a run of the coil driver can end with.
FAULT_NAMES = ("unsafe_command", "thermal_budget", "watchdog", "overcurrent", "supply_error", "daq_error")


@dataclass(frozen=True)
class Fault:
    """A named reason to stop driving the coils. ``str()`` is what the run's summary shows."""

    name: str
    message: str

    def __post_init__(self):
        if self.name not in FAULT_NAMES:
            raise ValueError(f"unknown fault {self.name!r}; known: {', '.join(FAULT_NAMES)}")

    def __str__(self) -> str:
        return f"{self.name}: {self.message}"


class BackendFault(RuntimeError):
    """Raised by a backend when its hardware reports a problem; carries the :class:`Fault`."""

    def __init__(self, fault: Fault):
        super().__init__(str(fault))
        self.fault = fault


@dataclass(frozen=True)
class Limits:
    """Shaping limits, per coil: ``v_max`` [V] and ``i_max`` [A] amplitudes, ``slew_v_per_s`` [V/s]."""

    v_max: float
    i_max: float
    slew_v_per_s: float


def limit_scale(amp_v: Sequence[float], prev_amp_v: Sequence[float], z_abs_ohm: float, dt_s: float,
                limits: Limits) -> float:
    """The common factor in [0, 1] that brings all six coils within ``limits``.

    ``amp_v``: the six wanted voltage amplitudes [V]; ``prev_amp_v``: the six
    amplitudes delivered at the previous tick [V]; ``z_abs_ohm``: the coils'
    impedance magnitude at the drive frequency; ``dt_s``: the tick [s].
    Sequences of floats or (6,) arrays alike (the driver passes lists: six
    values are cheaper in Python than through numpy).
    """
    peak = math.nan if any(map(math.isnan, amp_v)) else max(0.0, *amp_v)  # NaN propagates, as in numpy's max
    if peak == 0.0:
        return 1.0
    scale = min(1.0, limits.v_max / peak, limits.i_max * z_abs_ohm / peak)
    rise_v = limits.slew_v_per_s * dt_s
    # the largest scale at which no coil rises faster than the slew limit
    allowed = [(prev + rise_v) / amp for amp, prev in zip(amp_v, prev_amp_v) if amp * scale > prev + rise_v]
    if allowed:
        scale = min(scale, min(allowed))
    return scale


class ThermalBudget:
    """Energy dissipated in each coil over a sliding window, against a budget.

    Each tick adds ``I^2 R / 2 * dt`` per coil (the mean power of a sinusoid
    of amplitude ``I`` [A] in resistance ``R`` [ohm], over ``dt`` [s]); the
    window holds the last ``window_ticks`` ticks.
    """

    def __init__(self, r_ohm: float, dt_s: float, window_s: float, budget_j: float):
        self.r_ohm, self.dt_s, self.budget_j = r_ohm, dt_s, budget_j
        self.window_ticks = max(1, int(round(window_s / dt_s)))
        self._j_per_a2 = r_ohm / 2 * dt_s  # one tick's energy per squared ampere of amplitude [J/A^2]
        self._ring = [[0.0] * 6] * self.window_ticks  # window_ticks x 6 J per tick (rows replaced, never mutated)
        self._next = 0
        self.energy_j = [0.0] * 6  # six coils' J over the window

    def add(self, current_amp_a: Sequence[float]) -> Fault | None:
        """Account one tick at the six current amplitudes ``current_amp_a`` [A]; a fault when over budget."""
        j_per_a2 = self._j_per_a2
        tick_j = [i * i * j_per_a2 for i in current_amp_a]
        oldest_j = self._ring[self._next]
        self.energy_j = energy_j = [e + (new - old) for e, new, old in zip(self.energy_j, tick_j, oldest_j)]
        self._ring[self._next] = tick_j
        self._next = (self._next + 1) % self.window_ticks
        if max(energy_j) <= self.budget_j:
            return None
        over = [k for k, e in enumerate(energy_j) if e > self.budget_j]
        if not over:  # a NaN energy is never over budget
            return None
        k = max(over, key=energy_j.__getitem__)  # the first of the largest
        window_s = self.window_ticks * self.dt_s
        return Fault("thermal_budget", f"coil {COIL_NAMES[k]} dissipated {energy_j[k]:.1f} J in the last "
                                       f"{window_s:g} s (budget {self.budget_j:g} J)")


class Watchdog:
    """Time since the last new command, against a timeout.

    The clock is the caller's: the simulated time of the step for a simulated
    plant (deterministic), or the wall clock for hardware, where a monitor
    checks it between steps too. A new command is a step call carrying the
    omega input: the scheduler calls a component's step only once the input
    stamped for that tick has arrived, so each call is a fresh command (a
    held one when the controller's period is longer than the driver's).
    """

    def __init__(self, timeout_s: float, ticks: int):
        self.timeout_s, self.ticks = timeout_s, ticks
        self.last_s: float | None = None

    def kick(self, now_s: float) -> None:
        self.last_s = now_s

    def check(self, now_s: float) -> Fault | None:
        """A fault when more than the timeout has passed since the last kick (none before the first).

        A nanosecond of slack absorbs the rounding of step times (``k * dt``).
        """
        if self.last_s is None or now_s - self.last_s <= self.timeout_s + 1e-9:
            return None
        return Fault("watchdog", f"no new command for {self.ticks} ticks ({(now_s - self.last_s) * 1e3:.0f} ms "
                                 f"since the last, limit {self.timeout_s * 1e3:.0f} ms): outputs ramped to zero")


def unsafe_command(omega: np.ndarray, f_hz: float, f_limit_hz: float) -> Fault | None:
    """A fault when omega (3,) [rad/s] is not finite or spins faster than ``f_limit_hz``."""
    if f_hz <= f_limit_hz and all_finite(omega):
        return None
    return Fault("unsafe_command", f"unsafe command omega = {omega} rad/s (limit {f_limit_hz:g} Hz): field off")

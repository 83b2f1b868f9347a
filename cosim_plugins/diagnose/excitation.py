"""Spin-rate excitations: the schedules an experiment may apply, and the command shaper that applies one.

An excitation sets only the spin rate f(t) [Hz]; the direction of the rotation
vector stays the path controller's, so the swimmer keeps following its path.
Families (all within the band [f_lo_hz, f_hi_hz]):

* ``steps``: a square wave between the band's ends, ``period_s`` per full cycle;
* ``chirp``: f = mid + half-band sin(phase), the phase's rate sweeping linearly
  from ``chirp_from_hz`` to ``chirp_to_hz`` over ``duration_s``;
* ``constant``: the band's top, throughout;
* ``stop``: stop and go, the band's top for half of ``period_s`` then at rest
  (0 Hz: the coils' field still, the swimmer not propelled) for the other
  half. At rest only what needs no motion of the swimmer moves it (a flow
  pushes it, a drag does not), and each start is a step from rest.

:func:`candidates` lists the excitations an experiment design tries;
``diagnose.spin_schedule`` (:class:`SpinSchedule`) applies one in a scenario.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from cosim import Component, Port
from cosim.contract.component import ComponentError
from cosim.contract.params import Param, read_params

KINDS = ("steps", "chirp", "constant", "stop")
STEP_PERIODS_S = (0.5, 1.0, 2.0, 4.0)  # square-wave periods tried
CHIRPS_HZ = ((0.05, 1.0), (0.1, 3.0))  # chirp sweeps tried (phase rate from, to)
STOP_PERIODS_S = (2.0, 6.0)  # stop-and-go periods tried (half going, half at rest)


@dataclass(frozen=True)
class Excitation:
    """One spin-rate schedule; see the module doc for the families."""

    kind: str
    f_lo_hz: float
    f_hi_hz: float
    duration_s: float
    period_s: float = 1.0
    chirp_from_hz: float = 0.1
    chirp_to_hz: float = 3.0

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"excitation kind {self.kind!r}: one of {', '.join(KINDS)}")
        if not 0.0 <= self.f_lo_hz <= self.f_hi_hz:
            raise ValueError(f"excitation band [{self.f_lo_hz}, {self.f_hi_hz}] Hz: need 0 <= low <= high")
        if self.duration_s <= 0 or self.period_s <= 0:
            raise ValueError("excitation duration_s and period_s must be positive")

    def freq_hz(self, t_s: np.ndarray) -> np.ndarray:
        """(n,) spin rate [Hz] at times ``t_s`` (n,) [s]."""
        t = np.asarray(t_s, dtype=float)
        mid, half = 0.5 * (self.f_lo_hz + self.f_hi_hz), 0.5 * (self.f_hi_hz - self.f_lo_hz)
        if self.kind == "constant":
            return np.full(t.shape, self.f_hi_hz)
        if self.kind in ("steps", "stop"):
            high = np.floor(2.0 * t / self.period_s + 1e-9).astype(int) % 2 == 0
            return np.where(high, self.f_hi_hz, self.f_lo_hz if self.kind == "steps" else 0.0)
        a, b = self.chirp_from_hz, self.chirp_to_hz
        phase = 2.0 * np.pi * (a * t + 0.5 * (b - a) * t * t / self.duration_s)
        return mid + half * np.sin(phase)

    def describe(self) -> str:
        """In words, e.g. 'spin-rate steps between 4.0 and 16.0 Hz every 0.5 s'."""
        band = f"{self.f_lo_hz:.1f} and {self.f_hi_hz:.1f} Hz"
        if self.kind == "constant":
            return f"a constant spin rate of {self.f_hi_hz:.1f} Hz"
        if self.kind == "steps":
            return f"spin-rate steps between {band} every {self.period_s / 2:g} s"
        if self.kind == "stop":
            half = f"{self.period_s / 2:g} s"
            return f"stop and go: {self.f_hi_hz:.1f} Hz for {half}, then at rest for {half}"
        return f"a spin-rate chirp between {band}, {self.chirp_from_hz:g} to {self.chirp_to_hz:g} Hz"

    def params(self) -> dict:
        """The shaper's parameters (``diagnose.spin_schedule``) for this excitation."""
        return asdict(self)


def candidates(band_hz: tuple, duration_s: float, stops: bool = True) -> list[Excitation]:
    """Every excitation an experiment design tries within ``band_hz`` (low, high) [Hz]; the stop-and-go ones
    only when ``stops``."""
    lo, hi = band_hz
    out = [Excitation("steps", lo, hi, duration_s, period_s=p) for p in STEP_PERIODS_S]
    out += [Excitation("chirp", lo, hi, duration_s, chirp_from_hz=a, chirp_to_hz=b) for a, b in CHIRPS_HZ]
    out.append(Excitation("constant", lo, hi, duration_s))
    out += [Excitation("stop", lo, hi, duration_s, period_s=p) for p in STOP_PERIODS_S] if stops else []
    return out


PARAMS = {
    "kind": Param("steps", f"excitation family: {', '.join(KINDS)}"),
    "f_lo_hz": Param(4.0, "low end of the spin-rate band [Hz]", 0.0, 200.0),
    "f_hi_hz": Param(16.0, "high end of the spin-rate band [Hz]", 0.0, 200.0),
    "duration_s": Param(40.0, "length of the schedule (a chirp's sweep) [s]", 1e-3, 1e6),
    "period_s": Param(1.0, "steps, stop: period of the square wave [s]", 1e-3, 1e4),
    "chirp_from_hz": Param(0.1, "chirp: rate of the spin-rate oscillation at the start [Hz]", 0.0, 100.0),
    "chirp_to_hz": Param(3.0, "chirp: rate of the spin-rate oscillation at the end [Hz]", 0.0, 100.0),
}


class SpinSchedule(Component):
    """omega_out = 2 pi f(t) omega_in / |omega_in|: the controller steers, the excitation sets the spin rate."""

    inputs = (Port("omega", (3,), "rad/s", "the controller's rotation vector"),)
    outputs = (Port("omega", (3,), "rad/s", "same direction, the excitation's spin rate"),)

    def setup(self, params, rng):
        p = read_params(params, PARAMS)
        try:
            self.excitation = Excitation(**{k: p[k] for k in PARAMS})
        except ValueError as exc:
            raise ComponentError(str(exc)) from exc

    def initial_outputs(self):
        return {"omega": np.zeros(3)}

    def step(self, t, inputs):
        w = np.asarray(inputs["omega"], dtype=float)
        n = float(np.linalg.norm(w))
        if not np.isfinite(n) or n < 1e-9:
            return {"omega": np.zeros(3)}
        f = float(self.excitation.freq_hz(np.array([t]))[0])
        return {"omega": w / n * (2.0 * np.pi * f)}

"""Where the coil driver's voltages go, and in which order the hardware is switched.

``backend`` names the parts in use:

* ``fmu``: none; the voltage phasors go out on the component's ports only
  (to the simulated plant);
* ``daq``: the analog reference (:class:`DaqReference`), the supplies
  configured by hand;
* ``visa``: the supplies over SCPI (:class:`KepcoSupplies`), the reference
  coming from elsewhere;
* ``visa+daq``: both, the lab rig.

The ports carry the phasors in every case, so a run's record shows what was
commanded. The order is fixed here: on start the reference runs at zero
before the supplies' outputs go on; on stop the reference ramps to zero
before the outputs go off, and every part is stopped even when one fails.
"""

from __future__ import annotations

import numpy as np

from cosim_plugins.coil_driver.daq_backend import DaqReference
from cosim_plugins.coil_driver.interlocks import BackendFault, Fault
from cosim_plugins.coil_driver.visa_backend import KepcoSupplies, Reading

BACKENDS = ("fmu", "visa", "daq", "visa+daq")


def uses(backend: str, part: str) -> bool:
    """Whether ``backend`` (e.g. ``"visa+daq"``) includes ``part`` (``"visa"`` or ``"daq"``)."""
    return part in backend.split("+")


class Rig:
    """The hardware behind the bridge (possibly none). Thread-safety is the caller's."""

    def __init__(self, reference: DaqReference | None = None, supplies: KepcoSupplies | None = None):
        self.reference, self.supplies = reference, supplies
        self.running = False
        self.stopped = False

    @property
    def hardware(self) -> bool:
        return self.reference is not None or self.supplies is not None

    def open(self) -> None:
        """Connect and configure, outputs off. A part that fails leaves the others closed."""
        try:
            if self.reference is not None:
                self.reference.open()
            if self.supplies is not None:
                self.supplies.open()
        except BaseException:
            self.close()
            raise

    def start(self) -> None:
        """Reference running at zero, then the supplies' outputs on."""
        if self.reference is not None:
            self.reference.start()
        if self.supplies is not None:
            self.supplies.start()
        self.running = True

    def deliver(self, tick: int, amp_v: np.ndarray, phase_rad: np.ndarray, freq_hz: float) -> list[Reading]:
        """Hand tick ``tick``'s phasors to the reference; the supplies' readings due at this tick."""
        if self.reference is not None:
            self.reference.deliver(tick, amp_v, phase_rad, freq_hz)
        return self.supplies.poll(tick) if self.supplies is not None else []

    def stop(self) -> list[Fault]:
        """Reference ramped to zero, then outputs off; idempotent. Returns the failures (each part was tried)."""
        if self.stopped:
            return []
        self.stopped, self.running = True, False
        failures = []
        for part, name in ((self.reference, "daq_error"), (self.supplies, "supply_error")):
            if part is None:
                continue
            try:
                part.stop()
            except BackendFault as exc:
                failures.append(exc.fault)
            except Exception as exc:  # a driver's own error: still go on to the next part
                failures.append(Fault(name, f"{type(exc).__name__}: {exc}"))
        return failures

    def close(self) -> None:
        """Disconnect every part (after :meth:`stop`)."""
        for part in (self.reference, self.supplies):
            if part is not None:
                part.close()

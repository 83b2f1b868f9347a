"""Shared helpers of the coil driver tests: constants, omega, stand-ins for the hardware, the simulated supplies."""

from __future__ import annotations

from pathlib import Path

import numpy as np

DT = 0.02
DATA = Path(__file__).parent / "data"
#: The simulated supplies' addresses, coil-major (two per coil): twelve good ones.
ADDRESSES = [f"GPIB0::{i}::INSTR" for i in range(1, 13)]
#: A simulated supply whose output never switches off (see data/kepco_bop.yaml).
STUCK = "GPIB0::13::INSTR"


def spin(f_hz: float, axis=(0.0, 0.0, 1.0)) -> np.ndarray:
    """omega (3,) [rad/s] spinning at ``f_hz`` about ``axis``."""
    a = np.asarray(axis, dtype=float)
    return 2 * np.pi * f_hz * a / np.linalg.norm(a)


class RecordingReference:
    """Stands in for the analog reference: records every call into a shared ``log``.

    ``on_start``/``on_stop``: called at start and stop, e.g. to note the supplies' state then.
    """

    def __init__(self, log: list, on_start=None, on_stop=None):
        self.log = log
        self.delivered: list[tuple[int, np.ndarray]] = []
        self.on_start, self.on_stop = on_start, on_stop

    def open(self):
        self.log.append("reference.open")

    def start(self):
        self.log.append("reference.start")
        if self.on_start:
            self.on_start()

    def deliver(self, tick, amp_v, phase_rad, freq_hz):
        self.log.append("reference.deliver")
        self.delivered.append((tick, amp_v.copy()))

    def stop(self):
        self.log.append("reference.stop")
        if self.on_stop:
            self.on_stop()

    def close(self):
        self.log.append("reference.close")


class SimSupplies:
    """The supplies simulated by pyvisa-sim from a copy of ``data/kepco_bop.yaml`` at ``path``.

    pyvisa-sim keeps each device's state in its library object, which pyvisa
    forgets (and reads afresh from the file) once nothing refers to it; this
    object holds it, so a test can read what the driver's commands left even
    after the driver closed its resource manager. Each query opens a session
    of its own, as another client would; pyvisa shares one resource manager
    per library (the driver's while it is open), so none is closed here.
    """

    def __init__(self, path: Path):
        from pyvisa.highlevel import open_visa_library

        self.library = f"{path}@sim"  # what the driver's visa_library parameter names
        self._visalib = open_visa_library(self.library)

    def _session(self, address: str):
        import pyvisa

        return pyvisa.ResourceManager(self._visalib).open_resource(address, read_termination="\n",
                                                                   write_termination="\n")

    def query(self, address: str, command: str) -> str:
        res = self._session(address)
        try:
            return res.query(command).strip()
        finally:
            res.close()

    def write(self, address: str, command: str) -> None:
        res = self._session(address)
        try:
            res.write(command)
        finally:
            res.close()

    def outputs(self, addresses=ADDRESSES) -> list[int]:
        """``OUTP?`` of each supply: 1 on, 0 off."""
        return [int(self.query(a, "OUTP?")) for a in addresses]


def skip_if_ni_daqmx_installed() -> None:
    """Skip the test on a machine where NI's driver works (where nidaqmx can create a task)."""
    import pytest

    nidaqmx = pytest.importorskip("nidaqmx")
    try:
        nidaqmx.Task().close()
    except nidaqmx.errors.Error:
        return
    pytest.skip("NI-DAQmx is installed on this machine")

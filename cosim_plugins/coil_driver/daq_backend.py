"""Backend ``daq``: the supplies' analog reference, six hardware-timed outputs through NI-DAQmx.

One output per coil feeds the external reference input of that coil's
supplies. The task runs a continuous sample clock without regeneration
(NI-DAQmx's ``RegenerationMode.DONT_ALLOW_REGENERATION``): every sample is
written once, ``prefill_chunks`` chunks of zeros go in before the clock
starts, and each tick writes one ``dt``-long chunk ahead, so the coils
follow the commands ``prefill_chunks * dt`` late. The output buffer is set
to ``prefill_chunks + 1`` chunks: a write blocks while it is full, which
paces a run that is faster than real time and bounds the lag. Samples are
computed in the bridge's absolute time (sample ``k`` is at ``k / rate``,
tick ``i``'s chunk starts at sample ``i * n``), so the waveform stays
phase-continuous across chunks and across command changes.

Stopping writes the last command again, chunk by chunk, under an envelope
falling linearly to zero over ``ramp_s``, then a chunk of zeros, waits until
the device has generated them, and stops the task: the outputs rest at 0 V.

``nidaqmx`` is imported when the backend opens, so everything else runs
without it; without the package or without NI's driver (NI-DAQmx) the
backend fails with a one-line message naming what is missing.
"""

from __future__ import annotations

import math
import time
from typing import Any, Callable

import numpy as np

from cosim_plugins.coil_driver.interlocks import BackendFault, Fault


def reference_chunk(amp_v: np.ndarray, phase_rad: np.ndarray, freq_hz: float, rate_hz: float,
                    start_sample: int, n: int, gain_v_per_v: float,
                    envelope: np.ndarray | None = None) -> np.ndarray:
    """Reference samples (6, n) [V] of the coil voltages ``amp cos(2 pi f t + phase)``.

    ``amp_v``, ``phase_rad``: (6,) voltage phasors in absolute time [V, rad];
    ``freq_hz``: drive frequency; samples are at ``t = (start_sample + k) / rate_hz``
    for ``k`` in ``0..n-1``; ``gain_v_per_v``: coil volts per reference volt
    (the supplies' gain times the supplies in series); ``envelope``: optional
    (n,) factor applied to every channel.
    """
    k = start_sample + np.arange(n)
    # the angle from the integer sample index, reduced to [0, 1) cycles before the cosine: after a
    # day at 10 kHz (k ~ 1e9) its error is still below 1e-9 rad
    cycles = np.mod(k * (freq_hz / rate_hz), 1.0)
    out = (amp_v / gain_v_per_v)[:, None] * np.cos(2 * math.pi * cycles[None, :] + phase_rad[:, None])
    if envelope is not None:
        out = out * envelope[None, :]
    return out


def ramp_envelope(n: int, ramp_samples: int) -> np.ndarray:
    """(n,) factor falling linearly to 0 over ``ramp_samples`` samples: sample ``k`` gets
    ``1 - (k + 1) / ramp_samples``, exactly 0 from sample ``ramp_samples - 1`` on."""
    k = np.arange(n)
    if ramp_samples <= 0:
        return np.zeros(n)
    return np.clip(1.0 - (k + 1) / ramp_samples, 0.0, 1.0)


def import_nidaqmx():
    """The ``nidaqmx`` module, or an error naming what is missing."""
    try:
        import nidaqmx
        import nidaqmx.constants  # noqa: F401
        import nidaqmx.errors  # noqa: F401
    except ImportError as exc:
        raise RuntimeError(f"needs the nidaqmx package (pip install -e '.[lab]') and NI's driver NI-DAQmx: "
                           f"{exc}") from exc
    return nidaqmx


def samples_per_tick(rate_hz: float, dt_s: float) -> int:
    """Samples in one tick; ValueError unless ``rate_hz * dt_s`` is a whole number of at least 2."""
    n = rate_hz * dt_s
    if abs(n - round(n)) > 1e-9 or round(n) < 2:
        raise ValueError(f"daq_rate_hz={rate_hz:g} gives {n:g} samples per {dt_s:g} s tick; "
                         "it must be a whole number of at least 2")
    return int(round(n))


class DaqReference:
    """Six analog outputs driven chunk by chunk. ``task_factory`` stands in for ``nidaqmx.Task`` in tests.

    ``channels``: NI physical channels, e.g. ``"Dev1/ao0:5"`` (coil order +x -x +y -y +z -z);
    ``rate_hz``: sample rate, an integer number of samples per tick ``dt_s``;
    ``gain_v_per_v``: coil volts per reference volt; ``ao_max_v``: the outputs' range.
    """

    def __init__(self, channels: str, rate_hz: float, dt_s: float, gain_v_per_v: float, ao_max_v: float,
                 prefill_chunks: int, ramp_s: float, daqmx=None, task_factory: Callable[[], Any] | None = None):
        self.channels, self.rate_hz, self.n = channels, rate_hz, samples_per_tick(rate_hz, dt_s)
        self.gain, self.ao_max_v = gain_v_per_v, ao_max_v
        self.prefill, self.ramp_samples = prefill_chunks, int(round(ramp_s * rate_hz))
        self._daqmx, self._task_factory = daqmx, task_factory
        self.task = None
        self.started = False
        self.written = 0  # samples per channel written so far
        self._next_sample = 0  # absolute sample index of the next chunk's start (tick i -> i * n)
        self._last: tuple[np.ndarray, np.ndarray, float] | None = None  # the last phasors delivered

    def open(self) -> None:
        """Create and configure the task (nothing generated yet); the error names what is missing."""
        daqmx = self._daqmx or import_nidaqmx()
        self._daqmx = daqmx
        consts = daqmx.constants
        try:
            self.task = self._task_factory() if self._task_factory else daqmx.Task()
        except daqmx.errors.Error as exc:  # DaqNotFoundError: the package is here, NI's driver is not
            raise RuntimeError(f"nidaqmx could not create a task: NI-DAQmx (NI's driver) is missing or "
                               f"unusable: {exc}") from exc
        buffer = self.n * (self.prefill + 1)
        try:
            self.task.ao_channels.add_ao_voltage_chan(self.channels, min_val=-self.ao_max_v, max_val=self.ao_max_v)
            self.task.timing.cfg_samp_clk_timing(self.rate_hz, sample_mode=consts.AcquisitionType.CONTINUOUS,
                                                 samps_per_chan=buffer)
            self.task.out_stream.regen_mode = consts.RegenerationMode.DONT_ALLOW_REGENERATION
            self.task.out_stream.output_buf_size = buffer
        except daqmx.errors.Error as exc:
            self.close()
            raise RuntimeError(f"could not set up the analog outputs {self.channels}: {exc}") from exc

    def start(self) -> None:
        """Write the zero prefill and start the sample clock (the outputs start at 0 V)."""
        self._write(np.zeros((6, self.n * self.prefill)))
        self._call(self.task.start)
        self.started = True

    def deliver(self, tick: int, amp_v: np.ndarray, phase_rad: np.ndarray, freq_hz: float) -> None:
        """Write tick ``tick``'s chunk: samples ``[tick * n, (tick + 1) * n)`` of the command.

        Chunks must follow each other: a driver stepped less often than every
        tick would leave the outputs without samples, so a gap is a fault.
        """
        start = tick * self.n
        if start != self._next_sample:
            raise BackendFault(Fault("daq_error", f"tick {tick} does not follow the chunk written last "
                                                  f"(samples from {self._next_sample}): the coil driver "
                                                  "must step every tick (period 1) with this backend"))
        data = reference_chunk(amp_v, phase_rad, freq_hz, self.rate_hz, start, self.n, self.gain)
        peak = float(np.abs(data).max(initial=0.0))
        if peak > self.ao_max_v + 1e-9:  # the interlocks keep v_max / gain within range; this is a last guard
            raise BackendFault(Fault("daq_error", f"reference {peak:.3f} V exceeds the outputs' range "
                                                  f"+-{self.ao_max_v:g} V (check v_max and daq_gain_v_per_v)"))
        self._write(data)
        self._next_sample = start + self.n
        self._last = (amp_v.copy(), phase_rad.copy(), freq_hz)

    def stop(self, wait_s: float = 2.0) -> None:
        """Ramp the last command to zero over the ramp time, write zeros, let them play out, stop the task.

        When that fails (the task already stopped on an underflow, say), the
        task is stopped and one zero sample is written on demand instead, so
        the outputs do not rest at the last value they had.
        """
        if self.task is None or not self.started:
            return
        self.started = False
        try:
            if self._last is not None and self.ramp_samples > 0:
                amp, phase, f = self._last
                chunks = math.ceil(self.ramp_samples / self.n)
                envelope = ramp_envelope(chunks * self.n, self.ramp_samples)
                for i in range(chunks):  # a chunk at a time: each fits the buffer
                    start = i * self.n
                    self._write(reference_chunk(amp, phase, f, self.rate_hz, self._next_sample + start, self.n,
                                                self.gain, envelope[start:start + self.n]))
            self._write(np.zeros((6, self.n)))
            self._wait_generated(wait_s)
            self._call(self.task.stop)
        except BackendFault:
            self._force_zero()
            raise

    def _force_zero(self) -> None:
        """Stop the task and set every output to 0 V with a single on-demand write."""
        consts = self._daqmx.constants
        self._call(self.task.stop)
        self.task.timing.samp_timing_type = consts.SampleTimingType.ON_DEMAND
        self._call(lambda: self.task.write(np.zeros((6, 1)), auto_start=True, timeout=1.0))
        self._call(self.task.stop)

    def close(self) -> None:
        """Release the task (after :meth:`stop`)."""
        if self.task is not None:
            task, self.task = self.task, None
            task.close()

    def _wait_generated(self, wait_s: float) -> None:
        """Until the device has generated every sample written (at most ``wait_s`` past the buffered time)."""
        pending = self.written - self.task.out_stream.total_samp_per_chan_generated
        deadline = time.monotonic() + pending / self.rate_hz + wait_s
        while self.task.out_stream.total_samp_per_chan_generated < self.written:
            if time.monotonic() > deadline:
                raise BackendFault(Fault("daq_error", "the outputs did not generate the final zeros in time"))
            time.sleep(0.005)

    def _write(self, data: np.ndarray) -> None:
        """Write (6, m) samples [V]; waits at most a buffer's duration plus 1 s for room."""
        self._call(lambda: self.task.write(np.ascontiguousarray(data), auto_start=False,
                                           timeout=self.n * (self.prefill + 1) / self.rate_hz + 1.0))
        self.written += data.shape[1]

    def _call(self, action: Callable[[], Any]) -> Any:
        try:
            return action()
        except self._daqmx.errors.Error as exc:  # an underflow (a late tick), a device error...
            raise BackendFault(Fault("daq_error", f"{self.channels}: {exc}")) from exc

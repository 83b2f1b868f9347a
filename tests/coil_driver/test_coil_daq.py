"""Backend ``daq``: the reference chunks against the phasors, and the task driven as NI-DAQmx would be.

NI's driver cannot be installed here, so ``DaqReference`` drives a fake task
that records every call; what the real driver does with them is not tested.
"""

from __future__ import annotations

import sys
from fractions import Fraction
from types import SimpleNamespace

import numpy as np
import pytest
from coil_fakes import DT, skip_if_ni_daqmx_installed, spin

from cosim import ComponentError
from cosim_plugins.coil_driver.actuation import centre_matrix, impedance_ohm
from cosim_plugins.coil_driver.backends import Rig
from cosim_plugins.coil_driver.daq_backend import DaqReference, ramp_envelope, reference_chunk
from cosim_plugins.coil_driver.interlocks import BackendFault

RATE, N, GAIN = 10_000.0, 200, 4.0  # 200 samples per 20 ms tick
AMP = np.array([30.0, 30.0, 12.0, 12.0, 0.0, 0.0])  # V at the coils
PHASE = np.array([0.3, 0.3 + np.pi, -1.2, -1.2 + np.pi, 0.0, 0.0])
LOOSE = {"v_max": 1e4, "i_max_a": 1e3, "i_trip_a": 1e3, "slew_v_per_s": 1e9, "daq_ao_max_v": 100.0,
         "watchdog_clock": "sim"}


# ---------------------------------------------------------------- the chunks


def test_a_chunk_samples_the_phasors_at_its_absolute_times():
    f = 7.25
    for start in (0, 12_345, 10**9):  # 10**9 samples: 28 hours into a run
        chunk = reference_chunk(AMP, PHASE, f, RATE, start, N, GAIN)
        assert chunk.shape == (6, N)
        # the exact angle of each sample: (start + k) * f / rate cycles, reduced with rationals
        cycles = [float((Fraction(start + k) * Fraction(f) / Fraction(RATE)) % 1) for k in range(N)]
        expected = (AMP / GAIN)[:, None] * np.cos(2 * np.pi * np.array(cycles)[None, :] + PHASE[:, None])
        assert np.abs(chunk - expected).max() < 1e-8  # V: a phase error below 1e-9 rad


def test_consecutive_chunks_are_one_continuous_waveform():
    f = 11.3
    joined = np.hstack([reference_chunk(AMP, PHASE, f, RATE, i * N, N, GAIN) for i in range(5)])
    whole = reference_chunk(AMP, PHASE, f, RATE, 0, 5 * N, GAIN)
    assert np.abs(joined - whole).max() < 1e-12


def field_direction_at(out: dict, t_s: float) -> np.ndarray:
    """Unit field direction at the centre at ``t_s`` of the coils driven by the driver's outputs ``out``."""
    f = float(out["drive_freq"])
    current = out["coil_voltage_amp"] * np.exp(1j * out["coil_voltage_phase"]) / impedance_ohm(f, 12.9, 0.411, 430e-6)
    field = centre_matrix(1.0) @ np.real(current * np.exp(2j * np.pi * f * t_s))
    return field / np.linalg.norm(field)


@pytest.mark.parametrize("new_axis", [(0.0, 0.0, 1.0), (0.0, 0.6, 0.8)])
def test_a_command_change_at_a_tick_boundary_keeps_the_field_direction(make_driver, new_axis):
    """The old command's field at the boundary continues in the new plane (projected onto it when it tilts)."""
    driver = make_driver(**LOOSE)
    old = {}
    for k in range(5):
        old = driver.step(k * DT, {"omega": spin(6.0)})
    boundary = 5 * DT
    new = driver.step(boundary, {"omega": spin(9.5, new_axis)})
    before = field_direction_at(old, boundary)  # where the old chunk's waveform arrives at the boundary
    n = np.array(new_axis) / np.linalg.norm(new_axis)
    expected = before - before.dot(n) * n
    assert np.allclose(field_direction_at(new, boundary), expected / np.linalg.norm(expected), atol=1e-9)
    # the chunks written either side are these phasors sampled at absolute times
    last = reference_chunk(old["coil_voltage_amp"], old["coil_voltage_phase"], 6.0, RATE, 4 * N, N, GAIN)[:, -1]
    assert np.allclose(last * GAIN, old["coil_voltage_amp"] * np.cos(2 * np.pi * 6.0 * (boundary - 1 / RATE)
                                                                      + old["coil_voltage_phase"]))


def test_the_ramp_envelope_falls_linearly_and_ends_at_exactly_zero():
    env = ramp_envelope(1200, 1000)
    assert env[0] == pytest.approx(1 - 1 / 1000) and np.all(np.diff(env[:1000]) < 0)
    assert np.allclose(np.diff(env[:1000]), -1 / 1000)
    assert env[999] == 0.0 and np.all(env[1000:] == 0.0)
    assert np.all(ramp_envelope(10, 0) == 0.0)


# ---------------------------------------------------------------- the task, faked


class FakeDaqError(Exception):
    """Stands in for nidaqmx.errors.Error."""


FAKE_DAQMX = SimpleNamespace(
    constants=SimpleNamespace(AcquisitionType=SimpleNamespace(CONTINUOUS="continuous"),
                              RegenerationMode=SimpleNamespace(DONT_ALLOW_REGENERATION="no regeneration"),
                              SampleTimingType=SimpleNamespace(ON_DEMAND="on demand")),
    errors=SimpleNamespace(Error=FakeDaqError))


class FakeTask:
    """Records the calls an NI-DAQmx analog output task receives; generates whatever is written at once.

    ``fail_write``: the write number (from 0) that raises, as the driver would on an underflow.
    """

    def __init__(self, fail_write: int | None = None):
        self.calls: list[tuple] = []
        self.writes = 0
        self.fail_write = fail_write
        self.ao_channels = SimpleNamespace(add_ao_voltage_chan=lambda *a, **kw: self.calls.append(("channels", a, kw)))
        self.timing = SimpleNamespace(cfg_samp_clk_timing=lambda *a, **kw: self.calls.append(("timing", a, kw)),
                                      samp_timing_type="sample clock")
        self.out_stream = SimpleNamespace(regen_mode=None, output_buf_size=None, total_samp_per_chan_generated=0)

    def write(self, data, auto_start, timeout):
        self.writes += 1
        if self.writes - 1 == self.fail_write:
            raise FakeDaqError("-200290: the generation has stopped to prevent the regeneration of old samples")
        self.calls.append(("write", np.array(data), auto_start, self.timing.samp_timing_type))
        self.out_stream.total_samp_per_chan_generated += data.shape[1]

    def start(self):
        self.calls.append(("start",))

    def stop(self):
        self.calls.append(("stop",))

    def close(self):
        self.calls.append(("close",))

    def written(self) -> list[np.ndarray]:
        return [c[1] for c in self.calls if c[0] == "write"]


def daq_reference(task: FakeTask, prefill: int = 2, ramp_s: float = 0.1) -> DaqReference:
    return DaqReference("Dev1/ao0:5", RATE, DT, GAIN, 10.0, prefill, ramp_s, daqmx=FAKE_DAQMX,
                        task_factory=lambda: task)


def test_open_configures_a_continuous_non_regenerating_output_of_prefill_plus_one_chunks():
    task = FakeTask()
    daq_reference(task, prefill=3).open()
    assert task.calls == [("channels", ("Dev1/ao0:5",), {"min_val": -10.0, "max_val": 10.0}),
                          ("timing", (RATE,), {"sample_mode": "continuous", "samps_per_chan": 4 * N})]
    assert task.out_stream.regen_mode == "no regeneration" and task.out_stream.output_buf_size == 4 * N


def test_zeros_go_in_before_the_clock_starts_then_one_chunk_per_tick():
    task = FakeTask()
    ref = daq_reference(task)
    ref.open()
    ref.start()
    for tick in range(3):
        ref.deliver(tick, AMP, PHASE, 7.0)
    kinds = [c[0] for c in task.calls[2:]]
    assert kinds == ["write", "start", "write", "write", "write"]
    prefill, *chunks = task.written()
    assert prefill.shape == (6, 2 * N) and np.all(prefill == 0)
    for tick, chunk in enumerate(chunks):
        assert np.array_equal(chunk, reference_chunk(AMP, PHASE, 7.0, RATE, tick * N, N, GAIN))
    assert all(c[2] is False for c in task.calls if c[0] == "write")  # never started by a write


def test_a_gap_of_ticks_is_a_daq_error():
    ref = daq_reference(FakeTask())
    ref.open()
    ref.start()
    ref.deliver(0, AMP, PHASE, 7.0)
    with pytest.raises(BackendFault) as err:
        ref.deliver(2, AMP, PHASE, 7.0)
    assert err.value.fault.name == "daq_error"
    assert "tick 2 does not follow the chunk written last (samples from 200)" in err.value.fault.message


def test_stop_ramps_the_last_command_to_zero_then_writes_zeros_then_stops():
    task = FakeTask()
    ref = daq_reference(task, ramp_s=0.1)  # 1000 samples: five chunks
    ref.open()
    ref.start()
    for tick in range(3):
        ref.deliver(tick, AMP, PHASE, 7.0)
    ref.stop()
    writes = task.written()[4:]
    assert [w.shape for w in writes] == [(6, N)] * 6  # chunk by chunk, each fits the buffer
    ramp = np.hstack(writes[:5])
    continued = reference_chunk(AMP, PHASE, 7.0, RATE, 3 * N, 5 * N, GAIN)  # the waveform went on
    assert np.allclose(ramp, continued * ramp_envelope(5 * N, 1000)[None, :], atol=1e-12)
    assert np.all(ramp[:, -1] == 0.0) and np.all(writes[5] == 0.0)
    assert task.calls[-1] == ("stop",)
    ref.stop()  # idempotent
    assert task.calls[-1] == ("stop",) and task.calls.count(("stop",)) == 1


def test_a_driver_error_is_a_named_daq_error_and_stop_still_zeroes_the_outputs():
    task = FakeTask(fail_write=3)  # prefill, two chunks, then the driver fails
    ref = daq_reference(task)
    ref.open()
    ref.start()
    ref.deliver(0, AMP, PHASE, 7.0)
    ref.deliver(1, AMP, PHASE, 7.0)
    with pytest.raises(BackendFault) as err:
        ref.deliver(2, AMP, PHASE, 7.0)
    assert str(err.value.fault) == ("daq_error: Dev1/ao0:5: -200290: the generation has stopped to prevent "
                                    "the regeneration of old samples")
    task.fail_write = 4  # the ramp's first write fails too: stop, then one zero written on demand
    with pytest.raises(BackendFault):
        ref.stop()
    last_write = task.calls[-2]
    assert last_write[0] == "write" and last_write[1].shape == (6, 1) and np.all(last_write[1] == 0)
    assert last_write[2] is True and last_write[3] == "on demand"
    assert task.calls[-1] == ("stop",)


def test_a_reference_beyond_the_output_range_is_refused():
    ref = daq_reference(FakeTask())
    ref.open()
    ref.start()
    with pytest.raises(BackendFault) as err:
        ref.deliver(0, AMP * 2, PHASE, 7.0)  # 60 V / 4 = 15 V > 10 V
    assert err.value.fault.name == "daq_error" and "exceeds the outputs' range +-10 V" in err.value.fault.message


# ---------------------------------------------------------------- through the bridge


def test_the_bridge_writes_its_phasors_and_a_nan_command_never_reaches_the_outputs(make_driver):
    task = FakeTask()
    driver = make_driver(rig=Rig(daq_reference(task)), watchdog_clock="sim")
    outs = [driver.step(k * DT, {"omega": spin(8.0, (1.0, 0.2, 0.0))}) for k in range(4)]
    out = driver.step(4 * DT, {"omega": np.array([np.nan, 0.0, 0.0])})
    assert driver.fault.startswith("unsafe_command: ")
    assert np.all(out["coil_voltage_amp"] == 0) and np.all(out["coil_voltage_phase"] == 0)
    writes = task.written()
    for k, o in enumerate(outs):  # one chunk per tick, the ports' phasors
        assert np.array_equal(writes[1 + k], reference_chunk(o["coil_voltage_amp"], o["coil_voltage_phase"],
                                                             float(o["drive_freq"]), RATE, k * N, N, GAIN))
    after = np.hstack(writes[5:])  # what followed the NaN: the last good command ramped down, then zeros
    assert np.all(np.isfinite(after)) and np.all(after[:, -N:] == 0)
    assert np.all(np.abs(after) <= (outs[-1]["coil_voltage_amp"] / GAIN)[:, None] + 1e-12)
    assert task.calls[-1] == ("stop",)


def test_a_gap_in_the_bridge_steps_stops_the_outputs_with_a_daq_error(make_driver):
    task = FakeTask()
    driver = make_driver(rig=Rig(daq_reference(task)), watchdog_clock="sim")
    driver.step(0.0, {"omega": spin(8.0)})
    out = driver.step(2 * DT, {"omega": spin(8.0)})  # a driver stepped every other tick
    assert driver.fault.startswith("daq_error: tick 2 does not follow the chunk written last")
    assert np.all(out["coil_voltage_amp"] == 0) and task.calls[-1] == ("stop",)


# ---------------------------------------------------------------- without NI's software


def test_without_the_nidaqmx_package_backend_daq_names_it(monkeypatch):
    from cosim_plugins.coil_driver.inverse import InverseMagnetics

    monkeypatch.setitem(sys.modules, "nidaqmx", None)  # import nidaqmx raises ImportError
    with pytest.raises(ComponentError) as err:
        InverseMagnetics().setup({"dt": DT, "backend": "daq"}, np.random.default_rng(0))
    message = str(err.value)
    assert message.startswith("backend 'daq': needs the nidaqmx package (pip install -e '.[lab]') and NI's "
                              "driver NI-DAQmx") and "\n" not in message


def test_without_ni_daqmx_the_driver_backend_daq_names_it():
    """The nidaqmx package is installed here, NI's driver cannot be: creating a task fails, and says so."""
    from cosim_plugins.coil_driver.inverse import InverseMagnetics

    skip_if_ni_daqmx_installed()
    with pytest.raises(ComponentError) as err:
        InverseMagnetics().setup({"dt": DT, "backend": "daq"}, np.random.default_rng(0))
    message = str(err.value)
    assert message.startswith("backend 'daq': nidaqmx could not create a task: NI-DAQmx (NI's driver) is missing")
    assert "\n" not in message


def test_the_daq_backend_is_built_from_its_parameters():
    """Nothing opened: the reference only holds what the parameters say (channels, rate, gain, range, prefill)."""
    from cosim_plugins.coil_driver import params as coil_params
    from cosim_plugins.coil_driver.inverse import build_rig

    p = coil_params.read({"backend": "daq", "daq_channels": "Dev2/ao0:5", "daq_rate_hz": RATE,
                          "daq_gain_v_per_v": GAIN, "daq_ao_max_v": 12.5, "daq_prefill_chunks": 3})
    ref = build_rig(p, DT).reference
    assert (ref.channels, ref.rate_hz, ref.n, ref.gain, ref.ao_max_v, ref.prefill) == (
        "Dev2/ao0:5", RATE, N, GAIN, 12.5, 3)
    assert ref.task is None and not ref.started

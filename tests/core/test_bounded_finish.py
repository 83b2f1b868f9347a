"""The end of a run takes memory that does not depend on the run's length: the trace's chunks are
joined one chunk's column at a time, the last part from the rows the recorder holds (no copy), and
the recording is written without rerun's footer (whose manifest grows with every chunk sent)."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from cosim.record import rerun_log
from cosim.record.trace_files import ChunkedTrace, load_trace
from cosim.runtime.recorder import TraceRecorder
from cosim.runtime.wiring import build_wiring
from cosim.scenario.schema import load_scenario

TOY = Path(__file__).parent / "data" / "toy.yaml"
DT_S = 0.02
#: a chunk's ticks and the columns after t_s: (name, shape)
CHUNK_TICKS = 2000
COLUMNS = [("plant.position", (3,)), ("plant.coil_current_amp", (6,)), ("controller.solve_time", ())]


def _peak_bytes(call) -> int:
    """The most memory Python and numpy held at once while ``call()`` ran, over what they held before [bytes]."""
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        call()
        return tracemalloc.get_traced_memory()[1] - before
    finally:
        tracemalloc.stop()


def test_joining_a_many_chunk_trace_holds_one_chunks_column_at_a_time(tmp_path):
    chunks = 40
    trace = ChunkedTrace(tmp_path, COLUMNS, DT_S)
    trace.open()
    rng = np.random.default_rng(0)
    for k in range(chunks):
        ticks = np.arange(k * CHUNK_TICKS, (k + 1) * CHUNK_TICKS)
        trace.seal({"t_s": ticks * DT_S, **{n: rng.standard_normal((CHUNK_TICKS, *s)) for n, s in COLUMNS}})
    rest = {"t_s": np.arange(chunks * CHUNK_TICKS, chunks * CHUNK_TICKS + 7) * DT_S,
            **{n: np.zeros((7, *s)) for n, s in COLUMNS}}
    widest_column_bytes = chunks * CHUNK_TICKS * 6 * 8  # 3.84 MB: what reading a whole column would take
    peak = _peak_bytes(lambda: trace.finish(rest, tmp_path / "trace.npz"))
    # ~0.65 MB whether the trace has 5 chunks or 80: a chunk's column (96 kB) and the reading and
    # compressing buffers
    assert peak < widest_column_bytes / 4, f"joining took {peak / 1e3:.0f} kB at its peak"
    got = load_trace(tmp_path)
    assert got["t_s"].shape == (chunks * CHUNK_TICKS + 7,) and got["plant.coil_current_amp"].shape[1:] == (6,)
    assert np.array_equal(got["t_s"][:CHUNK_TICKS], np.arange(CHUNK_TICKS) * DT_S)
    assert not (tmp_path / "trace.chunks").exists()


def test_the_last_part_is_joined_from_the_rows_held_not_a_copy(tmp_path):
    scenario = load_scenario(TOY, ["duration_s=null"])
    wiring = build_wiring(scenario)
    recorder = TraceRecorder(scenario, wiring, tmp_path)
    recorder.open()
    widths = {c: rows.shape[1] for c, rows in recorder.rows.items()}
    ticks = 20_000
    for tick in range(ticks):
        recorder.on_tick(tick, tick * DT_S, {c: np.full(w, float(tick)) for c, w in widths.items()})
    recorder.write_out()
    held_bytes = ticks * 8 * (1 + sum(widths.values()))  # what a copy of the rows held takes
    assert recorder.base == 0 and held_bytes > 2_000_000  # all of them still held: one chunk
    peak = _peak_bytes(lambda: recorder.finish(None))
    assert peak < held_bytes / 2, f"finishing took {peak / 1e6:.2f} MB at its peak, the rows {held_bytes / 1e6:.2f} MB"
    trace = load_trace(tmp_path)
    assert np.array_equal(trace["plant.position"][:, 0], np.arange(ticks, dtype=float))
    assert b"RRF2FOOT" not in _tail(tmp_path / "recording.rrd")  # no footer: no manifest kept for it


def _tail(path: Path) -> bytes:
    with open(path, "rb") as f:
        f.seek(max(path.stat().st_size - 64, 0))
        return f.read()


@pytest.mark.parametrize("footer", [False, True])
def test_the_recording_is_written_without_a_footer_and_says_nothing(tmp_path, monkeypatch, capfd, footer):
    """rerun's footer ends a file with ``RRF2FOOT``; without it rerun keeps no manifest of the chunks."""
    monkeypatch.setattr(rerun_log, "WRITE_FOOTER", footer)
    rec = rerun_log.rr.RecordingStream(application_id=rerun_log.APPLICATION_ID, recording_id="t")
    rerun_log.save(rec, tmp_path / "r.rrd")
    rerun_log.log_scalars(rec, "plots/x", np.arange(5) * DT_S, np.arange(5.0))
    rec.flush()
    rec.disconnect()
    assert (b"RRF2FOOT" in _tail(tmp_path / "r.rrd")) is footer
    assert "footer" not in capfd.readouterr().err

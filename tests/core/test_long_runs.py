"""Runs of any length: figures computed as the run goes, the trace in chunks, recording parts,
runs until stopped."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cosim.api import RunRequest, run
from cosim.record.streaming import QUANTILE_REL_ERROR, Moments, Quantiles
from cosim.record.summary import metric_keys, trace_figures
from cosim.record.trace_files import ChunkedTrace, iter_trace, load_trace
from cosim.runtime import recorder as recorder_module
from cosim.scenario.paths import make_path
from cosim.scenario.schema import load_scenario

TOY = Path(__file__).parent / "data" / "toy.yaml"
FAULTY = Path(__file__).parent / "data" / "faulty.yaml"
DT_S = 0.02
#: the figures two runs share: all but the controller's computing time, which is measured
SHARED = [k for k in metric_keys() if k != "solve_ms"]


def test_moments_equal_the_whole_series_figures_batch_by_batch():
    rng = np.random.default_rng(0)
    series = rng.lognormal(0.0, 1.0, 10_000)
    series[::97] = np.nan
    moments = Moments()
    for batch in np.array_split(series, [1, 2, 500, 501, 4000]):
        moments.add(batch)
    v = series[np.isfinite(series)]
    got = moments.figures()
    assert got["mean"] == pytest.approx(np.mean(v), rel=1e-12)
    assert got["std"] == pytest.approx(np.std(v), rel=1e-10)
    assert got["max"] == np.max(v)
    assert Moments().figures() is None


@pytest.mark.parametrize("n", [1, 2, 3, 101, 20_000])
def test_quantiles_within_the_stated_error_of_numpy(n):
    rng = np.random.default_rng(n)
    values = np.concatenate([rng.lognormal(-3.0, 2.0, n), [0.0]])  # a zero too (a solve that took no time)
    q = Quantiles()
    for batch in np.array_split(values, 7):
        q.add(batch)
    for p in (0.0, 0.5, 0.99, 1.0):
        exact = np.percentile(values, 100 * p)
        assert abs(q.quantile(p) - exact) <= QUANTILE_REL_ERROR * exact + 1e-9, (p, q.quantile(p), exact)
    one = Quantiles()
    for v in values:
        one.add_one(float(v))
    assert np.array_equal(one.counts, q.counts)
    with pytest.raises(ValueError, match="negative"):
        Quantiles("solve time").add(np.array([-1.0]))


def _same_trace(a: dict, b: dict) -> bool:
    """Equal traces but for the measured computing time."""
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k], equal_nan=True) for k in a
                                        if not k.endswith("solve_time"))


def _close(got: dict | None, exact: dict | None, rel: float) -> None:
    assert (got is None) == (exact is None)
    for key in exact or {}:
        assert got[key] == pytest.approx(exact[key], rel=rel, abs=1e-9), key


def _check_figures(out: Path, summary: dict) -> None:
    """The summary's figures, computed as the run went, against the whole trace's."""
    scenario = load_scenario(TOY)
    path = make_path(scenario.path.plugin, scenario.path.params)
    exact = trace_figures(load_trace(out), scenario.record.ports(), path)
    for key in metric_keys():
        rel = QUANTILE_REL_ERROR if key in ("solve_ms", "detection_error_mm") else 1e-9
        _close(summary[key], exact[key], rel)
    assert summary["tracking_error_mm"] and summary["detection_error_mm"]


def test_a_run_held_in_chunks_gives_the_whole_runs_figures_and_trace(tmp_path, monkeypatch):
    """A chunk smaller than the run: the recorder holds 50 of its 200 ticks at a time."""
    whole = run(RunRequest(TOY, tmp_path / "whole", progress=False))
    monkeypatch.setattr(recorder_module, "CHUNK_BYTES", 1)  # one batch (1 s = 50 ticks) per chunk
    chunked = run(RunRequest(TOY, tmp_path / "chunked", progress=False))
    _check_figures(tmp_path / "chunked", chunked)
    for key in SHARED:
        _close(chunked[key], whole[key], 1e-12)
    a, b = load_trace(tmp_path / "whole"), load_trace(tmp_path / "chunked")
    assert _same_trace(a, b)
    assert len(a["t_s"]) == 200 and not (tmp_path / "chunked" / "trace.chunks").exists()
    assert (tmp_path / "chunked" / "log.csv").read_bytes() == (tmp_path / "whole" / "log.csv").read_bytes()


def test_the_chunks_of_a_run_going_or_killed_read_as_its_trace(tmp_path):
    trace = ChunkedTrace(tmp_path, [("plant.position", (3,))], DT_S)
    trace.open()
    rows = np.column_stack([np.arange(10) * DT_S, np.arange(30.0).reshape(10, 3)])
    trace.append(rows[:6])
    trace.seal({"t_s": rows[:6, 0], "plant.position": rows[:6, 1:]})
    trace.append(rows[6:9])
    with open(tmp_path / "trace.chunks" / "current.part", "ab") as part:
        part.write(rows[9].tobytes()[:20])  # a row cut by a kill
    got = load_trace(tmp_path)
    assert np.array_equal(got["t_s"], rows[:9, 0]) and np.array_equal(got["plant.position"], rows[:9, 1:])
    assert [len(p["t_s"]) for p in iter_trace(tmp_path, ["plant.position"])] == [6, 3]
    # killed between sealing a chunk and emptying the part: the part's rows of the chunk are not read twice
    (tmp_path / "trace.chunks" / "current.part").write_bytes(rows[:9].tobytes())
    assert np.array_equal(load_trace(tmp_path)["t_s"], rows[:9, 0])


def test_rotated_parts_hold_the_run_between_them(tmp_path):
    out = tmp_path / "rotated"
    summary = run(RunRequest(TOY, out, progress=False, rotate_s=1.5))  # 4 s: parts of 75, 75 and 50 ticks
    whole = run(RunRequest(TOY, tmp_path / "whole", progress=False))
    assert summary["files"] == {"parts": ["part-000", "part-001", "part-002"]}
    traces = [load_trace(out / p) for p in summary["files"]["parts"]]
    assert [len(t["t_s"]) for t in traces] == [75, 75, 50]
    joined = {k: np.concatenate([t[k] for t in traces]) for k in traces[0]}
    reference = load_trace(tmp_path / "whole")
    assert _same_trace(joined, reference)
    assert _same_trace(load_trace(out), reference)  # the parts read one after another
    for part in summary["files"]["parts"]:
        assert (out / part / "recording.rrd").stat().st_size > 0 and (out / part / "log.csv").is_file()
    for key in SHARED:
        _close(summary[key], whole[key], 1e-12)


def test_an_open_ended_run_stopped_by_sigint_is_a_timed_run_of_its_length(tmp_path):
    out = tmp_path / "open"
    proc = subprocess.Popen([sys.executable, "-m", "cosim.cli", "run", str(TOY), "--out", str(out), "--quiet",
                             "--until-stopped"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    log = out / "log.csv"
    deadline = time.monotonic() + 60
    while not log.is_file() or len(log.read_text().splitlines()) < 301:  # 300 ticks = 6 s simulated
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    summary = json.loads((out / "summary.json").read_text())
    steps = summary["steps"]
    assert summary["status"] == "interrupted" and summary["error"].startswith("stopped by SIGINT") and steps >= 300
    timed = run(RunRequest(TOY, tmp_path / "timed", [f"duration_s={steps * DT_S}"], progress=False))
    assert timed["status"] == "ok" and timed["steps"] == steps
    for key in SHARED:
        _close(summary[key], timed[key], 1e-12)
    assert log.read_bytes() == (tmp_path / "timed" / "log.csv").read_bytes()
    a, b = load_trace(out), load_trace(tmp_path / "timed")
    assert len(a["t_s"]) == steps and _same_trace(a, b)


def test_a_sweep_cannot_run_until_stopped(tmp_path):
    from cosim.contract.errors import UserError

    with pytest.raises(UserError, match="needs a duration_s"):
        run(RunRequest(TOY, tmp_path, ["duration_s=null", "sweep.seed=[1, 2]"], progress=False))


def test_the_end_of_a_replayed_input_ends_an_open_ended_run_as_a_timed_one(tmp_path):
    summary = run(RunRequest(FAULTY, tmp_path, ["components.relay.params.mode=end", "duration_s=null"],
                             progress=False))
    assert summary["status"] == "ok" and summary["error"] is None and summary["steps"] == 50  # ends at t = 1 s
    assert summary["end"] == "input ended (relay: the recording replayed has no more rows)"
    assert len(load_trace(tmp_path)["t_s"]) == 50


def test_the_end_of_a_replayed_input_in_a_node_ends_the_run_as_in_one_process(tmp_path):
    """With a process per component the node whose input ended tells the scheduler so: the run ends
    ``ok`` with the same ticks, the same log and the same end as in one process (not as a failure)."""
    overrides = ["components.relay.params.mode=end", "duration_s=null"]
    one = run(RunRequest(FAULTY, tmp_path / "one", overrides, progress=False))
    many = run(RunRequest(FAULTY, tmp_path / "many", overrides, processes=True, progress=False))
    assert many["status"] == "ok" and many["error"] is None and many["steps"] == one["steps"] == 50
    assert many["end"] == one["end"] == "input ended (relay: the recording replayed has no more rows)"
    assert (tmp_path / "many" / "log.csv").read_bytes() == (tmp_path / "one" / "log.csv").read_bytes()
    assert len(load_trace(tmp_path / "many")["t_s"]) == 50


def test_replay_opens_the_parts_asked_for(tmp_path):
    from cosim.cli.commands import recording_files
    from cosim.contract.errors import UserError

    run(RunRequest(TOY, tmp_path, ["duration_s=2"], progress=False, rotate_s=0.5))
    assert [f.parent.name for f in recording_files(tmp_path)] == ["part-000", "part-001", "part-002", "part-003"]
    assert [f.parent.name for f in recording_files(tmp_path, "1-2")] == ["part-001", "part-002"]
    with pytest.raises(UserError, match="expected a part number"):
        recording_files(tmp_path, "x")
    with pytest.raises(UserError, match="has parts 0-3"):
        recording_files(tmp_path, "7")


@pytest.mark.parametrize("duration", ["3600", "604800", "null"])  # an hour, a week, until stopped
def test_the_recorder_holds_one_chunk_whatever_the_duration(tmp_path, duration):
    from cosim.runtime.recorder import CHUNK_BYTES, TraceRecorder
    from cosim.runtime.wiring import build_wiring

    scenario = load_scenario(TOY, [f"duration_s={duration}"])
    recorder = TraceRecorder(scenario, build_wiring(scenario), tmp_path)
    assert 0 < sum(rows.nbytes for rows in recorder.rows.values()) <= CHUNK_BYTES
    swimmer = next(acc for acc in recorder.figures.sets if hasattr(acc, "detection"))  # the lab's figure set
    assert swimmer.detection.counts.nbytes < 400_000  # the histogram: fixed


def test_bad_rotate_and_parts_are_clear_errors(tmp_path, capsys):
    from cosim.cli.main import main

    assert main(["run", str(TOY), "--out", str(tmp_path / "r"), "--rotate", "0"]) == 2
    assert "--rotate 0: the hours per part must be > 0" in capsys.readouterr().err
    assert main(["validate", str(TOY), "--set", "duration_s=null"]) == 0
    assert "until stopped" in capsys.readouterr().out
    run(RunRequest(TOY, tmp_path / "one", ["duration_s=0.2"], progress=False))
    assert main(["replay", str(tmp_path / "one"), "--parts", "1"]) == 2
    assert "was not recorded in parts (cosim run --rotate)" in capsys.readouterr().err

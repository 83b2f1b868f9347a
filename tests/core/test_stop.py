"""Stopping a run: SIGINT and SIGTERM keep every step up to the stop, SIGKILL all but the last second."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cosim.runtime.recorder import FLUSH_EVERY_S, load_trace
from cosim.runtime.scheduler import WINDOW
from cosim_plugins.raw_log import read_log

TOY = Path(__file__).parent / "data" / "toy.yaml"
DT_S = 0.02


#: the override every run of this module sets, which its nodes are given too: it tells them from the nodes of
#: another test running the toy scenario meanwhile (tests/security runs it with --processes for 120 s)
OURS = "duration_s=3000"


def _start(out: Path, *extra: str) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "cosim.cli", "run", str(TOY), "--out", str(out), "--quiet",
           "--set", OURS, *extra]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _rows(out: Path) -> int:
    log = out / "log.csv"
    return max(len(log.read_text().splitlines()) - 1, 0) if log.is_file() else 0


def _wait_for_rows(out: Path, proc: subprocess.Popen, rows: int, timeout_s: float = 60.0) -> float:
    """Wait until log.csv has ``rows`` data rows; returns when (time.monotonic())."""
    deadline = time.monotonic() + timeout_s
    while _rows(out) < rows:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, f"log.csv never reached {rows} rows"
        time.sleep(0.02)
    return time.monotonic()


def _nodes_of(scenario_marker: str) -> list[str]:
    """The command lines of the running nodes of this module's runs of ``scenario_marker``."""
    found = []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            text = cmdline.read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        if "cosim.cli node" in text and scenario_marker in text and f"--set {OURS}" in text:
            found.append(text)
    return found


@pytest.mark.parametrize("sig, processes", [(signal.SIGINT, False), (signal.SIGTERM, False),
                                            (signal.SIGINT, True), (signal.SIGTERM, True)])
def test_a_signal_stops_the_run_and_keeps_every_step(tmp_path, sig, processes):
    out = tmp_path / "run"
    proc = _start(out, *(["--processes"] if processes else []))
    _wait_for_rows(out, proc, 300)
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "everything recorded until then is kept" in stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["error"].startswith(f"stopped by {sig.name}")
    steps = summary["steps"]
    assert 300 <= steps < 150_000
    log = read_log(out / "log.csv", outlier_mm=50.0)
    assert log.n == steps and log.t_s[-1] == pytest.approx((steps - 1) * DT_S)
    trace = load_trace(out)
    assert trace["plant.position"].shape == (steps, 3) and np.isfinite(trace["plant.position"]).all()
    assert not (out / "trace.part").exists()  # the trace was completed into trace.npz
    assert not _nodes_of(str(TOY))


def _last_tick(path: Path) -> int:
    """The last tick the plant wrote to its tick file (complete lines only)."""
    lines = path.read_text().split("\n")[:-1]
    return int(lines[-1])


def test_a_killed_scheduler_loses_at_most_the_last_second(tmp_path):
    """The plant notes each tick it steps; after the kill, the log holds every tick but at most the last
    batch (one second's worth) and the window the nodes may run ahead of the scheduler. In ticks, so
    a slow machine changes nothing."""
    out = tmp_path / "run"
    ticks = tmp_path / "plant_ticks.txt"
    proc = _start(out, "--realtime", "1", "--processes", "--set", f"components.plant.params.tick_file={ticks}")
    _wait_for_rows(out, proc, 1)  # the first batch is out: the loop runs
    rows_then = _rows(out)
    _wait_for_rows(out, proc, rows_then + 2 * int(FLUSH_EVERY_S / DT_S))  # two more batches written
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=30)
    stepped = _last_tick(ticks) + 1  # ticks the plant stepped (a node: it may have run ahead)
    assert stepped >= rows_then + 2 * int(FLUSH_EVERY_S / DT_S)
    lost = stepped - _rows(out)
    assert 0 <= lost <= FLUSH_EVERY_S / DT_S + WINDOW + 1, (stepped, _rows(out))
    assert json.loads((out / "summary.json").read_text())["status"] == "running"  # it says it never finished
    log = read_log(out / "log.csv", outlier_mm=50.0)
    assert np.allclose(np.diff(log.t_s), DT_S)
    trace = load_trace(out)  # from trace.part: every whole row written
    assert len(trace["t_s"]) >= log.n - 1 and np.array_equal(trace["t_s"][: log.n - 1], log.t_s[: log.n - 1])
    deadline = time.monotonic() + 20  # the nodes saw the scheduler go and stopped themselves
    while _nodes_of(str(TOY)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _nodes_of(str(TOY))

"""A paused process of a ``--processes`` run is named for what it is: a paused node as not answering
(its process is still there), a paused scheduler as the scheduler, not the first node in the alphabet.
Each test pauses a process past zenoh's 10 s lease, so each takes about 15 s."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TOY = ROOT / "tests" / "core" / "data" / "toy.yaml"
PAUSE_S = 13.0  # past zenoh's lease (10 s), after which a silent peer counts as gone


def _start(out: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.Popen([sys.executable, "-m", "cosim.cli", "run", str(TOY), "--out", str(out), "--quiet",
                             "--processes", "--node-cpus", "none", "--realtime", "1", "--set", "duration_s=120"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def _node_pid(run: subprocess.Popen, component: str, out: Path) -> int:
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline:
        log = out / "log.csv"
        if log.is_file() and len(log.read_text().splitlines()) > 5:  # stepping
            for status in Path("/proc").glob("[0-9]*/status"):
                try:
                    if f"PPid:\t{run.pid}\n" in status.read_text():
                        args = (status.parent / "cmdline").read_bytes().decode().split("\0")
                        if "node" in args and component in args:
                            return int(status.parent.name)
                except OSError:
                    continue
        assert run.poll() is None, run.communicate()
        time.sleep(0.1)
    raise AssertionError("the run never stepped")


def _finish(run: subprocess.Popen) -> str:
    try:
        return run.communicate(timeout=90)[1]
    finally:
        if run.poll() is None:
            run.kill()
            run.communicate()


def test_a_paused_node_is_reported_as_not_answering(tmp_path):
    run = _start(tmp_path / "run")
    pid = _node_pid(run, "estimator", tmp_path / "run")
    os.kill(pid, signal.SIGSTOP)
    try:
        err = _finish(run)
    finally:
        try:
            os.kill(pid, signal.SIGCONT)
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    assert run.returncode == 2
    assert "component 'estimator': not answering: its process is still there" in err, err
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["status"] == "failed" and "'estimator': not answering" in summary["error"]


def test_a_paused_scheduler_is_the_one_named(tmp_path):
    run = _start(tmp_path / "run")
    _node_pid(run, "estimator", tmp_path / "run")
    run.send_signal(signal.SIGSTOP)
    time.sleep(PAUSE_S)
    run.send_signal(signal.SIGCONT)
    err = _finish(run)
    assert run.returncode == 2
    assert "component 'scheduler': the scheduler's own process did not run for" in err, err

"""``cosim replay --web`` listens on loopback only, on free ports, prints one address, and leaves nothing
running after SIGTERM."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

from proc_sockets import socket_inodes

from cosim.api import RunRequest, run

ROOT = Path(__file__).resolve().parents[2]
TOY = ROOT / "tests" / "core" / "data" / "toy.yaml"


def _listening(pid: int) -> list[tuple[str, int]]:
    """(address, port) of the TCP sockets process ``pid`` listens on (IPv4 and IPv6, from /proc)."""
    mine = socket_inodes(pid)
    out = []
    for table, family in (("/proc/net/tcp", socket.AF_INET), ("/proc/net/tcp6", socket.AF_INET6)):
        for line in Path(table).read_text().splitlines()[1:]:
            cols = line.split()
            if cols[3] != "0A" or cols[9] not in mine:
                continue
            hexaddr, hexport = cols[1].split(":")
            raw = bytes.fromhex(hexaddr)
            raw = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))  # /proc prints 32-bit words
            out.append((socket.inet_ntop(family, raw), int(hexport, 16)))
    return out


def _descendants(pid: int) -> list[int]:
    kids = []
    for status in Path("/proc").glob("[0-9]*/status"):
        try:
            if f"PPid:\t{pid}\n" in status.read_text():
                kids.append(int(status.parent.name))
        except OSError:
            continue
    return kids + [d for k in kids for d in _descendants(k)]


def _running(pid: int) -> bool:
    """Whether ``pid`` is alive (an exited process not yet reaped by its parent is not)."""
    try:
        return "(zombie)" not in Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False


def test_replay_web_listens_on_loopback_and_stops_on_sigterm(tmp_path):
    run(RunRequest(TOY, tmp_path / "run", ["duration_s=1"], progress=False))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-m", "cosim.cli", "replay", str(tmp_path / "run"), "--web"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        line = proc.stdout.readline()
        assert line.startswith("open http://127.0.0.1:") and "in a browser" in line, (line, proc.stderr.read())
        viewers = _descendants(proc.pid)
        assert viewers
        sockets = [s for pid in viewers for s in _listening(pid)]
        assert len(sockets) == 2, sockets  # the page and its data
        assert {a for a, _ in sockets} == {"127.0.0.1"}
        assert 9876 not in {p for _, p in sockets}  # free ports, not rerun's fixed one
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=30) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    deadline = time.monotonic() + 10
    while [pid for pid in viewers if _running(pid)] and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [pid for pid in viewers if _running(pid)], "the viewer is still running"
    for _, port in sockets:
        with socket.socket() as s:
            assert s.connect_ex(("127.0.0.1", port)) != 0  # nothing listens there any more

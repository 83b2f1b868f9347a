"""A one-machine ``cosim run --processes``: no TCP listener, unix sockets in a 0700 folder of the run that
another user of the machine cannot connect to, removed when the run ends; and a node accepts one sample
per tick of each producer, from that producer's key."""

from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from proc_sockets import socket_inodes

from cosim.runtime.security_log import SecurityLog

ROOT = Path(__file__).resolve().parents[2]
TOY = ROOT / "tests" / "core" / "data" / "toy.yaml"


def _children(pid: int) -> list[int]:
    out = []
    for status in Path("/proc").glob("[0-9]*/status"):
        try:
            text = status.read_text()
        except OSError:
            continue
        ppid = next((int(line.split()[1]) for line in text.splitlines() if line.startswith("PPid:")), None)
        if ppid == pid:
            out.append(int(status.parent.name))
    return out


def _cmdline(pid: int) -> list[str]:
    return Path(f"/proc/{pid}/cmdline").read_bytes().decode().split("\0")


def _tcp_listen_inodes() -> set[str]:
    inodes = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            cols = line.split()
            if cols[3] == "0A":  # LISTEN
                inodes.add(cols[9])
    return inodes


def _connect_as(uid: int | None, path: str) -> str:
    """Try to connect to the unix socket ``path`` from a process of user ``uid`` (None: this user)."""
    code = ("import socket, sys\n"
            "s = socket.socket(socket.AF_UNIX)\n"
            "try:\n"
            "    s.connect(sys.argv[1]); print('CONNECTED')\n"
            "except OSError as e:\n"
            "    print('REFUSED', type(e).__name__)\n")
    pre = (lambda: (os.setgid(65534), os.setuid(uid))) if uid is not None else None
    done = subprocess.run(["/usr/bin/python3" if uid is not None else sys.executable, "-c", code, path],
                          capture_output=True, text=True, timeout=30, preexec_fn=pre, env={"PATH": "/usr/bin:/bin"})
    return done.stdout.strip() or done.stderr.strip()


def test_a_process_of_another_user_cannot_join_a_processes_run(tmp_path):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    run = subprocess.Popen([sys.executable, "-m", "cosim.cli", "run", str(TOY), "--out", str(tmp_path / "run"),
                            "--quiet", "--processes", "--node-cpus", "none", "--set", "duration_s=600"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        deadline = time.monotonic() + 90
        log = tmp_path / "run" / "log.csv"
        while not (log.is_file() and len(log.read_text().splitlines()) > 20):  # stepping: every node joined
            assert run.poll() is None, run.communicate()
            assert time.monotonic() < deadline, "the run never started stepping"
            time.sleep(0.1)
        nodes = [p for p in _children(run.pid) if "node" in _cmdline(p)]
        assert len(nodes) == 4
        listens = [a for p in nodes for a in _cmdline(p)[_cmdline(p).index("--listen") + 1:][:1]]
        assert all(a.startswith("unixsock-stream/") for a in listens), listens
        folder = Path(listens[0].split("/", 1)[1]).parent
        assert {Path(a.split("/", 1)[1]).parent for a in listens} == {folder}
        assert stat.S_IMODE(folder.stat().st_mode) == 0o700 and folder.stat().st_uid == os.getuid()
        listening = _tcp_listen_inodes()
        for pid in [run.pid, *nodes]:
            assert not (socket_inodes(pid) & listening), f"process {pid} listens on TCP"
        sock = listens[0].split("/", 1)[1]
        if os.getuid() == 0:  # root can act as another user: the real test
            assert _connect_as(65534, sock).startswith("REFUSED PermissionError")
            assert _connect_as(None, sock) == "CONNECTED"  # the same socket is open to the run's own user
        else:
            pytest.skip("needs root to act as another user")
    finally:
        if run.poll() is None:
            run.send_signal(signal.SIGTERM)
        run.communicate(timeout=60)
    assert not folder.exists()  # the run removed its sockets' folder


def test_a_node_accepts_each_producers_tick_once(tmp_path):
    """A second sample for a tick, a replay of an older one, a stamp off the producer's period and a
    payload of the wrong size are dropped; the first sample for each tick is what the node steps with."""
    from cosim.contract.component import Port
    from cosim.runtime.node import _Node
    from cosim.runtime.portcache import PortStore, expected_stamp

    class Sample:
        def __init__(self, tick, values):
            import struct

            self.attachment = type("A", (), {"to_bytes": lambda _: struct.pack("<q", tick)})()
            self.payload = type("P", (), {"to_bytes": lambda _: np.asarray(values, "<f8").tobytes()})()

    class Stepper:
        def __init__(self):
            self.seen = []

        def step(self, tick, t):
            self.seen.append((tick, float(store.row("controller", expected_stamp(tick, 2, 1))[0])))
            self.last_outputs = []

    store = PortStore({"controller": [Port("omega", (3,), "Hz")]}, keep=8)
    stepper = Stepper()
    log = SecurityLog(tmp_path, "node coil_driver")
    node = _Node(stepper, store, [("controller", "omega", 2, 1)], 1, 0.02, lambda *a, **k: None, log, "r1")
    node.on_data("controller", Sample(-1, [1, 0, 0]))
    node.on_data("controller", Sample(-1, [1, 0, 0]))  # the initial outputs sent again (set-up does): no event
    node.on_data("controller", Sample(-1, [9, 9, 9]))  # another initial sample: dropped
    node.on_data("controller", Sample(0, [2, 0, 0]))
    node.on_data("controller", Sample(0, [7.77, 0, 0]))  # a forged second sample for tick 0: dropped
    node.on_data("controller", Sample(1, [5, 0, 0]))  # off the producer's period of 2: dropped
    node.on_data("controller", Sample(2, [1, 2]))  # wrong size: dropped
    node.on_data("controller", Sample(2, [3, 0, 0]))
    node.on_data("controller", Sample(0, [7.77, 0, 0]))  # a replay: dropped
    node.until = 3
    with node.lock:
        node._advance()
    assert stepper.seen == [(0, 1.0), (1, 2.0), (2, 2.0)]
    assert node.security_events == 5
    events = [json.loads(line) for line in (tmp_path / "security.jsonl").read_text().splitlines()]
    assert [(e["key"], e["tick"]) for e in events] == [("cosim/r1/controller/outputs", t) for t in (-1, 0, 1, 2, 0)]
    assert all(e["process"] == "node coil_driver" and e["time"].endswith("Z") for e in events)
    assert "already accepted or out of order" in events[1]["reason"]
    assert "payload holds 2 values, expected 1 x 3" in events[3]["reason"]
    # a command that is none (a forged one, say) is dropped and noted too
    node.on_cmd(type("S", (), {"payload": type("P", (), {"to_bytes": lambda _: b'{"cmd": "arm"}'})(),
                                "key_expr": "cosim/r1/ctl/coil_driver/cmd"})())
    assert not node.stopped.is_set() and node.security_events == 6
    last = json.loads((tmp_path / "security.jsonl").read_text().splitlines()[-1])
    assert last["key"] == "cosim/r1/ctl/coil_driver/cmd" and "none of stop, flush, init" in last["reason"]


def test_the_scheduler_takes_a_reply_only_from_the_node_it_names(tmp_path):
    """A reply on camera's key that names the controller (a forged failure, say) is dropped and counted."""
    from cosim.runtime import bus
    from cosim.runtime.portcache import PortStore
    from cosim.runtime.scheduler import RemoteGroup
    from cosim.runtime.wiring import build_wiring
    from cosim.scenario.schema import load_scenario

    wiring = build_wiring(load_scenario(TOY))
    session = bus.open_session()
    try:
        group = RemoteGroup(session, "r1", wiring, PortStore(wiring.outputs), SecurityLog(tmp_path, "scheduler"))
        forged = bus.encode_json({"name": "controller", "tick": 3, "phase": None, "ok": False, "error": "forged"})
        session.put(bus.ctl_key("r1", "camera", "reply"), b"", attachment=forged)
        own = bus.encode_json({"name": "camera", "tick": -1, "phase": "check", "ok": True, "missing": []})
        session.put(bus.ctl_key("r1", "camera", "reply"), b"", attachment=own)
        assert group.poll_reply(2.0) == {"name": "camera", "tick": -1, "phase": "check", "ok": True, "missing": []}
        assert group.poll_reply(0.2) is None
        assert group.security_events == ["dropped a reply on cosim/r1/ctl/camera/reply naming 'controller'"]
        (event,) = [json.loads(line) for line in (tmp_path / "security.jsonl").read_text().splitlines()]
        assert event["key"] == "cosim/r1/ctl/camera/reply" and event["process"] == "scheduler"
        assert event["reason"] == "dropped a reply naming 'controller', not its key's node"
    finally:
        session.close()

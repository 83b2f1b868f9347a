"""Security events of a run: attempts the bus refused or a process rejected, one JSON line each.

Every process of a run spread over processes (the scheduler and each node)
appends its events to ``security.jsonl`` in the run's output folder (a node on
another machine: in the run folder there), one JSON object a line::

    {"time": "2026-11-25T20:41:07.114Z", "process": "node actuator", "key": "cosim/1f2e/controller/outputs",
     "reason": "refused by access control: sensor@lab may not Put (ingress) here", "from": "sensor@lab"}

Two kinds of events:

* refused by zenoh's access control (a ``--hosts`` run, where every peer is
  known by its certificate's name): a put, a subscription or a liveliness
  token on a key the peer's identity has no right to. zenoh drops the
  message and says so in its log (at trace level, in the access-control
  module, with every decision that allowed one: so a ``--hosts`` run logs
  a line a message, which :class:`ZenohDenials` reads and keeps only the
  refusals of);
* rejected by the process itself: a sample for a tick already accepted or
  out of order, one of the wrong size or without a stamp (a node); a reply
  that names another node than its key (the scheduler); a command that is
  not one (a node).

Lines are written as they happen (the file is readable while the run goes)
up to ``MAX_LINES`` per process, so a flood cannot fill the disk; past that
they are counted only, and the count is in ``summary.json``.
"""

from __future__ import annotations

import atexit
import json
import os
import re
import sys
import threading
import time
from pathlib import Path

FILE_NAME = "security.jsonl"
#: Lines a process writes at most; the events past them are counted only.
MAX_LINES = 1000
#: zenoh's access-control log: ``<zid> on <subject> is [un]authorized to <what> on <key>`` when it decides,
#: ``Using cached result: <zid> is [un]authorized to <what> on <key>`` when it reuses a decision; the
#: subject names the peer's certificate: ``...+CertCommonName(sensor@lab)+...``
_DECISION = re.compile(r"(?:Using cached result: )?(?P<zid>[0-9a-f]+)(?: on (?P<subject>\S+))? is "
                       r"(?P<un>un)?authorized to (?P<what>.+?) on (?P<key>\S+)\s*$")
_NAME = re.compile(r"CertCommonName\(([^)]*)\)")
#: zenoh works out its decisions for a key once a peer declares it: a line naming the key, then one line
#: per kind of message on the same thread (decisions about no message at all)
_CACHING = re.compile(r"ThreadId\((?P<tid>\d+)\).*caching permissions for `(?P<key>[^`]+)`")
_THREAD = re.compile(r"ThreadId\((\d+)\)")
_KINDS = 9  # query, reply, put, delete, (un)declare subscriber, queryable, token, liveliness query, subscriber
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
#: the log directive that makes zenoh report what its access control decides (refusals are logged at
#: trace level, with the decisions it allows)
ZENOH_DIRECTIVE = "zenoh::net::routing::interceptor::access_control=trace"
_TARGET = b"interceptor::access_control"


class DenialParser:
    """Reads zenoh's access-control log lines; knows each peer's certificate name by its zenoh id."""

    def __init__(self):
        self.names: dict[str, str] = {}  # zenoh id -> certificate common name
        self._caching: dict[str, list] = {}  # thread -> [key, decisions still to come] of a key being cached

    def feed(self, line: str) -> dict | None:
        """``{"key", "reason", "from"}`` of a refusal, else None (a decision that allowed, one worked out
        in advance for a declared key, another line)."""
        line = _ANSI.sub("", line)
        caching = _CACHING.search(line)
        if caching:
            self._caching[caching["tid"]] = [caching["key"], _KINDS]
            return None
        match = _DECISION.search(line)
        if match is None:
            return None
        zid = match["zid"]
        if match["subject"]:
            name = _NAME.search(match["subject"])
            if name:
                self.names[zid] = name[1]
        thread = _THREAD.search(line)
        block = self._caching.get(thread[1]) if thread else None
        if block and block[0] == match["key"] and not line.count("Using cached result"):
            block[1] -= 1
            if block[1] <= 0:
                del self._caching[thread[1]]
            return None
        if not match["un"]:
            return None
        who = self.names.get(zid, f"peer {zid}")
        return {"key": match["key"], "reason": f"refused by access control: {who} may not {match['what']} here",
                "from": who}


class SecurityLog:
    """One process's events, appended to ``run_dir/security.jsonl`` (``run_dir`` None: counted only)."""

    def __init__(self, run_dir: Path | str | None, process: str):
        self.process = process
        self.path = Path(run_dir) / FILE_NAME if run_dir is not None else None
        self.count = 0
        self._lock = threading.Lock()
        self._written = 0

    def event(self, key: str, reason: str, **extra) -> None:
        """Note one event: on ``key`` (a bus key), why it was refused, and what else is known
        (``tick``, ``sender``...). Thread-safe; never raises (a write error is counted only)."""
        now = time.time()
        stamp = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(now)) + f".{int(now % 1 * 1000):03d}Z"
        record = {"time": stamp, "process": self.process, "key": key, "reason": reason, **extra}
        with self._lock:
            self.count += 1
            if self.path is None or self._written >= MAX_LINES:
                return
            self._written += 1
            try:  # one write of one line, appended: lines of the run's processes never interleave
                self.path.parent.mkdir(parents=True, exist_ok=True)
                fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
                try:
                    os.write(fd, (json.dumps(record) + "\n").encode())
                finally:
                    os.close(fd)
            except OSError:
                pass


class _StdoutPump:
    """This process's standard output through a pipe and a thread, installed once: zenoh's access-control
    lines go to the open :class:`ZenohDenials`' log (or nowhere), every other line goes through as it was.
    zenoh's logger, set once a process, goes on writing to whatever file descriptor 1 is, so the pump
    stays for the life of the process; at its exit standard output is put back once every line has gone
    through (:func:`atexit`)."""

    def __init__(self):
        import zenoh

        self.sink: SecurityLog | None = None
        self.lock = threading.Lock()
        self._markers: dict[bytes, threading.Event] = {}  # drain() lines awaited
        sys.stdout.flush()
        read_fd, write_fd = os.pipe()
        self.out_fd = os.dup(1)
        os.dup2(write_fd, 1)
        os.close(write_fd)
        self.thread = threading.Thread(target=self._pump, args=(read_fd,), name="cosim-security-log", daemon=True)
        self.thread.start()
        atexit.register(self.restore)
        directives = [d for d in os.environ.get("RUST_LOG", "error").split(",") if d]
        os.environ["RUST_LOG"] = ",".join([*directives, ZENOH_DIRECTIVE])
        zenoh.init_log_from_env_or("error")

    def _pump(self, read_fd: int) -> None:
        parser = DenialParser()
        with os.fdopen(read_fd, "rb") as pipe:
            for raw in iter(pipe.readline, b""):
                if _TARGET not in raw:  # anything else written to standard output goes through
                    with self.lock:
                        seen = self._markers.get(raw)
                    if seen is not None:
                        seen.set()
                    else:
                        os.write(self.out_fd, raw)
                    continue
                if b"Using cached result" in raw and b"unauthorized" not in raw:
                    continue  # the bulk of it: a message allowed, as decided before
                found = parser.feed(raw.decode(errors="replace"))
                with self.lock:
                    sink = self.sink
                if found is not None and sink is not None:
                    sink.event(found.pop("key"), found.pop("reason"), **found)

    def drain(self, timeout_s: float = 5.0) -> None:
        """Wait until every line written to standard output so far has been read: a marker line of
        this call's own goes through the pipe after them, and the thread says when it reads it."""
        seen = threading.Event()
        marker = f"cosim-security-log-drain {id(seen)} {time.monotonic_ns()}\n".encode()
        with self.lock:
            self._markers[marker] = seen
        sys.stdout.flush()
        try:
            os.write(1, marker)
        except OSError:
            return
        seen.wait(timeout_s)
        with self.lock:
            self._markers.pop(marker, None)

    def restore(self) -> None:
        """Standard output back as it was (the pipe's last writer goes: the thread reads to its end)."""
        if self.out_fd < 0:
            return
        sys.stdout.flush()
        os.dup2(self.out_fd, 1)
        self.thread.join(timeout=5.0)
        os.close(self.out_fd)
        self.out_fd = -1


_pump: _StdoutPump | None = None


class ZenohDenials:
    """While open, what zenoh's access control refuses in this process becomes events of ``log``.

    zenoh (Rust) logs to this process's standard output (file descriptor 1);
    open this before the first zenoh session. Standard output then goes through
    a pipe read by a thread of this process, which passes every other line
    through unchanged (see :class:`_StdoutPump`); :meth:`close` (after the
    session closed) waits until the lines written before have been read.
    """

    def __init__(self, log: SecurityLog):
        global _pump
        if _pump is None:
            _pump = _StdoutPump()
        with _pump.lock:
            _pump.sink = log

    def close(self) -> None:
        if _pump is None:
            return
        _pump.drain()
        with _pump.lock:
            _pump.sink = None

"""The run's security log: events as JSON lines, bounded, and zenoh's access-control log read for refusals."""

from __future__ import annotations

import json

from cosim.runtime import security_log
from cosim.runtime.security_log import DenialParser, SecurityLog

LOG = "2026-11-25T20:22:41.016916Z TRACE rx-0 ThreadId({tid}) zenoh::net::routing::interceptor::access_control: {text}"
PEER = "e1c611c3afd0fa74c481aff762a2e144"
SUBJECT = f"Interface(lo)+CertCommonName(camera@lab)+Transport(Tls)+{PEER}"


def test_a_refusal_is_named_with_the_peers_certificate_and_decisions_worked_out_in_advance_are_not():
    parser = DenialParser()
    key = "cosim/r1/controller/outputs"
    # a peer declares the key: zenoh works out every kind of message for it in advance, refusals included
    lines = [LOG.format(tid=11, text=f"ACL (ingress): caching permissions for `{key}` ...")]
    lines += [LOG.format(tid=11, text=f"{PEER} on {SUBJECT} is {'un' if kind != 'Query' else ''}authorized to "
                                      f"{kind} (ingress) on {key}")
              for kind in ("Query", "Reply", "Put", "Delete", "Declare/Undeclare Subscriber",
                           "Declare/Undeclare Queryable", "Declare/Undeclare Liveliness Token", "Liveliness Query",
                           "Declare Liveliness Subscriber")]
    assert [parser.feed(line) for line in lines] == [None] * len(lines)
    allowed = LOG.format(tid=12, text=f"Using cached result: {PEER} is authorized to Put (ingress) on {key}")
    assert parser.feed(allowed) is None
    refused = LOG.format(tid=12, text=f"Using cached result: {PEER} is unauthorized to Put (ingress) on {key}")
    assert parser.feed("\x1b[2m" + refused + "\x1b[0m") == {
        "key": key, "reason": "refused by access control: camera@lab may not Put (ingress) here",
        "from": "camera@lab"}
    # a decision on a message, outside any key's caching: a refusal too
    direct = LOG.format(tid=13, text=f"{PEER} on {SUBJECT} is unauthorized to Put (ingress) on cosim/r1/ctl/tick")
    assert parser.feed(direct)["key"] == "cosim/r1/ctl/tick"
    assert parser.feed(LOG.format(tid=1, text="Access control is enabled")) is None


def test_events_are_json_lines_with_time_key_and_reason_and_a_flood_is_counted_not_written(tmp_path, monkeypatch):
    monkeypatch.setattr(security_log, "MAX_LINES", 3)
    log = SecurityLog(tmp_path / "run", "node plant")
    for tick in range(5):
        log.event("cosim/r1/coil_driver/outputs", "dropped a sample", tick=tick)
    lines = [json.loads(line) for line in (tmp_path / "run" / "security.jsonl").read_text().splitlines()]
    assert log.count == 5 and [e["tick"] for e in lines] == [0, 1, 2]
    assert set(lines[0]) == {"time", "process", "key", "reason", "tick"} and lines[0]["process"] == "node plant"


def test_zenohs_refusals_on_standard_output_become_events_and_every_other_line_goes_through(tmp_path):
    """In a process of its own (the pump takes over file descriptor 1 for the process's life): what the
    process prints passes through in order, before and after, up to its exit; zenoh's access-control
    lines do not, and its refusals are logged while a run's log is open."""
    import subprocess
    import sys

    zenoh_line = "2026 TRACE rx-0 ThreadId(3) zenoh::net::routing::interceptor::access_control: {}\n"
    script = f"""
import os
from cosim.runtime.security_log import SecurityLog, ZenohDenials
log = SecurityLog({str(tmp_path)!r}, "scheduler")
denials = ZenohDenials(log)
print("first", flush=True)
os.write(1, {zenoh_line!r}.format("Using cached result: abcd is unauthorized to Put (ingress) on cosim/r/x").encode())
os.write(1, {zenoh_line!r}.format("Using cached result: abcd is authorized to Put (ingress) on cosim/r/y").encode())
denials.close()
print("events", log.count)
os.write(1, {zenoh_line!r}.format("Access control is disabled").encode())
print("last")
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "first\nevents 1\nlast\n"
    (event,) = [json.loads(line) for line in (tmp_path / "security.jsonl").read_text().splitlines()]
    assert event["key"] == "cosim/r/x" and event["reason"].startswith("refused by access control: peer abcd")

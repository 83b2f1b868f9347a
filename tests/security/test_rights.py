"""Per-component rights in a ``--hosts`` run (two loopback addresses standing in for two machines, one of
them running the camera and the coil driver): a holder of the camera's certificate, connecting from
elsewhere, cannot change what the coil driver applies nor what the plant is driven with, though the coil
driver runs on the camera's host; every attempt is refused and logged in the run's security.jsonl; plain
TCP beyond loopback is refused."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cosim.api import RunRequest, run
from cosim.cli import main
from cosim.runtime import bus
from cosim.runtime.bus import TlsFiles
from cosim.runtime.wiring import build_wiring
from cosim.scenario.schema import load_scenario
from cosim_plugins.resources import SCENARIOS_DIR

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = SCENARIOS_DIR / "racetrack.yaml"
SHORT = ["duration_s=4"]  # paced at real time: the forger has 4 s of stepping to act in
FORGED_HZ = 55.5555  # a drive frequency the controller never commands


def _free_port(address: str) -> int:
    with socket.socket() as s:
        s.bind((address, 0))
        return s.getsockname()[1]


def _hosts(folder: Path) -> Path:
    sim, lab = _free_port("127.0.0.1"), [_free_port("127.0.0.2") for _ in range(2)]
    hosts = folder / "hosts.yaml"
    hosts.write_text(f"""
wait_s: 60
tls: {{ca: certs/ca.pem}}
scheduler: {{host: sim, listen: tls/127.0.0.1:{sim}}}
hosts:
  sim: {{address: 127.0.0.1, cert: certs/sim.pem, key: certs/sim.key}}
  lab: {{address: 127.0.0.2, launch: local, cert: certs/lab.pem, key: certs/lab.key}}
components:
  camera: {{host: lab, listen: tls/127.0.0.2:{lab[0]}}}
  coil_driver: {{host: lab, listen: tls/127.0.0.2:{lab[1]}}}
""")
    assert main(["certs", str(hosts)]) == 0
    return hosts


def _node_args(run_pid: int, component: str, timeout_s: float = 90.0) -> list[str]:
    """The command line of the run's node of ``component`` (a child of ``run_pid``), once it is up."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for status in Path("/proc").glob("[0-9]*/status"):
            try:
                if f"PPid:\t{run_pid}\n" not in status.read_text():
                    continue
                args = (status.parent / "cmdline").read_bytes().decode().split("\0")
            except OSError:
                continue
            if "node" in args and component in args:
                return args
        time.sleep(0.05)
    raise AssertionError(f"no node of {component} appeared")


def test_the_camera_certificate_cannot_drive_the_coils_of_its_own_host(tmp_path):
    hosts = _hosts(tmp_path)
    certs = tmp_path / "certs"
    stolen = TlsFiles(certs / "ca.pem", certs / "lab.camera.pem", certs / "lab.camera.key")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    run_proc = subprocess.Popen([sys.executable, "-m", "cosim.cli", "run", str(SCENARIO), "--processes", "--hosts",
                                 str(hosts), "--out", "run", "--quiet", "--realtime", "1",
                                 *[a for s in SHORT for a in ("--set", s)]],
                                cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    session = None
    try:
        args = _node_args(run_proc.pid, "coil_driver")
        run_id = args[args.index("--run-id") + 1]
        endpoints = [args[args.index("--listen") + 1], *[a for i, a in enumerate(args) if args[i - 1] == "--connect"]]
        # the camera's files, used from another address: the coil driver's node, the scheduler, all
        session = bus.open_session(connect=endpoints, tls=stolen)
        scenario = load_scenario(SCENARIO, SHORT)
        outputs = build_wiring(scenario).outputs
        # what the coil driver takes (the controller's outputs) and what the plant takes (the coil driver's)
        forged = {c: np.full(sum(int(np.prod(p.shape)) for p in outputs[c]), FORGED_HZ)
                  for c in ("controller", "coil_driver")}
        outs = {c: bus.publisher(session, bus.outputs_key(run_id, c)) for c in forged}
        cmd = bus.publisher(session, bus.ctl_key(run_id, "coil_driver", "cmd"))
        tick_pub = bus.publisher(session, bus.tick_key(run_id))
        for _ in range(300):  # bounded: up to 300 bursts (15 s), every tick stamped ahead of its producer
            for tick in range(scenario.n_steps):
                for comp, values in forged.items():
                    outs[comp].put(values.tobytes(), attachment=bus.encode_tick(tick))
            tick_pub.put(bus.encode_json({"until": scenario.n_steps}))
            cmd.put(bus.encode_json({"cmd": "stop"}))
            if run_proc.poll() is not None:
                break
            time.sleep(0.05)
        _, err = run_proc.communicate(timeout=120)
    finally:
        if session is not None:
            session.close()
        if run_proc.poll() is None:
            run_proc.kill()
            run_proc.communicate()
    assert run_proc.returncode == 0, err
    one = run(RunRequest(SCENARIO, tmp_path / "one", SHORT, progress=False))
    assert one["status"] == "ok"
    log = (tmp_path / "run" / "log.csv").read_text()
    assert str(FORGED_HZ) not in log
    # what the coil driver applied was the controller's, and the plant moved as driven by the coil driver's
    assert log == (tmp_path / "one" / "log.csv").read_text()
    # every attempt refused where it arrived, logged with its time, key and reason in the run's security.jsonl
    events = [json.loads(line) for line in (tmp_path / "run" / "security.jsonl").read_text().splitlines()]
    refused = {(e["process"], e["key"]) for e in events if e.get("from") == "camera@lab"}
    assert {("node coil_driver", bus.outputs_key(run_id, "controller")),
            ("node coil_driver", bus.ctl_key(run_id, "coil_driver", "cmd")),
            ("node plant", bus.outputs_key(run_id, "coil_driver"))} <= refused, refused
    assert all(e["reason"].startswith("refused by access control: camera@lab may not") and e["time"]
               for e in events if e.get("from"))
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["security_event_count"] >= len(events)


def test_plain_tcp_beyond_loopback_is_refused(tmp_path, capsys):
    hosts = tmp_path / "hosts.yaml"
    hosts.write_text("scheduler: {host: one, listen: tcp/0.0.0.0:7447}\nhosts:\n  one: {address: 0.0.0.0}\n")
    code = main(["run", str(ROOT / "tests" / "core" / "data" / "toy.yaml"), "--processes", "--hosts", str(hosts),
                 "--out", str(tmp_path / "run")])
    assert code == 2
    assert ("scheduler.listen (line 1): tcp/0.0.0.0:7447: plain TCP beyond loopback lets anyone on the network "
            "join the run") in capsys.readouterr().err
    assert not (tmp_path / "run").exists()  # a refused hosts file writes nothing


def test_rights_text_round_trips_and_bad_text_is_named():
    from cosim.contract.errors import UserError
    from cosim.runtime.rights import Rights, format_rights, parse_rights

    rights = Rights("sim", {"sim": ("plant", "controller"), "cam": ("camera",)})
    assert parse_rights(format_rights(rights)) == rights
    with pytest.raises(UserError, match="expected SCHEDULER_HOST;IDENTITY=COMP"):
        parse_rights("sim;cam")


def test_each_placed_component_links_with_a_certificate_of_its_own_and_its_rights_only(tmp_path):
    from cosim.runtime.hosts import load_hosts
    from cosim.runtime.rights import access_control, rights_of

    scenario = load_scenario(SCENARIO)
    plan = load_hosts(_hosts(tmp_path), scenario)
    assert {n: (p.identity, p.tls.cert.name) for n, p in plan.nodes.items() if n in ("camera", "coil_driver")} == \
        {"camera": ("camera@lab", "lab.camera.pem"), "coil_driver": ("coil_driver@lab", "lab.coil_driver.pem")}
    rights = rights_of(plan)
    # the components not placed run on the scheduler's machine, under its certificate; the lab host's own has none
    assert rights.identities == {"sim": ("plant", "estimator", "controller"), "camera@lab": ("camera",),
                                 "coil_driver@lab": ("coil_driver",)}
    acl = access_control("r1", build_wiring(scenario), rights)
    subject = {s["cert_common_names"][0]: s["id"] for s in acl["subjects"]}
    policy = next(p for p in acl["policies"] if p["subjects"] == [subject["camera@lab"]])
    rules = {r["id"]: r for r in acl["rules"] if r["id"] in policy["rules"]}
    puts = sorted(k for r in rules.values() if r["flows"] == ["ingress"] and "put" in r["messages"]
                  for k in r["key_exprs"])
    assert puts == ["cosim/r1/camera/outputs", "cosim/r1/ctl/camera/reply"]
    assert "lab" not in subject  # a certificate of the host alone may publish nothing

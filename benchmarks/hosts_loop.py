"""What crossing between hosts costs a tick: the racetrack loop with one process per component, on
loopback TCP (``--processes``) and over mutual TLS between two loopback addresses (``--hosts``).

The second layout is a run over machines as ``cosim run --hosts`` makes it,
on one machine: the camera and the estimator on "host two" (127.0.0.2), the
plant, the controller and the coil driver with the scheduler on 127.0.0.1,
every link mutual TLS with certificates ``cosim certs`` makes; its nodes are
started here (``launch: local``), so no network's latency is in it, only
TLS and the endpoints. Prints JSON: each layout's real-time factor (median
of ``--repeats``; simulated over wall time of the stepping loop), their
ratio, and whether the logs are byte-identical.

    .venv/bin/python benchmarks/hosts_loop.py [--sim-s 30] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import socket
import statistics
import tempfile
from pathlib import Path

from cosim.api import RunRequest, run
from cosim.scale.certs import make_certificates
from cosim_plugins.resources import SCENARIOS_DIR

SCENARIO = SCENARIOS_DIR / "racetrack.yaml"


def _port(address: str) -> int:
    with socket.socket() as s:
        s.bind((address, 0))
        return s.getsockname()[1]


def hosts_file(folder: Path) -> Path:
    path = folder / "hosts.yaml"
    path.write_text(f"""
tls: {{ca: certs/ca.pem}}
scheduler: {{host: one, listen: tls/127.0.0.1:{_port('127.0.0.1')}}}
hosts:
  one: {{address: 127.0.0.1, cert: certs/one.pem, key: certs/one.key}}
  two: {{address: 127.0.0.2, launch: local, cert: certs/two.pem, key: certs/two.key}}
components:
  camera: {{host: two, listen: tls/127.0.0.2:{_port('127.0.0.2')}}}
  estimator: {{host: two, listen: tls/127.0.0.2:{_port('127.0.0.2')}}}
""")
    make_certificates(path)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sim-s", type=float, default=30.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    factors: dict[str, list[float]] = {"loopback_tcp": [], "two_hosts_tls": []}
    logs: dict[str, set[bytes]] = {k: set() for k in factors}
    with tempfile.TemporaryDirectory() as tmp:
        hosts = hosts_file(Path(tmp))
        for i in range(args.repeats):
            for layout in factors:
                out = Path(tmp) / f"{layout}_{i}"
                summary = run(RunRequest(SCENARIO, out, [f"duration_s={args.sim_s}"], True, False,
                                         hosts=hosts if layout == "two_hosts_tls" else None))
                factors[layout].append(round(summary["realtime_factor"], 2))
                logs[layout].add((out / "log.csv").read_bytes())
    median = {k: statistics.median(v) for k, v in factors.items()}
    print(json.dumps({
        "sim_s": args.sim_s,
        **{k: {"realtime_factor": median[k], "runs": v} for k, v in factors.items()},
        "tls_over_tcp": round(median["two_hosts_tls"] / median["loopback_tcp"], 3),
        "logs_identical": len(logs["loopback_tcp"] | logs["two_hosts_tls"]) == 1,
    }, indent=2))


if __name__ == "__main__":
    main()

"""Soak: the racetrack run for hours of simulated time, its peak memory and the files it leaves.

Each case runs in a fresh Python process (``cosim run`` in-process there, as fast as it goes),
which reports its own peak resident memory (``ru_maxrss``) and, with ``--processes``, the
largest of its node processes'. Prints JSON: ``{"runs": [{"hours", "layout", "wall_s",
"peak_mb", "files_mb", "nodes_peak_mb", "steps", "realtime_factor", "status"}]}``; ``layout``
is ``one_process`` or ``processes``, ``wall_s`` the case's whole wall time (set-up and
writing the files included), ``files_mb`` the size of the run's folder when it ended.

    .venv/bin/python benchmarks/soak.py                    # 1 h and 12 h in one process, 1 h with --processes
    .venv/bin/python benchmarks/soak.py --hours 0.25       # a shorter check: 15 min each way
    .venv/bin/python benchmarks/soak.py --hours 1 --rotate 0.5 --no-processes
    .venv/bin/python benchmarks/soak.py --no-one-process --processes-hours 1 12   # --processes, 1 h and 12 h
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from cosim_plugins.resources import SCENARIOS_DIR

SCENARIO = SCENARIOS_DIR / "racetrack.yaml"


def child(hours: float, processes: bool, out: Path, rotate_h: float | None) -> None:
    """Run one case here and print what it took (in the child process)."""
    from cosim.api import RunRequest, run

    summary = run(RunRequest(SCENARIO, out, [f"duration_s={hours * 3600.0}"], processes, progress=False,
                             rotate_s=None if rotate_h is None else rotate_h * 3600.0))
    own, nodes = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    print(json.dumps({"peak_mb": round(own.ru_maxrss / 1024, 1),  # ru_maxrss: kB on Linux
                      "nodes_peak_mb": round(nodes.ru_maxrss / 1024, 1) if processes else None,
                      "steps": summary["steps"], "realtime_factor": round(summary["realtime_factor"] or 0, 1),
                      "status": summary["status"]}))


def measure(hours: float, processes: bool, rotate_h: float | None) -> dict:
    with tempfile.TemporaryDirectory(prefix="soak-") as tmp:
        out = Path(tmp) / "run"
        cmd = [sys.executable, __file__, "--child", str(hours), "--out", str(out)]
        cmd += ["--processes"] if processes else []
        cmd += ["--rotate", str(rotate_h)] if rotate_h else []
        t0 = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True)
        wall_s = time.perf_counter() - t0
        if done.returncode != 0:
            raise SystemExit(f"soak {hours} h ({'processes' if processes else 'one process'}) failed:\n{done.stderr}")
        files_mb = sum(f.stat().st_size for f in out.rglob("*") if f.is_file()) / 2**20
        got = json.loads(done.stdout.strip().splitlines()[-1])
    return {"hours": hours, "layout": "processes" if processes else "one_process", "wall_s": round(wall_s, 1),
            "peak_mb": got["peak_mb"], "files_mb": round(files_mb, 1), "nodes_peak_mb": got["nodes_peak_mb"],
            "steps": got["steps"], "realtime_factor": got["realtime_factor"], "status": got["status"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, nargs="+", default=[1.0, 12.0],
                        help="simulated hours of the one-process runs (default 1 12)")
    parser.add_argument("--no-processes", action="store_true", help="leave out the --processes runs")
    parser.add_argument("--processes-hours", type=float, nargs="+", default=None,
                        help="simulated hours of the --processes runs (default: the first of --hours)")
    parser.add_argument("--no-one-process", action="store_true", help="leave out the one-process runs")
    parser.add_argument("--rotate", type=float, default=None, metavar="HOURS",
                        help="record in parts (cosim run --rotate)")
    parser.add_argument("--child", type=float, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--processes", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        child(args.child, args.processes, args.out, args.rotate)
        return
    processes_hours = args.processes_hours or args.hours[:1]
    for name, hours in (("--hours", args.hours), ("--processes-hours", processes_hours)):
        if any(not h > 0 for h in hours):
            parser.error(f"{name} {hours}: every value must be > 0")
    runs = [] if args.no_one_process else [measure(h, False, args.rotate) for h in args.hours]
    if not args.no_processes:
        runs += [measure(h, True, args.rotate) for h in processes_hours]
    print(json.dumps({"runs": runs}, indent=2))


if __name__ == "__main__":
    main()

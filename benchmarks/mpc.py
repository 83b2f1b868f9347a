"""MPC solve time per control step over a racetrack run (horizon 5, Table V weights).

Runs ``scenarios/controllers_racetrack.yaml`` with ``controller.mpc`` (no sweep)
through the normal runner (plant FMU, camera noise, zenoh, one process) and
reads the controller's ``solve_time`` port from the trace: the wall time of
each step's computation (reference + QP + clipping). The first
``--skip`` steps are dropped (before the first camera frame there is no solve).
Prints JSON: {"median_ms", "p99_ms", "solves", "backend", "duration_s", "tracking_error_mm"}.
Budget (DESIGN.md): median <= 1.5 ms, p99 <= 5 ms (the paper: 10.7 +- 5.3 ms).

    .venv/bin/python benchmarks/mpc.py [--duration 60] [--backend osqp|cvxpy]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from cosim.api import RunRequest, run
from cosim_plugins.resources import SCENARIOS_DIR

SCENARIO = SCENARIOS_DIR / "controllers_racetrack.yaml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=60.0, help="simulated seconds [s]")
    parser.add_argument("--backend", default="osqp", choices=("osqp", "cvxpy"))
    parser.add_argument("--skip", type=int, default=1, help="initial steps not counted")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_mpc_") as tmp:
        overrides = ["sweep={}", f"duration_s={args.duration}", "components.controller.plugin=controller.mpc",
                     f"components.controller.params.backend={args.backend}"]
        summary = run(RunRequest(SCENARIO, Path(tmp), overrides, progress=False))
        with np.load(Path(tmp) / "trace.npz") as trace:
            solve_ms = trace["controller.solve_time"][args.skip:] * 1e3
    solve_ms = solve_ms[np.isfinite(solve_ms)]
    print(json.dumps({
        "median_ms": round(float(np.median(solve_ms)), 4),
        "p99_ms": round(float(np.percentile(solve_ms, 99)), 4),
        "solves": int(len(solve_ms)),
        "backend": args.backend,
        "duration_s": args.duration,
        "tracking_error_mm": summary["tracking_error_mm"],
    }))


if __name__ == "__main__":
    main()

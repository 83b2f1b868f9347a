"""Real-time factor of the racetrack PI loop over zenoh: one process, and one process per component.

Prints JSON: {"one_process": {"realtime_factor": median, "runs": [...]},
"processes": {...}, "sim_s": ..., "budgets": {...}}. The factor is simulated
time over the wall time of the stepping loop (set-up and file writing excluded).

    .venv/bin/python benchmarks/loop.py [--sim-s 60] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
from pathlib import Path

from cosim.runner import RunRequest, run

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "racetrack.yaml"


def measure(processes: bool, sim_s: float, repeats: int) -> dict:
    factors = []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as out:
            summary = run(RunRequest(SCENARIO, Path(out), [f"duration_s={sim_s}"], processes, progress=False))
        factors.append(round(summary["realtime_factor"], 2))
    return {"realtime_factor": statistics.median(factors), "runs": factors}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sim-s", type=float, default=60.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    result = {
        "sim_s": args.sim_s,
        "one_process": measure(False, args.sim_s, args.repeats),
        "processes": measure(True, args.sim_s, args.repeats),
        "budgets": {"one_process": 50, "processes": 10},
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()

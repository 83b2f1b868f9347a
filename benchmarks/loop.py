"""Real-time factor of the racetrack PI loop over zenoh: one process, and one process per component.

Prints JSON: {"one_process": {"realtime_factor": median, "runs": [...],
"cpu_steal_pct": ...}, "processes": {...}, "processes_os_placement": {...},
"sim_s": ..., "budgets": {...}}. ``processes`` places the nodes as ``cosim run
--processes`` does by default (all on one CPU, see cosim.runtime.placement);
``processes_os_placement`` leaves that to the operating system
(``--node-cpus none``), for comparison. The
factor is simulated time over the wall time of the stepping loop (set-up and
file writing excluded). ``cpu_steal_pct`` is the share of CPU time the
hypervisor took from this machine while the runs went (Linux /proc/stat; None
elsewhere): on a shared VM a high share explains a low factor.

    .venv/bin/python benchmarks/loop.py [--sim-s 60] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
from pathlib import Path

from cosim.runtime.runner import RunRequest, run
from cosim_plugins.resources import SCENARIOS_DIR

SCENARIO = SCENARIOS_DIR / "racetrack.yaml"


def cpu_times() -> list[int] | None:
    """The machine's aggregate CPU times (jiffies: user nice system idle iowait irq softirq steal)."""
    try:
        return [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:9]]
    except (OSError, ValueError):
        return None


def measure(processes: bool, sim_s: float, repeats: int, node_cpus: str = "auto") -> dict:
    factors = []
    before = cpu_times()
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as out:
            summary = run(RunRequest(SCENARIO, Path(out), [f"duration_s={sim_s}"], processes, False, node_cpus))
        factors.append(round(summary["realtime_factor"], 2))
    after = cpu_times()
    steal = None
    if before and after and sum(after) > sum(before):
        steal = round(100 * (after[7] - before[7]) / (sum(after) - sum(before)), 1)
    return {"realtime_factor": statistics.median(factors), "runs": factors, "cpu_steal_pct": steal}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sim-s", type=float, default=60.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    result = {
        "sim_s": args.sim_s,
        "one_process": measure(False, args.sim_s, args.repeats),
        "processes": measure(True, args.sim_s, args.repeats),
        "processes_os_placement": measure(True, args.sim_s, args.repeats, node_cpus="none"),
        "budgets": {"one_process": 100, "processes": 25},
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()

"""Wall time of the Fig. 6 sweep with one run at a time and with two in parallel (``cosim run --jobs``).

Runs ``cosim run scenarios/feedback_sweep.yaml --quiet`` with ``--jobs 1``
(every run in one process, one after another) and ``--jobs 2`` (two worker
processes), each as a fresh ``cosim`` process, alternately, ``--repeats``
times; the caches (models, the paper dataset) are made first, untimed.
Prints JSON: each setting's wall times and their median, the ratio of the
medians (budget: <= 0.6 on two cores), whether the rows (but for the
measured computation times, ``solve_ms``) and every run's ``log.csv`` are
identical, and the machine's load (the 1-minute load average before and
after, the CPU share the hypervisor stole meanwhile).

    .venv/bin/python benchmarks/sweep_jobs.py [--repeats 3] [--set KEY=VALUE]...
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from cosim.scale.sweep import prepare_caches
from cosim.scenario.schema import load_scenario, sweep_overrides
from cosim_plugins.resources import SCENARIOS_DIR

SCENARIO = SCENARIOS_DIR / "feedback_sweep.yaml"
TIMINGS = ("solve_ms",)


def cpu_times() -> list[int] | None:
    try:
        return [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:9]]
    except (OSError, ValueError):
        return None


def sweep(jobs: int, out: Path, overrides: list[str]) -> float:
    """Wall time [s] of one ``cosim run`` of the sweep with ``--jobs jobs``."""
    cmd = [sys.executable, "-m", "cosim.cli", "run", str(SCENARIO), "--out", str(out), "--quiet", "--jobs", str(jobs)]
    for item in overrides:
        cmd += ["--set", item]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, stdin=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} exited with status {done.returncode}")
    return wall


def outcome(out: Path) -> tuple[list[dict], dict[str, bytes]]:
    rows = json.loads((out / "summary.json").read_text())["sweep"]
    rows = [{k: v for k, v in row.items() if k not in TIMINGS} for row in rows]
    logs = {d.name: (d / "log.csv").read_bytes() for d in sorted((out / "runs").iterdir())}
    return rows, logs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override the scenario (e.g. duration_s=10 for a quick look)")
    args = parser.parse_args()
    base = load_scenario(SCENARIO, args.overrides)
    prepare_caches((SCENARIO, [*args.overrides, *extra, "sweep={}"]) for _, extra in sweep_overrides(base))
    walls: dict[int, list[float]] = {1: [], 2: []}
    same_rows = same_logs = True
    load_before, steal_before = os.getloadavg()[0], cpu_times()
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.repeats):
            outs = {}
            for jobs in ((1, 2) if i % 2 == 0 else (2, 1)):
                outs[jobs] = Path(tmp) / f"{i}_jobs{jobs}"
                walls[jobs].append(round(sweep(jobs, outs[jobs], args.overrides), 2))
            (rows1, logs1), (rows2, logs2) = outcome(outs[1]), outcome(outs[2])
            same_rows &= rows1 == rows2
            same_logs &= logs1 == logs2 and len(logs1) == len(sweep_overrides(base))
    steal_after = cpu_times()
    steal = None
    if steal_before and steal_after and sum(steal_after) > sum(steal_before):
        steal = round(100 * (steal_after[7] - steal_before[7]) / (sum(steal_after) - sum(steal_before)), 1)
    median = {jobs: statistics.median(w) for jobs, w in walls.items()}
    print(json.dumps({
        "scenario": str(SCENARIO.relative_to(SCENARIO.parents[1])), "overrides": args.overrides,
        "runs_per_sweep": len(sweep_overrides(base)), "cpus": len(os.sched_getaffinity(0)),
        "jobs_1_wall_s": {"median": median[1], "runs": walls[1]},
        "jobs_2_wall_s": {"median": median[2], "runs": walls[2]},
        "ratio": round(median[2] / median[1], 3), "budget_ratio": 0.6,
        "rows_identical_but_timings": same_rows, "logs_identical": same_logs,
        "load_average_1min": {"before": round(load_before, 2), "after": round(os.getloadavg()[0], 2)},
        "cpu_steal_pct": steal,
    }, indent=2))


if __name__ == "__main__":
    main()

"""Real-time pacing of the racetrack PI loop: missed ticks and lateness, one process and --processes.

Runs ``scenarios/racetrack.yaml`` paced at real time (``cosim run --realtime``)
and prints JSON: per layout the run's ``realtime`` summary (ticks, missed,
longest run of misses, lateness p50/p99/max [ms], whether SCHED_FIFO was
granted), ``missed_pct``, and the budgets of issue 15 (missed <= 0.1 %,
lateness p99 <= 2 ms) with whether they held. A paced run takes its
simulated time in wall time (60 s each by default).

    .venv/bin/python benchmarks/realtime.py [--sim-s 60] [--factor 1] [--layouts one,processes]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from cosim.api import RunRequest, run
from cosim_plugins.resources import SCENARIOS_DIR

SCENARIO = SCENARIOS_DIR / "racetrack.yaml"
BUDGETS = {"missed_pct_max": 0.1, "lateness_p99_ms_max": 2.0}


def measure(processes: bool, sim_s: float, factor: float) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        summary = run(RunRequest(SCENARIO, Path(tmp), [f"duration_s={sim_s}"], processes=processes,
                                 progress=False, realtime=factor))
    rt = summary["realtime"]
    missed_pct = 100.0 * rt["missed"] / max(rt["ticks"] + rt["missed"], 1)
    return {**rt, "missed_pct": round(missed_pct, 4),
            "within_budget": missed_pct <= BUDGETS["missed_pct_max"]
            and rt["lateness_ms"]["p99"] <= BUDGETS["lateness_p99_ms_max"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim-s", type=float, default=60.0, help="simulated (= wall) seconds per run")
    ap.add_argument("--factor", type=float, default=1.0, help="real-time factor (default 1)")
    ap.add_argument("--layouts", default="one,processes", help="one, processes or both (comma-separated)")
    args = ap.parse_args(argv)
    out = {"sim_s": args.sim_s, "budgets": BUDGETS}
    for layout in args.layouts.split(","):
        out[layout] = measure(layout == "processes", args.sim_s, args.factor)
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

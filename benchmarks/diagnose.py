"""Wall time of `cosim diagnose` on five 3,000-row plant logs; prints JSON. Budget: 20 s (DESIGN.md, round 3).

The logs come from ``scenarios/diagnose/plain.yaml`` (60 s per path, a
background flow of 3 mm/s hidden in the plant FMU), recorded once and cached
under ``cache/bench_diagnose/``; recording is not timed. The timed part is
the whole command: reading the logs, the baseline fit, the noise floor, the
localisation, the joint refit of every library effect, the verdict and
writing diagnosis.json, report.md with its plots and diagnosis.rrd, with the
command's default ``--jobs`` (the CPUs, at most 4).

    .venv/bin/python benchmarks/diagnose.py [--cache cache/bench_diagnose] [--jobs N]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

from cosim_plugins.resources import SCENARIOS_DIR

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = SCENARIOS_DIR / "diagnose" / "plain.yaml"
BUDGET_S = 20.0
N_LOGS = 5
HIDDEN = ["components.plant.params.background_flow_on=true", "components.plant.params.flow_x=0.003"]


def make_logs(cache: Path) -> tuple[list[Path], float]:
    """Five 60 s logs (two sweeps of the scenario with different seeds), cached."""
    from cosim.api import RunRequest, run

    t0 = time.perf_counter()
    files: list[Path] = []
    for seed in (7, 8):
        out = cache / f"seed{seed}"
        if not sorted(out.glob("runs/*/log.csv")):
            run(RunRequest(SCENARIO, out, ["duration_s=60", f"seed={seed}", *HIDDEN], progress=False))
        files += sorted(out.glob("runs/*/log.csv"))
    return files[:N_LOGS], time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", default=str(ROOT / "cache" / "bench_diagnose"))
    ap.add_argument("--jobs", type=int, default=min(4, os.cpu_count() or 1), help="diagnose --jobs (default: CPUs)")
    args = ap.parse_args(argv)

    from cosim_plugins.diagnose.pipeline import Settings, run
    from cosim_plugins.diagnose.report import write_outputs
    from cosim_plugins.raw_log import read_logs

    files, record_s = make_logs(Path(args.cache))
    rows = sum(lg.n for lg in read_logs(files))
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        diag = run(files, settings=Settings(jobs=args.jobs))
        write_outputs(diag, Path(tmp) / "diag", args.jobs)
        wall = time.perf_counter() - t0
    r = diag.json
    best = r["ranking"][0]
    print(json.dumps({
        "logs": len(files), "rows": rows, "record_s": round(record_s, 1),
        "diagnose_wall_s": round(wall, 2), "jobs": args.jobs, "budget_s": BUDGET_S, "within_budget": wall <= BUDGET_S,
        "candidates": len(r["ranking"]), "hidden": "background_flow (3 mm/s along x)",
        "verdict": r["verdict"]["effect"], "named": r["verdict"]["effects"], "drift_flagged": r["drift"]["flagged"],
        "best": {"effect": best["effect"], "reduction": round(best["reduction"], 3),
                 "params": {k: round(v["value"], 3) for k, v in best["params"].items()}},
        "baseline_rollout_mm": {h: round(v, 3) for h, v in r["baseline"]["rollout_mm"].items()},
        "noise_floor_mm": round(r["noise_floor_mm"], 3),
    }, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

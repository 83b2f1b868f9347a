"""Wall time and peak memory of `cosim diagnose` on an archive: 5, 20 and 120 logs of 60 s; prints JSON.

The logs come from the blind bench's independent simulator (``benchmarks/blind_sim.py``): one case with one
hidden library effect (default: a background flow; ``--effect``), drawn with 120 logs of 60 s each on
their own paths (2 hours), written once under ``--cache``. Each size diagnoses the first N of them, in a
fresh process (``cosim diagnose`` as a user runs it, ``--jobs`` as given), so each peak is its own:
``peak_mb`` is the diagnosis process's peak resident memory plus the largest of its worker processes'.
Budget (DESIGN.md): 2 hours within 3 minutes and 3 GB, and the verdict for 120 logs the same as for 20.

    .venv/bin/python benchmarks/archive.py [--sizes 5,20,120] [--seed 1] [--jobs 2] [--cache cache/bench_archive]

Prints ``{"runs": [{"logs", "rows", "wall_s", "peak_mb", "effects", "status"}], ...}``; ``effects`` is the
verdict's named set.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
BUDGET_S, BUDGET_MB = 180.0, 3000.0
LOG_S = 60.0


def make_logs(cache: Path, n: int, seed: int, effect: str) -> list[Path]:
    """n logs of 60 s of one bench case hiding ``effect`` (cached with the case's truth in case.json)."""
    sys.path.insert(0, str(HERE))
    import blind_sim

    folder = cache / f"{effect}_seed{seed}_{n}"
    files = sorted(folder.glob("log_*.csv"))
    if len(files) == n:
        return files
    case = blind_sim.draw_case(seed, "library", effect, logs=n, log_durations_s=[LOG_S] * n,
                               duration_s=LOG_S * n)
    files = blind_sim.simulate(case, folder)
    (folder / "case.json").write_text(json.dumps({"effect": case.effect, "truth": case.truth,
                                                  "regime": case.regime}, indent=1))
    return files


def _child(args) -> int:
    """Run one diagnosis in this process and print its figures as one JSON line (the parent's measurement)."""
    import resource

    from cosim_plugins.diagnose.pipeline import Settings, run
    from cosim_plugins.diagnose.report import write_outputs

    files = [Path(p) for p in args.files]
    t0 = time.perf_counter()
    diag = run(files, settings=Settings(jobs=args.jobs))
    with tempfile.TemporaryDirectory() as tmp:
        write_outputs(diag, Path(tmp) / "diag", args.jobs)
    wall = time.perf_counter() - t0
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    workers = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    v = diag.json["verdict"]
    print(json.dumps({"wall_s": round(wall, 1), "peak_mb": round(own + workers, 1), "effects": v["effects"],
                      "lookalikes": v["lookalikes"], "status": v["status"],
                      "drift_flagged": diag.json["drift"]["flagged"],
                      "rows": int(diag.timeline.n)}))
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="5,20,120", help="numbers of logs (default 5,20,120)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the bench case (default 1)")
    ap.add_argument("--effect", default="background_flow", help="the hidden library effect (default background_flow)")
    ap.add_argument("--jobs", type=int, default=min(4, os.cpu_count() or 1), help="diagnose --jobs (default: CPUs)")
    ap.add_argument("--cache", default=str(ROOT / "cache" / "bench_archive"))
    ap.add_argument("--child", nargs="+", dest="files", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.files:
        return _child(args)
    sizes = sorted({int(x) for x in args.sizes.split(",")})
    t0 = time.perf_counter()
    logs = make_logs(Path(args.cache), max(sizes), args.seed, args.effect)
    record_s = time.perf_counter() - t0
    runs = []
    for n in sizes:
        print(f"archive: diagnosing {n} logs ...", file=sys.stderr, flush=True)
        proc = subprocess.run([sys.executable, __file__, "--jobs", str(args.jobs), "--child",
                               *map(str, logs[:n])], capture_output=True, text=True)
        if proc.returncode != 0:
            print(proc.stderr[-2000:], file=sys.stderr)
            raise SystemExit(f"archive: the diagnosis of {n} logs failed (exit {proc.returncode})")
        run = json.loads(proc.stdout.strip().splitlines()[-1])
        runs.append({"logs": n, "hours": round(n * LOG_S / 3600.0, 2), **run})
        print(f"archive: {n} logs: {run['wall_s']} s, {run['peak_mb']} MB, named {run['effects']}",
              file=sys.stderr, flush=True)
    largest = runs[-1]
    twenty = next((r for r in runs if r["logs"] == 20), None)
    print(json.dumps({
        "hidden": args.effect, "seed": args.seed, "jobs": args.jobs, "record_s": round(record_s, 1), "runs": runs,
        "budget": {"wall_s": BUDGET_S, "peak_mb": BUDGET_MB, "logs": largest["logs"],
                   "within": largest["wall_s"] <= BUDGET_S and largest["peak_mb"] <= BUDGET_MB},
        "same_verdict_as_20": (twenty is not None and twenty["effects"] == largest["effects"]
                               and twenty["lookalikes"] == largest["lookalikes"]),
    }, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

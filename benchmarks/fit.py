"""Training times of the four models on the paper's data volume (Table II analog); prints JSON.

174,000 samples: 12 synthetic logs (6 circles, 6 racetracks) x 14,500 rows
from the richer synthetic plant (physical model + quadratic drag, fine
steps), cached under ``cache/bench_fit/``. Budgets: physical <= 15 s,
SINDy nonlinear <= 5 s, SINDy linear <= 1 s, MLP <= 30 s, all <= 60 s.
Times exclude importing pysindy/torch (done once up front) and reading logs.

    .venv/bin/python benchmarks/fit.py [--rows 14500] [--repeats 3] [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

BUDGETS_S = {"physical": 15.0, "sindy-linear": 1.0, "sindy-nonlinear": 5.0, "mlp": 30.0}
TOTAL_BUDGET_S = 60.0
#: Repeats are cheap only for the SINDy models.
CHEAP = {"sindy-linear", "sindy-nonlinear"}


def make_logs(root: Path, rows: int, seed: int) -> tuple[list[Path], float]:
    from cosim_plugins.identify import synthetic as syn
    from cosim_plugins.models.physical import synthetic_plant

    out = root / f"rows{rows}_seed{seed}"
    files = sorted(out.glob("*.csv"))
    if len(files) == 12:
        return files, 0.0
    t0 = time.perf_counter()
    files = syn.write_cases(out, synthetic_plant().predict, rows, seed=seed, bias_hz=(0.0, 0.0, 2.4))
    return files, time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=14500)
    ap.add_argument("--repeats", type=int, default=3, help="repeats for the cheap (SINDy) fits; median reported")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cache", default="cache/bench_fit")
    args = ap.parse_args(argv)

    import pysindy  # noqa: F401  (imports excluded from the timings)
    import torch  # noqa: F401

    from cosim_plugins.identify.dataset import Dataset
    from cosim_plugins.identify.fit import make_model

    files, gen_s = make_logs(Path(args.cache), args.rows, args.seed)
    t0 = time.perf_counter()
    ds = Dataset.from_paths(files)
    read_s = time.perf_counter() - t0
    result = {"samples": sum(lg.n for lg in ds.logs), "files": len(files), "pairs": int(len(ds.pair_index())),
              "generate_s": round(gen_s, 2), "read_s": round(read_s, 3), "models": {}}
    for name, budget in BUDGETS_S.items():
        runs = []
        for _ in range(args.repeats if name in CHEAP else 1):
            model = make_model(name, seed=args.seed)
            t = time.perf_counter()
            model.fit(ds)
            runs.append(time.perf_counter() - t)
        med = statistics.median(runs)
        result["models"][name] = {"train_time_s": round(med, 3), "runs_s": [round(r, 3) for r in runs],
                                  "budget_s": budget, "ok": med <= budget, "n_params": model.n_params}
        print(f"{name}: {med:.2f} s (budget {budget:g} s)", file=sys.stderr, flush=True)
    total = sum(m["train_time_s"] for m in result["models"].values())
    result["total_train_s"] = round(total, 2)
    result["total_budget_s"] = TOTAL_BUDGET_S
    result["ok"] = total <= TOTAL_BUDGET_S and all(m["ok"] for m in result["models"].values())
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

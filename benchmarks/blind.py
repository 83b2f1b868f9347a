"""Blind bench of `cosim diagnose`: logs from an independent simulator, one hidden effect each; prints JSON.

The logs come from ``benchmarks/blind_sim.py`` (its own equations, no code
shared with ``cosim``): cases drawn at random (seeded) over wide regimes,
each with one hidden library effect, none (false-alarm cases) or one outside
the library. Every case is diagnosed blind, as a user would
(``cosim diagnose LOGS --discover``: every library effect ranked, the
discovery run), then refitted with the true form (the simulator's own law as
an effect file, started at the truth: the reduction a perfect diagnosis
would reach). Per case one JSON line is appended to ``OUT/cases.jsonl`` as
it finishes; at the end one JSON object is printed:

* ``library``: ``cases``; ``top1`` (fraction whose top-ranked candidate is
  the hidden effect), ``named`` (the verdict names it), the same over the
  ``detectable`` cases (the true form lowers the held-out error by >= 10 %);
  ``top1_or_tied_detectable`` also counts a detectable case whose hidden effect
  ranks second within paired t < 3 of the first (the verdict then says the logs
  cannot tell the two apart);
  ``median_reduction_ratio`` (achieved / true-form reduction, achieved = the
  top-ranked candidate's reduction);
* ``no_effect``: ``cases``, ``false_alarms`` (an effect named), and
  ``discovered_alarms`` (a discovered form lowering the error by >= 10 %, t >= 3);
* ``outside``: ``cases``, ``discovered_ok`` (fraction whose discovered effect
  reaches >= 50 % of the true form's reduction), over the outside cases with
  a true form (a time-periodic force has none: no force in p, v, u can
  express it; those are counted under ``time_varying``);
* ``seconds_per_case`` (median wall time of the diagnosis and the true-form refit).

    .venv/bin/python benchmarks/blind.py [--cases 60] [--seed 0] [--jobs 2] [--out runs/blind]
    .venv/bin/python benchmarks/blind.py --write-case outside:rotating_flow [--seed 3] --out DIR

``--summarise OUT/cases.jsonl`` prints the figures of the cases recorded so
far (a bench stopped midway keeps every finished case); ``--resume`` goes on
with such a bench: the finished cases of ``OUT/cases.jsonl`` are kept and
only the others are diagnosed (same ``--cases`` and ``--seed``).
``--write-case GROUP[:EFFECT]`` only simulates one case into ``DIR/logs`` (and
its true form into ``DIR/true_form.py``, its truth into ``DIR/case.json``):
logs to try ``cosim diagnose`` on by hand.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core per case: set before numpy loads (children fork)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor, as_completed  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

import blind_sim  # noqa: E402  (the independent simulator beside this file)

DETECTABLE = 0.10  # a true-form reduction below this: the effect is invisible in these logs
MIN_T = 3.0  # the verdict's paired t below which two effects are not told apart
GOOD_SHARE = 0.5  # discovered_ok: the discovered form reaches this share of the true form's reduction


def run_case(case: blind_sim.Case, out: Path) -> dict:
    """Simulate, diagnose blind, refit with the true form; one JSON-able record."""
    from cosim.contract import plugins
    from cosim_plugins.identify.diagnose import Settings, run

    folder = out / f"case_{case.index:03d}"
    logs = blind_sim.simulate(case, folder / "logs")
    t0 = time.perf_counter()
    plugins.reset()
    diag = run(logs, settings=Settings(discover=True)).result
    key = next(k for k, v in diag["horizons_s"].items() if v == diag["reference_horizon_s"])
    ranked = [e for e in diag["ranking"] if e.get("identifiable", True)]
    top = ranked[0] if ranked else None
    found = diag.get("discovered") or {}
    record = {
        "index": case.index, "seed": case.seed, "group": case.group, "effect": case.effect, "law": case.law,
        "truth": case.truth, "regime": case.regime,
        "baseline_mm": diag["baseline"]["rollout_mm"][key], "floor_mm": diag["noise_floor_mm"],
        "top": top["effect"] if top else None, "top_reduction": top["reduction"] if top else 0.0,
        "top_t": top["t_stat"] if top else 0.0, "runner_up": (top or {}).get("runner_up"),
        "named": diag["verdict"]["effect"],
        "status": diag["verdict"]["status"], "fit_notes": diag.get("fit_notes", []),
        "ranking": [[e["effect"], round(e["reduction"], 4)] for e in diag["ranking"]],
        "discovered": {k: found.get(k) for k in ("status", "reduction", "t_stat", "terms", "words")},
        "true_reduction": None,
    }
    if case.true_form:
        form = folder / "true_form.py"
        form.write_text(case.true_form)
        plugins.reset()
        true = run(logs, settings=Settings(effects_files=[str(form)], add=[case.true_form_name],
                                           candidates=[])).result
        record["true_reduction"] = true["added"]["reduction"][key]
        record["true_params"] = {k: v["value"] for k, v in true["added"]["params"].items()}
    plugins.reset()
    record["seconds"] = round(time.perf_counter() - t0, 1)
    return record


def _worker(args) -> dict:
    case, out = args
    try:
        return run_case(case, Path(out))
    except Exception as exc:  # one failed case is one failed row, never the whole bench
        return {"index": case.index, "group": case.group, "effect": case.effect,
                "error": f"{type(exc).__name__}: {exc}"}


def summarise(records: list[dict]) -> dict:
    """The bench's figures from the per-case records (see the module docstring)."""
    import numpy as np

    ok = [r for r in records if "error" not in r]
    lib = [r for r in ok if r["group"] == "library"]
    det = [r for r in lib if (r["true_reduction"] or 0.0) >= DETECTABLE]
    none = [r for r in ok if r["group"] == "none"]
    out = [r for r in ok if r["group"] == "outside"]
    out_form = [r for r in out if r["true_reduction"] is not None]

    def frac(rows, pred):
        return round(sum(1 for r in rows if pred(r)) / len(rows), 3) if rows else None

    def top_or_tied(r):  # the truth first, or ranked second and not told apart from the first (the verdict says so)
        rival = r.get("runner_up") or {}
        return (r["top"] == r["effect"] or rival.get("effect") == r["effect"] and rival.get("t_stat", MIN_T) < MIN_T
                and (rival.get("reduction") or 0.0) >= DETECTABLE)

    def ratio(r):
        return r["top_reduction"] / r["true_reduction"] if r["top"] == r["effect"] else 0.0

    def disc_ok(r):
        d = r["discovered"]
        return d["status"] == "found" and (d["reduction"] or 0.0) >= GOOD_SHARE * r["true_reduction"]

    def disc_alarm(r):
        d = r["discovered"]
        return d["status"] == "found" and (d["reduction"] or 0.0) >= DETECTABLE and (d["t_stat"] or 0.0) >= 3.0

    by_effect = {}
    for r in lib:
        e = by_effect.setdefault(r["effect"], {"cases": 0, "top1": 0, "detectable": 0})
        e["cases"] += 1
        e["top1"] += int(r["top"] == r["effect"])
        e["detectable"] += int(r in det)
    return {
        "cases": len(records), "failed": len(records) - len(ok),
        "library": {"cases": len(lib), "top1": frac(lib, lambda r: r["top"] == r["effect"]),
                    "named": frac(lib, lambda r: r["named"] == r["effect"]),
                    "detectable": len(det), "top1_detectable": frac(det, lambda r: r["top"] == r["effect"]),
                    "named_detectable": frac(det, lambda r: r["named"] == r["effect"]),
                    "top1_or_tied_detectable": frac(det, top_or_tied),
                    "median_reduction_ratio": round(float(np.median([ratio(r) for r in det])), 3) if det else None,
                    "by_effect": by_effect},
        "no_effect": {"cases": len(none), "false_alarms": sum(1 for r in none if r["named"]),
                      "discovered_alarms": sum(1 for r in none if disc_alarm(r))},
        "outside": {"cases": len(out_form), "discovered_ok": frac(out_form, disc_ok),
                    "time_varying": len(out) - len(out_form),
                    "time_varying_named": sum(1 for r in out if r["true_reduction"] is None and r["named"])},
        "seconds_per_case": round(float(np.median([r["seconds"] for r in ok])), 1) if ok else None,
    }


def _finished(lines: Path, cases: list) -> list[dict]:
    """The error-free records of an earlier run's ``cases.jsonl`` that match this draw."""
    if not lines.is_file():
        return []
    drawn = {c.index: c for c in cases}
    kept = []
    for n, line in enumerate(lines.read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            print(f"{lines}:{n}: not a JSON line (a cut write?): diagnosed again", file=sys.stderr)
            continue
        case = drawn.get(rec.get("index"))
        same = case is not None and (case.group, case.effect, case.seed) == (
            rec.get("group"), rec.get("effect"), rec.get("seed", case.seed))
        if not same:
            raise SystemExit(f"--resume: {lines}:{n} is case {rec.get('index')} {rec.get('group')} "
                             f"{rec.get('effect')}, not in this draw (other --cases/--seed?)")
        if "error" not in rec:
            kept.append(rec)
    return kept


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=60, help="number of cases (default 60)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the case draw (default 0)")
    ap.add_argument("--jobs", type=int, default=2, help="cases diagnosed at once (default 2)")
    ap.add_argument("--out", default=str(ROOT / "runs" / "blind"), help="folder for logs and cases.jsonl")
    ap.add_argument("--only", choices=("library", "none", "outside"),
                    help="run only the drawn cases of this group (the same cases as in the full draw)")
    ap.add_argument("--resume", action="store_true",
                    help="keep the finished cases of OUT/cases.jsonl and diagnose only the others")
    ap.add_argument("--summarise", metavar="CASES.jsonl|OUT",
                    help="only print the figures of a (possibly unfinished) run's cases.jsonl")
    ap.add_argument("--write-case", metavar="GROUP[:EFFECT]",
                    help="only simulate one case (library|none|outside, e.g. outside:rotating_flow) into --out")
    args = ap.parse_args(argv)
    if args.cases < 1 or args.jobs < 1:
        ap.error("--cases and --jobs must be at least 1")
    if args.summarise:
        path = Path(args.summarise)
        path = path / "cases.jsonl" if path.is_dir() else path
        if not path.is_file():
            ap.error(f"--summarise {args.summarise}: no such file (a bench's --out folder or its cases.jsonl)")
        rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
        print(json.dumps(summarise(sorted(rows, key=lambda r: r["index"])), indent=2))
        return 0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.write_case:
        group, _, effect = args.write_case.partition(":")
        try:
            case = blind_sim.draw_case(args.seed, group, effect or None)
        except ValueError as exc:
            ap.error(f"--write-case {args.write_case}: {exc}")
        logs = blind_sim.simulate(case, out / "logs")
        if case.true_form:
            (out / "true_form.py").write_text(case.true_form)
        (out / "case.json").write_text(json.dumps({"group": case.group, "effect": case.effect, "law": case.law,
                                                   "truth": case.truth, "regime": case.regime}, indent=2) + "\n")
        print(f"wrote {len(logs)} logs to {out / 'logs'} ({case.group} {case.effect or ''} {case.truth})")
        return 0
    cases = [c for c in blind_sim.draw_cases(args.cases, args.seed) if args.only in (None, c.group)]
    lines = out / "cases.jsonl"
    records = _finished(lines, cases) if args.resume else []
    lines.write_text("".join(json.dumps(r) + "\n" for r in records))
    kept = {r["index"] for r in records}
    todo = [c for c in cases if c.index not in kept]
    if records:
        print(f"resuming: {len(records)} finished cases kept, {len(todo)} to go", file=sys.stderr, flush=True)
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(_worker, (c, str(out))) for c in todo]
        for done, fut in enumerate(as_completed(futures), len(records) + 1):
            rec = fut.result()
            records.append(rec)
            with open(lines, "a") as fh:
                fh.write(json.dumps(rec) + "\n")
            what = rec.get("error") or f"top {rec['top']} ({rec['top_reduction']:+.0%}), true {rec['true_reduction']}"
            print(f"[{done}/{len(cases)}] case {rec['index']} {rec['group']} {rec['effect']}: {what}",
                  file=sys.stderr, flush=True)
    records.sort(key=lambda r: r["index"])
    print(json.dumps(summarise(records), indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

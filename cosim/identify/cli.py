"""``cosim fit`` and ``cosim compare``.

    cosim fit LOG... [--model all|NAME[,NAME...]] --out DIR [--seed N]
    cosim compare LOG... --models DIR --json OUT [--plots DIR] [--split train|test|validation]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def add_commands(subparsers) -> None:
    p = subparsers.add_parser("fit", help="train dynamics models from raw logs (Table II analog)",
                              description="Fit models to raw logs and write DIR/NAME.npz and DIR/fit.json.")
    p.add_argument("logs", nargs="+", metavar="LOG", help="raw log CSV files")
    p.add_argument("--model", default="all",
                   help="'all' (default), a model name, or a comma-separated list "
                        "(built-in: physical, sindy-linear, sindy-nonlinear, mlp)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.set_defaults(func=cmd_fit)

    c = subparsers.add_parser("compare", help="prediction errors of fitted models on raw logs (Table III analog)",
                              description="One-step and 0.1/0.42/1.0 s open-loop rollout errors per model.")
    c.add_argument("logs", nargs="+", metavar="LOG", help="raw log CSV files")
    c.add_argument("--models", required=True, metavar="DIR", help="directory written by `cosim fit`")
    c.add_argument("--json", required=True, metavar="OUT", help="write the results here (JSON)")
    c.add_argument("--plots", metavar="DIR", help="write PNG plots and compare.rrd here")
    c.add_argument("--split", choices=("train", "test", "validation"), help="label for these logs in the output")
    c.set_defaults(func=cmd_compare)


def _progress(message: str) -> None:
    print(f"  .. {message}", file=sys.stderr, flush=True)


def _quality_table(dataset) -> str:
    lines = [f"{'log':<40} {'rows':>7} {'gaps':>6} {'outliers':>8} {'repeats':>7} {'duration_s':>10}"]
    for q in dataset.quality():
        name = Path(q["file"]).name
        lines.append(f"{name:<40} {q['rows']:>7} {q['gaps']:>6} {q['outliers']:>8} {q['repeats']:>7} "
                     f"{q['duration_s']:>10.2f}")
    return "\n".join(lines)


def cmd_fit(args) -> int:
    from cosim.identify.dataset import Dataset
    from cosim.identify.fit import fit_models, resolve_names, save_models, summarise

    names = resolve_names(args.model)
    dataset = Dataset.from_paths(args.logs)
    print("data quality:")
    print(_quality_table(dataset))
    print(f"{len(dataset.pair_index())} one-step pairs at dt = {dataset.dt_s * 1e3:g} ms")
    models = fit_models(dataset, names, seed=args.seed, progress=_progress)
    summary = summarise(models, dataset, seed=args.seed)
    path = save_models(models, summary, args.out)
    print(f"\n{'model':<16} {'train_time_s':>12} {'n_params':>9}  params")
    for name, s in summary["models"].items():
        params = ", ".join(f"{k}={_short(v)}" for k, v in s["params"].items())
        print(f"{name:<16} {s['train_time_s']:>12.3f} {s['n_params']:>9}  {params}")
    print(f"wrote {path}")
    return 0


def cmd_compare(args) -> int:
    from cosim.identify.compare import compare, format_table
    from cosim.identify.dataset import Dataset
    from cosim.identify.fit import load_models

    models = load_models(args.models)
    dataset = Dataset.from_paths(args.logs)
    print("data quality:")
    print(_quality_table(dataset))
    result = compare(models, dataset, progress=_progress)
    result["split"] = args.split
    result["logs"] = [str(p) for p in args.logs]
    print(f"\nsplit: {args.split}" if args.split else "")
    print(format_table(result))
    out = Path(args.json)
    if out.parent and not out.parent.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {out}")
    if args.plots:
        from cosim.identify.plots import write_plots

        files = write_plots(models, dataset, result, args.plots)
        print(f"wrote {len(files)} plot files to {args.plots}")
    return 0


def _short(v) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)

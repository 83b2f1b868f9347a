"""``cosim fit``, ``cosim convert`` and ``cosim compare``.

    cosim fit LOG... [--model all|NAME[,NAME...]] [--effects NAME,...] [--effects-file FILE.py]... --out DIR
    cosim convert --commands CMD.csv --positions POS.csv [--dt S] [--unit mm|m|px] --out LOG.csv
    cosim compare LOG... --models DIR --json OUT [--plots DIR] [--split train|test|validation]
"""

from __future__ import annotations

import json
from pathlib import Path

from cosim.contract.errors import UserError
from cosim_plugins.commands import progress


def add_commands(subparsers) -> None:
    """Add ``cosim fit``, ``convert`` and ``compare`` to the ``cosim`` parser's ``subparsers``."""
    p = subparsers.add_parser("fit", help="train dynamics models from raw logs (Table II analog)",
                              description="Fit models to raw logs and write DIR/NAME.npz and DIR/fit.json.")
    p.add_argument("logs", nargs="+", metavar="LOG", help="raw log CSV files")
    p.add_argument("--model", default="all",
                   help="'all' (default), a model name, or a comma-separated list "
                        "(built-in: physical, sindy-linear, sindy-nonlinear, mlp)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--effects", metavar="NAME[,NAME...]",
                   help="force effects the physical model includes, fitted jointly with it (see `cosim plugins`)")
    p.add_argument("--effects-file", action="append", default=[], metavar="FILE.py",
                   help="a Python file registering effects (e.g. diagnose's discovered_effect.py); repeatable")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.set_defaults(func=cmd_fit)

    v = subparsers.add_parser("convert", help="a lab's command and detection recordings into a raw log",
                              description="Put a command log (t_s or t_ms, then omega_x,omega_y,omega_z [rad/s] or "
                                          "axis_x,axis_y,axis_z,freq_hz) and a detection log (t_s or t_ms, x,y,z) "
                                          "on one control grid: the command held, the nearest detection within "
                                          "half a period (else empty).")
    v.add_argument("--commands", required=True, type=Path, metavar="CMD.csv", help="the commands with their times")
    v.add_argument("--positions", required=True, type=Path, metavar="POS.csv",
                   help="the detections with their capture times (missing frames: rows left out or empty x,y,z)")
    v.add_argument("--dt", type=float, default=0.02, help="control period of the raw log [s] (default 0.02)")
    v.add_argument("--unit", default="mm", choices=("mm", "m", "px"), help="unit of x,y,z (default mm)")
    v.add_argument("--pixel-mm", type=float, help="with --unit px: one pixel's size in the tank [mm]")
    v.add_argument("--out", required=True, type=Path, metavar="LOG.csv", help="the raw log to write")
    v.set_defaults(func=cmd_convert)

    c = subparsers.add_parser("compare", help="prediction errors of fitted models on raw logs (Table III analog)",
                              description="One-step and 0.1/0.42/1.0 s open-loop rollout errors per model.")
    c.add_argument("logs", nargs="+", metavar="LOG", help="raw log CSV files")
    c.add_argument("--models", required=True, metavar="DIR", help="directory written by `cosim fit`")
    c.add_argument("--json", required=True, metavar="OUT", help="write the results here (JSON)")
    c.add_argument("--plots", metavar="DIR", help="write PNG plots and compare.rrd here")
    c.add_argument("--split", choices=("train", "test", "validation"), help="label for these logs in the output")
    c.add_argument("--effects-file", action="append", default=[], metavar="FILE.py",
                   help="a Python file registering effects the models use; repeatable")
    c.set_defaults(func=cmd_compare)


def _quality_table(dataset) -> str:
    from cosim_plugins.identify.dataset import log_label

    lines = [f"{'log':<40} {'rows':>7} {'gaps':>6} {'outliers':>8} {'repeats':>7} {'duration_s':>10}"]
    for q in dataset.quality():
        lines.append(f"{log_label(q['file']):<40} {q['rows']:>7} {q['gaps']:>6} {q['outliers']:>8} {q['repeats']:>7} "
                     f"{q['duration_s']:>10.2f}")
    lines.append("(gaps: rows with no position (no frame); outliers: positions that jump away from their neighbours "
                 "(reflections), dropped; repeats: a position repeated exactly from the row before (a camera that "
                 "held its last detection), dropped)")
    return "\n".join(lines)


def cmd_fit(args) -> int:
    """``cosim fit``: train models on raw logs; writes ``DIR/NAME.npz`` and ``DIR/fit.json``."""
    from cosim_plugins.identify.dataset import Dataset
    from cosim_plugins.identify.fit import fit_models, resolve_names, save_models, summarise

    names = resolve_names(args.model)
    effects = _fit_effects(args, names)
    dataset = Dataset.from_paths(args.logs)
    print("data quality:")
    print(_quality_table(dataset))
    print(f"{len(dataset.pair_index())} one-step pairs at dt = {dataset.dt_s * 1e3:g} ms")
    models = fit_models(dataset, names, seed=args.seed, progress=progress, effects=effects)
    summary = summarise(models, dataset, seed=args.seed)
    path = save_models(models, summary, args.out)
    print(f"\n{'model':<16} {'train_time_s':>12} {'n_params':>9}  params")
    for name, s in summary["models"].items():
        params = ", ".join(f"{k}={_short(v)}" for k, v in s["params"].items())
        print(f"{name:<16} {s['train_time_s']:>12.3f} {s['n_params']:>9}  {params}")
    print(f"wrote {path}")
    return 0


def _fit_effects(args, names) -> list:
    """The force effects of ``cosim fit --effects``, checked against the chosen models."""
    from cosim_plugins.identify.effect import load_effect_files, resolve
    from cosim_plugins.identify.fit import takes_effects

    load_effect_files(args.effects_file)
    if not args.effects:
        return []
    effects = resolve([n.strip() for n in args.effects.split(",") if n.strip()])
    other = [f"{e.name} ({e.kind})" for e in effects if e.kind != "force"]
    if other:
        raise UserError(f"--effects {', '.join(other)}: only force effects become part of a fitted model")
    hosts = [n for n in names if takes_effects(n)]
    if not hosts:
        raise UserError(f"--effects: none of the models {', '.join(names)} can include effects (physical can)")
    skipped = [n for n in names if n not in hosts]
    if skipped:
        print(f"note: {', '.join(e.name for e in effects)} added to {', '.join(hosts)} only; "
              f"{', '.join(skipped)} cannot include effects")
    return effects


def cmd_convert(args) -> int:
    """``cosim convert``: a rig's command and detection recordings as one raw log."""
    from cosim_plugins.identify.convert import convert

    got = convert(args.commands, args.positions, args.out, args.dt, args.unit, args.pixel_mm)
    print(f"wrote {args.out}: {got['rows']} rows of {args.dt * 1e3:g} ms ({got['duration_s']:.1f} s), "
          f"{got['measured']} with a position from {got['detections']} detections"
          + (f"; {got['outside']} detections lie outside the commands' time span and were left out"
             if got["outside"] else ""))
    return 0


def cmd_compare(args) -> int:
    """``cosim compare``: per-model one-step and open-loop errors against the measurements."""
    from cosim_plugins.identify.compare import compare, format_table
    from cosim_plugins.identify.dataset import Dataset
    from cosim_plugins.identify.effect import load_effect_files
    from cosim_plugins.identify.fit import load_models

    load_effect_files(args.effects_file)
    models = load_models(args.models)
    dataset = Dataset.from_paths(args.logs)
    print("data quality:")
    print(_quality_table(dataset))
    result = compare(models, dataset, progress=progress)
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
        from cosim_plugins.identify.plots import write_plots

        files = write_plots(models, dataset, result, args.plots)
        print(f"wrote {len(files)} plot files to {args.plots}")
    return 0


def _short(v) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)

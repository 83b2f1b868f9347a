"""``cosim fit``, ``cosim convert``, ``cosim compare`` and ``cosim diagnose``.

    cosim fit LOG... [--model all|NAME[,NAME...]] [--effects NAME,...] [--effects-file FILE.py]... --out DIR
    cosim convert --commands CMD.csv --positions POS.csv [--dt S] [--unit mm|m|px] --out LOG.csv
    cosim compare LOG... --models DIR --json OUT [--plots DIR] [--split train|test|validation]
    cosim diagnose LOG... [--validate LOG...] [--model physical] [--effects-file FILE.py]...
                   [--add EFFECT]... [--save-model PATH.npz] [--effects NAME,...] [--reference S] --out DIR
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from cosim.contract.errors import UserError


def add_commands(subparsers) -> None:
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

    d = subparsers.add_parser(
        "diagnose", help="find where a model fails and which physical effect explains it",
        description="Fit the baseline model, measure its open-loop error against the noise floor, localise it, "
                    "and rank candidate effects by the drop of held-out error after a joint refit. Writes "
                    "DIR/diagnosis.json, DIR/report.md (+ PNG plots) and DIR/diagnosis.rrd.")
    d.add_argument("logs", nargs="+", metavar="LOG", help="raw log CSV files")
    d.add_argument("--validate", nargs="+", default=[], metavar="LOG",
                   help="held-out logs (default: every third 5 s block of the given logs)")
    d.add_argument("--model", default="physical", help="baseline model (any registered model; default physical)")
    d.add_argument("--effects-file", action="append", default=[], metavar="FILE.py",
                   help="a Python file registering effects (cosim_register_effects hook); repeatable")
    d.add_argument("--add", action="append", default=[], metavar="EFFECT",
                   help="refit with this effect and show the error before and after; repeatable")
    d.add_argument("--effects", metavar="NAME[,NAME...]",
                   help="candidate effects to rank (default: every registered effect)")
    d.add_argument("--reference", default="1.0", help="reference horizon for the ranking [s] (default 1.0)")
    d.add_argument("--discover", action="store_true",
                   help="also fit a sparse combination of candidate force terms to the error left (done anyway "
                        "when no listed effect explains it); writes DIR/discovered_effect.py")
    d.add_argument("--save-model", metavar="PATH.npz",
                   help="with --add: save the model with the added effects (refitted) as a model file the "
                        "Kalman filter and the MPC load (components.estimator.params.model=PATH.npz)")
    d.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    d.add_argument("--out", required=True, metavar="DIR", help="output directory")
    d.set_defaults(func=cmd_diagnose)


def _progress(message: str) -> None:
    print(f"  .. {message}", file=sys.stderr, flush=True)


def _quality_table(dataset) -> str:
    from cosim_plugins.identify.report import log_label

    lines = [f"{'log':<40} {'rows':>7} {'gaps':>6} {'outliers':>8} {'repeats':>7} {'duration_s':>10}"]
    for q in dataset.quality():
        lines.append(f"{log_label(q['file']):<40} {q['rows']:>7} {q['gaps']:>6} {q['outliers']:>8} {q['repeats']:>7} "
                     f"{q['duration_s']:>10.2f}")
    lines.append("(gaps: rows with no position (no frame); outliers: positions that jump away from their neighbours "
                 "(reflections), dropped; repeats: a position repeated exactly from the row before (a camera that "
                 "held its last detection), dropped)")
    return "\n".join(lines)


def cmd_fit(args) -> int:
    from cosim_plugins.identify.dataset import Dataset
    from cosim_plugins.identify.fit import fit_models, resolve_names, save_models, summarise

    names = resolve_names(args.model)
    effects = _fit_effects(args, names)
    dataset = Dataset.from_paths(args.logs)
    print("data quality:")
    print(_quality_table(dataset))
    print(f"{len(dataset.pair_index())} one-step pairs at dt = {dataset.dt_s * 1e3:g} ms")
    models = fit_models(dataset, names, seed=args.seed, progress=_progress, effects=effects)
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
    from cosim_plugins.identify.convert import convert

    got = convert(args.commands, args.positions, args.out, args.dt, args.unit, args.pixel_mm)
    print(f"wrote {args.out}: {got['rows']} rows of {args.dt * 1e3:g} ms ({got['duration_s']:.1f} s), "
          f"{got['measured']} with a position from {got['detections']} detections"
          + (f"; {got['outside']} detections lie outside the commands' time span and were left out"
             if got["outside"] else ""))
    return 0


def cmd_compare(args) -> int:
    from cosim_plugins.identify.compare import compare, format_table
    from cosim_plugins.identify.dataset import Dataset
    from cosim_plugins.identify.effect import load_effect_files
    from cosim_plugins.identify.fit import load_models

    load_effect_files(args.effects_file)
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
        from cosim_plugins.identify.plots import write_plots

        files = write_plots(models, dataset, result, args.plots)
        print(f"wrote {len(files)} plot files to {args.plots}")
    return 0


def cmd_diagnose(args) -> int:
    from cosim_plugins.identify.diagnose import Settings, run
    from cosim_plugins.identify.report import write_outputs

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a directory")
    candidates = None
    if args.effects is not None:
        candidates = [n.strip() for n in args.effects.split(",") if n.strip() and n.strip() != "none"]
    if args.save_model and not args.add:
        raise UserError("--save-model saves the model with the effects of --add: name at least one (--add EFFECT)")
    settings = Settings(model=args.model, effects_files=args.effects_file, add=args.add, candidates=candidates,
                        reference=args.reference, seed=args.seed, discover=args.discover)
    diag = run(args.logs, args.validate, settings, progress=_progress)
    saved = save_model(diag.added_model.savable(), args.save_model) if args.save_model else None
    files = write_outputs(diag, out)
    print(format_diagnosis(diag.result))
    print(f"wrote {len(files)} files to {out} (report.md, diagnosis.json, diagnosis.rrd)")
    if saved:
        print(f"wrote the model with {' + '.join(args.add)} to {saved}; use it in a scenario with "
              f"--set components.estimator.params.model={saved} (the Kalman filter) or "
              f"components.controller.params.model={saved} (the MPC)")
    return 0


def save_model(model, path) -> Path:
    """Write ``model`` to ``path`` (.npz, parent folders made); a path that is a folder is an error."""
    path = Path(path)
    if path.suffix != ".npz":
        raise UserError(f"model file {path}: the name must end in .npz")
    if path.is_dir():
        raise UserError(f"model file {path} is a directory")
    path.parent.mkdir(parents=True, exist_ok=True)
    return model.save(path)


def format_diagnosis(r: dict) -> str:
    """Printable summary of a diagnosis: errors by horizon, ranking, what the figures mean, verdict."""
    from cosim_plugins.identify.wording import legend

    hs = list(r["horizons_s"])
    key = next(k for k, v in r["horizons_s"].items() if v == r["reference_horizon_s"])
    lines = [f"{'held-out error [mm]':<28}" + "".join(f"{h + ' s':>9}" for h in hs),
             f"{r['baseline']['model'] + ' (baseline)':<28}" + "".join(f"{_num(r['baseline']['rollout_mm'][h]):>9}"
                                                                      for h in hs)]
    if r["added"]:
        a = r["added"]
        lines.append(f"{'+ ' + ' + '.join(a['effects']):<28}" + "".join(f"{_num(a['rollout_mm'][h]):>9}" for h in hs))
    elif r["reference"]:
        ref = r["reference"]
        lines.append(f"{ref['model'] + ' (effects ref.)':<28}"
                     + "".join(f"{_num(ref['rollout_mm'][h]):>9}" for h in hs))
    lines.append(f"{'noise floor':<28}" + "".join(f"{_num(r['noise']['floor_mm'][h]):>9}" for h in hs))
    lines += ["", f"{'rank':<5}{'effect':<20}{'error ' + key + ' s':>12}{'reduction':>11}{'t':>7}"]
    for i, e in enumerate(r["ranking"], 1):
        if not e.get("identifiable", True):
            lines.append(f"{'-':<5}{e['effect']:<20}{'not identifiable from these logs':>30}")
            continue
        lines.append(f"{i:<5}{e['effect']:<20}{_num(e['rollout_mm'][key]):>12}{e['reduction']:>+11.1%}"
                     f"{e['t_stat']:>7.1f}")
    found = r.get("discovered")
    if found and found["status"] == "found":
        lines.append(f"{'+':<5}{'discovered':<20}{_num(found['rollout_mm'][key]):>12}{found['reduction']:>+11.1%}"
                     f"{found['t_stat']:>7.1f}   ({len(found['terms'])} terms, {found['file']})")
    for note in r.get("fit_notes", ()):
        lines.append(f"note: {note}")
    lines += [""] + [f"  {line}" for line in legend()]
    lines += ["", "verdict: " + r["verdict"]["explanation"]]
    return "\n".join(lines)


def _num(v) -> str:
    return "-" if v is None else f"{v:.3f}"


def _short(v) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)

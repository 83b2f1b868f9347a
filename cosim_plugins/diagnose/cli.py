"""``cosim diagnose``: where a model fails and which physical effects explain it.

    cosim diagnose LOG... [--validate LOG...] [--model physical] [--effects-file FILE.py]...
                   [--add EFFECT]... [--save-model PATH.npz] [--effects NAME,...] [--reference S]
                   [--per-log PARAM,...] [--t-start S,...] [--no-drift] [--jobs N] --out DIR
"""

from __future__ import annotations

import os
from pathlib import Path

from cosim.contract.errors import UserError
from cosim_plugins.commands import output_folder, progress
from cosim_plugins.diagnose.stepwise import MAX_EFFECTS


def add_commands(subparsers) -> None:
    """Register ``cosim diagnose``."""
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
    d.add_argument("--max-effects", type=int, default=MAX_EFFECTS, metavar="N",
                   help=f"effects the stepwise search may name, one per round (default {MAX_EFFECTS})")
    d.add_argument("--discover", action="store_true",
                   help="also fit a sparse combination of candidate force terms to the error left (done anyway "
                        "when no listed effect explains it); writes DIR/discovered_effect.py")
    d.add_argument("--per-log", metavar="PARAM[,PARAM...]",
                   help="fit these base parameters of the model free per log, the rest shared, and rank the fit "
                        "like an effect by its held-out drop (default drift test: k,Cd1,Fvs)")
    d.add_argument("--t-start", metavar="S[,S...]",
                   help="each log's start time [s], in the order of LOG... (the drift's order; default: the "
                        "order the logs are given in)")
    d.add_argument("--no-drift", action="store_true",
                   help="skip the test for drift between and within the logs")
    d.add_argument("--save-model", metavar="PATH.npz",
                   help="with --add: save the model with the added effects (refitted) as a model file the "
                        "Kalman filter and the MPC load (components.estimator.params.model=PATH.npz)")
    d.add_argument("--jobs", type=int, default=min(4, os.cpu_count() or 1), metavar="N",
                   help="processes the candidates' fits are spread over (default: the CPUs, at most 4); the "
                        "figures are the same for any N")
    d.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    d.add_argument("--out", required=True, metavar="DIR", help="output directory")
    d.set_defaults(func=cmd_diagnose)


def cmd_diagnose(args) -> int:
    """``cosim diagnose``: which physical effects the model misses; writes the report folder."""
    from cosim_plugins.diagnose.pipeline import Settings, run
    from cosim_plugins.diagnose.render import terminal
    from cosim_plugins.diagnose.report import write_outputs

    out = output_folder(args.out)
    candidates = None
    if args.effects is not None:
        candidates = [n.strip() for n in args.effects.split(",") if n.strip() and n.strip() != "none"]
    if args.save_model and not args.add:
        raise UserError("--save-model saves the model with the effects of --add: name at least one (--add EFFECT)")
    if args.jobs < 1:
        raise UserError(f"--jobs {args.jobs}: give at least 1")
    per_log = [n.strip() for n in args.per_log.split(",") if n.strip()] if args.per_log else None
    if args.no_drift and (per_log or args.t_start):
        raise UserError("--no-drift skips the drift test that --per-log and --t-start configure: give one or the "
                        "other")
    settings = Settings(model=args.model, effects_files=args.effects_file, add=args.add, candidates=candidates,
                        reference=args.reference, seed=args.seed, discover=args.discover,
                        max_effects=args.max_effects, jobs=args.jobs, drift=not args.no_drift, per_log=per_log,
                        t_start=_t_start(args.t_start, len(args.logs)))
    diag = run(args.logs, args.validate, settings, progress=progress)
    saved = save_model(diag.added_model.savable(), args.save_model) if args.save_model else None
    files = write_outputs(diag, out, settings.jobs)
    print(terminal(diag.result))
    print(f"wrote {len(files)} files to {out} (report.md, diagnosis.json, diagnosis.rrd"
          + (", experiment.yaml, experiment_excitation.csv" if diag.experiment is not None else "") + ")")
    if saved:
        print(f"wrote the model with {' + '.join(args.add)} to {saved}; use it in a scenario with "
              f"--set components.estimator.params.model={saved} (the Kalman filter) or "
              f"components.controller.params.model={saved} (the MPC)")
    return 0


def _t_start(text: str | None, n_logs: int) -> list | None:
    """--t-start's start times [s], one per log, or a UserError naming what is wrong."""
    if text is None:
        return None
    try:
        times = [float(x) for x in text.split(",")]
    except ValueError:
        raise UserError(f"--t-start {text}: give one start time in seconds per log, separated by commas") from None
    if len(times) != n_logs:
        raise UserError(f"--t-start gives {len(times)} start times for {n_logs} logs: give one per LOG, in order")
    return times


def save_model(model, path) -> Path:
    """Write ``model`` to ``path`` (.npz, parent folders made); a path that is a folder is an error."""
    path = Path(path)
    if path.suffix != ".npz":
        raise UserError(f"model file {path}: the name must end in .npz")
    if path.is_dir():
        raise UserError(f"model file {path} is a directory")
    path.parent.mkdir(parents=True, exist_ok=True)
    return model.save(path)

"""``cosim twin calibrate``: calibrate the plant FMU to a lab's logs (see :mod:`.calibrate`).

    cosim twin calibrate LOG... [--validate LOG...] [--effects NAME,...|--model M.npz]
                         [--scenario LAB.yaml] [--jobs N] [--seed S] --out DIR
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from cosim.contract.errors import UserError
from cosim_plugins.commands import output_folder, progress


def add_commands(subparsers) -> None:
    """Register ``cosim twin`` and its subcommand ``calibrate``."""
    twin = subparsers.add_parser("twin", help="the plant FMU as a twin of a lab: calibrate it to the lab's logs",
                                 description="The co-simulation twin of a lab (docs/twin.md).")
    sub = twin.add_subparsers(dest="twin_command", metavar="COMMAND", required=True)
    c = sub.add_parser(
        "calibrate", help="fit the plant FMU (and effects) to raw logs; write DIR/twin.yaml and DIR/twin.json",
        description="Replay the logs' commands through the plant FMU open loop on diagnose's held-out windows, "
                    "fit its physical parameters, the camera's latency and noise and the effects' parameters, and "
                    "write DIR/twin.yaml (the lab's loop on the calibrated twin: cosim run DIR/twin.yaml) and "
                    "DIR/twin.json (held-out errors by horizon, the parameters with standard errors).")
    c.add_argument("logs", nargs="+", metavar="LOG", help="raw log CSV files")
    c.add_argument("--validate", nargs="+", default=[], metavar="LOG",
                   help="held-out logs (default: every third 5 s block of the given logs, as cosim diagnose)")
    c.add_argument("--effects", metavar="NAME[,NAME...]",
                   help="library effects to add to the twin (what cosim diagnose named); force effects go through "
                        "the FMU's external force input")
    c.add_argument("--model", metavar="M.npz",
                   help="start from a saved physical model (cosim diagnose --add ... --save-model) and its effects "
                        "instead of fitting one")
    c.add_argument("--scenario", metavar="LAB.yaml",
                   help="the lab's loop to run on the twin (default: the shipped racetrack scenario)")
    c.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1), metavar="N",
                   help="processes the FMU replays are spread over (default: the CPUs, at most 2)")
    c.add_argument("--seed", type=int, default=0, help="random seed of the training sample (default 0)")
    c.add_argument("--out", required=True, metavar="DIR", help="output directory")
    c.set_defaults(func=cmd_calibrate)


def cmd_calibrate(args) -> int:
    """``cosim twin calibrate``; see the module docstring."""
    from cosim_plugins.twin.calibrate import Settings, calibrate
    from cosim_plugins.twin.scenario import base_scenario, write_twin

    out = output_folder(args.out)
    for p in [*args.logs, *args.validate]:
        if not Path(p).is_file():
            raise UserError(f"log {p}: no such file")
    if args.model and not Path(args.model).is_file():
        raise UserError(f"--model {args.model}: no such file")
    base_scenario(args.scenario)  # a bad --scenario fails before the fit
    effects = [n.strip() for n in (args.effects or "").split(",") if n.strip()]
    cal = calibrate(args.logs, args.validate, Settings(effects=effects, model=args.model, jobs=args.jobs,
                                                       seed=args.seed), progress=progress)
    out.mkdir(parents=True, exist_ok=True)
    (out / "twin.json").write_text(json.dumps(cal.result, indent=1) + "\n")
    path = write_twin(cal, out, args.scenario)
    print(format_calibration(cal.result))
    print(f"wrote {out / 'twin.json'} and {path}; run the lab's loop on the twin with: cosim run {path}")
    return 0


def format_calibration(r: dict) -> str:
    """Printable summary: held-out errors by horizon, the calibrated values, what the logs cannot determine."""
    hs = list(r["held_out_error_mm"])
    rows = [("uncalibrated FMU", r["uncalibrated_error_mm"]), ("host fit mapped to FMU", r["mapped_error_mm"]),
            ("calibrated twin", r["held_out_error_mm"])]
    if r.get("host_error_mm"):
        rows.append((f"host model ({r['host_model']})"[:30], r["host_error_mm"]))
    lines = [f"{'held-out error [mm]':<32}" + "".join(f"{h + ' s':>9}" for h in hs)]
    lines += [f"{label:<32}" + "".join(f"{_n(d.get(h)):>9}" for h in hs) for label, d in rows]
    lines += ["", f"{'parameter':<26}{'value':>12}{'+- std':>11}  unit"]
    for name, p in r["params"].items():
        std = "-" if p["std"] is None else f"{p['std']:.2g}"
        flag = "  (not determined)" if name in r["not_determined"] else ""
        lines.append(f"{name:<26}{p['value']:>12.4g}{std:>11}  {p['unit']}{flag}")
    lines.append("FMU switches: " + ", ".join(f"{k}={v}" for k, v in r["switches"].items()))
    if r.get("camera_noise_mm"):
        lines.append("camera noise [mm]: " + ", ".join(f"{a} {v:.3f}" for a, v in r["camera_noise_mm"].items()))
    lines.append(f"held at the FMU's values (the logs cannot determine them): {', '.join(r['held_fixed'])}")
    return "\n".join(lines)


def _n(v) -> str:
    return "-" if v is None else f"{v:.3f}"

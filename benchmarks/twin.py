"""The calibrated twin (``cosim twin calibrate``, docs/twin.md): timing and held-out figures; prints JSON.

Two parts:

* ``lab``: five 60 s logs of the lab's loop on the plant FMU (the racetrack, seeds 1-5,
  a hidden 3 mm/s background flow), calibrated with ``--effects background_flow``:
  the calibration's wall time (budget: 3 minutes on this machine) and its held-out errors.
* ``blind``: logs from the blind bench's independent simulator (``benchmarks/blind_sim.py``,
  another swimmer with its own law, a hidden library effect: ``--case``, default
  ``library:background_flow`` seed 1), calibrated with the hidden effect and without it;
  ``blind_fresh``: the same on a seed not used before (``--fresh-seed``, default 50).
  Figures at the 1.0 s horizon on diagnose's held-out windows: the calibrated twin's
  open-loop error against the uncalibrated FMU's (target <= 0.5x) and against diagnose's
  host model with the same effect (target <= 1.5x), and the twin's error without the
  effect (the effect must lower it).

The machine's load (1-minute average, ``os.getloadavg``) is recorded before and after the lab's
calibration: its wall time depends on it.

    PYTHONPATH=. .venv/bin/python benchmarks/twin.py [--jobs 2] [--case library:background_flow] [--seed 1]
                                                     [--fresh-seed 50]
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

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
RACETRACK = ROOT / "cosim_plugins" / "scenarios" / "racetrack.yaml"
HIDDEN_FLOW = ("--set", "components.plant.params.background_flow_on=true",
               "--set", "components.plant.params.flow_x=0.003")
REF = "1.0"
BUDGET_S = 180.0


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}


def calibrate(logs, effects: str, out: Path, jobs: int) -> tuple[dict, float]:
    """(twin.json, wall time [s]) of ``cosim twin calibrate LOGS [--effects E] --out OUT``."""
    cmd = [sys.executable, "-m", "cosim.cli", "twin", "calibrate", *map(str, logs), "--jobs", str(jobs),
           "--out", str(out)] + (["--effects", effects] if effects else [])
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=_env(), cwd=ROOT, stdout=subprocess.DEVNULL)
    return json.loads((out / "twin.json").read_text()), time.perf_counter() - t0


def lab_logs(folder: Path) -> list[Path]:
    """Five 60 s racetrack logs of the lab's loop on the FMU with a hidden background flow (seeds 1-5)."""
    logs = []
    for seed in range(1, 6):
        run = folder / f"seed{seed}"
        subprocess.run([sys.executable, "-m", "cosim.cli", "run", str(RACETRACK), "--out", str(run), "--quiet",
                        "--set", f"seed={seed}", *HIDDEN_FLOW], check=True, env=_env(), cwd=ROOT)
        logs.append(run / "log.csv")
    return logs


def figures(r: dict) -> dict:
    """The 1.0 s figures of one twin.json."""
    twin, uncal = r["held_out_error_mm"][REF], r["uncalibrated_error_mm"][REF]
    host = (r["host_error_mm"] or {}).get(REF)
    return {"twin_mm": round(twin, 4), "uncalibrated_mm": round(uncal, 4),
            "mapped_mm": round(r["mapped_error_mm"][REF], 4),
            "host_mm": round(host, 4) if host else None, "twin_over_uncalibrated": round(twin / uncal, 3),
            "twin_over_host": round(twin / host, 3) if host else None, "switches": r["switches"],
            "not_determined": sorted(r["not_determined"]), "polish_steps": r["polish"]["steps"]}


def recovered(r: dict) -> dict:
    """The lab twin's FMU knobs against the FMU's values that wrote the logs: {knob: {true, fitted, std,
    off_in_std}} (the racetrack's plant runs at the FMU's defaults, its camera without latency)."""
    from cosim_plugins.twin import knobs as K

    truth = {**K.plant_defaults(), "latency_s": 0.0}
    out = {}
    for name in ("prop_coeff", "drag_axial", "anisotropy_ratio", "net_weight", "rot_drag_perp",
                 "gradient_force_scale", "latency_s"):
        p = r["params"][name]
        std = p["std"]
        out[name] = {"true": truth[name], "fitted": float(f"{p['value']:.4g}"),
                     "std": float(f"{std:.2g}") if std else None,
                     "off_in_std": round((p["value"] - truth[name]) / std, 2) if std else None}
    return out


def blind(group: str, effect: str, seed: int, args, tmp: Path) -> dict:
    """The blind part on one seed: the twin calibrated with the hidden effect and without it."""
    import blind_sim

    case = blind_sim.draw_case(seed, group, effect or None)
    logs = blind_sim.simulate(case, tmp / "logs")
    with_r, with_s = calibrate(logs, case.effect, tmp / "with", args.jobs)
    without_r, without_s = calibrate(logs, "", tmp / "without", args.jobs)
    w, wo = figures(with_r), figures(without_r)
    return {"case": args.case, "seed": seed, "truth": case.truth, "logs": len(logs),
            "log_s": round(sum(1 for p in logs for _ in open(p)) * 0.02 / len(logs), 1),
            "with_effect": {**w, "calibration_s": round(with_s, 1)},
            "without_effect": {**wo, "calibration_s": round(without_s, 1)},
            "effect_lowers_twin_error": w["twin_mm"] < wo["twin_mm"],
            "twin_over_uncalibrated_ok": w["twin_over_uncalibrated"] <= 0.5,
            "twin_over_host_ok": (w["twin_over_host"] or 99) <= 1.5}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--case", default="library:background_flow", help="blind bench case GROUP:EFFECT")
    ap.add_argument("--seed", type=int, default=1, help="the blind case's seed")
    ap.add_argument("--fresh-seed", type=int, default=50, help="a second blind seed, not used before (0: none)")
    ap.add_argument("--skip-lab", action="store_true", help="only the blind part")
    args = ap.parse_args(argv)
    group, _, effect = args.case.partition(":")
    out = {"horizon_s": float(REF), "targets": {"twin_over_uncalibrated": 0.5, "twin_over_host": 1.5,
                                                "lab_calibration_s": BUDGET_S}}
    with tempfile.TemporaryDirectory(prefix="twin_bench_") as tmp:
        tmp = Path(tmp)
        if not args.skip_lab:
            logs = lab_logs(tmp / "lab")
            load0 = os.getloadavg()[0]
            r, wall = calibrate(logs, "background_flow", tmp / "lab_twin", args.jobs)
            out["lab"] = {"logs": 5, "log_s": 60, "calibration_s": round(wall, 1), "within_budget": wall <= BUDGET_S,
                          "load_1min": [round(load0, 2), round(os.getloadavg()[0], 2)],
                          "flow_x_mm_s": {"true": 3.0, "fitted": round(r["params"]["background_flow.w_x"]["value"], 3),
                                          "std": r["params"]["background_flow.w_x"]["std"]},
                          "recovered": recovered(r), **figures(r)}
            print(json.dumps(out["lab"]), file=sys.stderr)
        for key, seed in (("blind", args.seed), ("blind_fresh", args.fresh_seed)):
            if seed:
                out[key] = blind(group, effect, seed, args, tmp / key)
                print(json.dumps({key: out[key]}), file=sys.stderr)
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

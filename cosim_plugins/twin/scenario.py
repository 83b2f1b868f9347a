"""DIR/twin.yaml: the lab's closed loop with its plant replaced by the calibrated twin.

The scenario is the lab's (``--scenario``, default the shipped racetrack) with
``plant.fmu_forced`` as its plant (the calibrated FMU parameters and dynamics
switches), ``twin.effect`` applying the calibrated force effects and the paper's lift
and centring force through the plant's external force input, and the camera's latency
and noise set to the calibrated ones. Every calibrated value carries its standard error
in a comment. ``twin_effects.py`` beside it registers the effect ``twin_paper_forces``.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

import yaml

from cosim.contract.errors import UserError
from cosim_plugins.twin import knobs as K
from cosim_plugins.twin.host_forces import NAME as PAPER
from cosim_plugins.twin.host_forces import effect_file_source

DEFAULT_SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "racetrack.yaml"
EFFECT_FILE = "twin_effects.py"
FORCE_WIRES = {"external_force": "effect.force", "external_force_dp": "effect.force_dp",
               "external_force_dv": "effect.force_dv"}


def base_scenario(path: str | Path | None) -> dict:
    """The lab's scenario as a dict (a file with a ``plant`` component and a ``camera.emulator`` camera)."""
    path = Path(path) if path else DEFAULT_SCENARIO
    if not path.is_file():
        raise UserError(f"--scenario {path}: no such file")
    try:
        sc = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise UserError(f"--scenario {path}: not YAML: {exc}") from exc
    comps = (sc or {}).get("components") if isinstance(sc, dict) else None
    if not isinstance(comps, dict) or "plant" not in comps:
        raise UserError(f"--scenario {path}: it has no component named 'plant' to replace with the twin")
    if "effect" in comps:
        raise UserError(f"--scenario {path}: it already has a component named 'effect' (the twin adds its own)")
    for name in sc.get("plugins") or []:
        if not Path(name).is_absolute():
            raise UserError(f"--scenario {path}: plugins entry {name} is relative; give the scenario's plugins as "
                            "absolute paths (twin.yaml is written elsewhere)")
    return sc


def write_twin(cal, out: Path, scenario_path=None) -> Path:
    """Write ``out/twin.yaml`` and ``out/twin_effects.py`` for the calibration ``cal``; returns twin.yaml's path."""
    sc = copy.deepcopy(base_scenario(scenario_path))
    out.mkdir(parents=True, exist_ok=True)
    paper = any(e.name == PAPER for e in cal.effects)
    if paper:
        (out / EFFECT_FILE).write_text(effect_file_source())
    r = cal.result
    comps = sc["components"]
    plant = comps["plant"]
    base_params = {k: v for k, v in (plant.get("params") or {}).items()
                   if k.startswith(("p0_", "axis0_"))}
    inputs = dict(plant.get("inputs") or {})
    forced = bool(cal.effects)  # no force effect: the plain plant, no effect component
    if forced:
        inputs.update({port: {"from": src, "delay": 1} for port, src in FORCE_WIRES.items()})
    std, values = cal.std, cal.values
    plant_lines = [f"{k}: {_num(v)}" for k, v in base_params.items()]
    fmu = K.fmu_values({k.name: values[k.name] for k in K.PLANT_KNOBS})
    for k in K.PLANT_KNOBS:
        name = "volume" if k.name == "net_weight" else k.name
        note = _pm(std[k.name], k.unit, k.name, r)
        if k.name == "net_weight":
            note = f"from the net weight {values[k.name]:.4g} N {_pm(std[k.name], 'N', k.name, r)}"
        plant_lines.append(f"{name}: {_num(fmu[name])}   # {note}")
    for sw, on in cal.switches.items():
        plant_lines.append(f"{sw}: {'true' if on else 'false'}   # chosen on the training windows")
    eff_names = [e.name for e in cal.effects]
    eff_lines = []
    for e in cal.effects:
        eff_lines.append(f"{e.name}:")
        for q, p in zip(e.param_names(), e.params):
            eff_lines.append(f"  {p.name}: {_num(values[q])}   # {_pm(std[q], p.unit, q, r)}")
    cam = comps.get("camera")
    cam_note = []
    if isinstance(cam, dict) and cam.get("plugin") == "camera.emulator":
        cp = dict(cam.get("params") or {})
        dt = float(sc.get("dt_s", 0.02))
        lat = values["latency_s"]
        cp["latency_s"] = round(round(lat / dt) * dt, 9)
        cam_note.append(f"latency_s: calibrated {lat:.4g} s {_pm(std['latency_s'], 's', 'latency_s', r)}, "
                        f"rounded to a multiple of dt_s")
        if cal.sigma_mm is not None:
            px = float(cp.get("pixel_mm", 0.19))
            sigma = float(sum(cal.sigma_mm) / len(cal.sigma_mm))
            cp["noise_px"] = round(sigma / px, 4)
            cam_note.append(f"noise_px: the logs' camera noise {sigma:.3f} mm (mean of x, y, z) / pixel_mm")
        cam["params"] = cp
    others = {k: v for k, v in comps.items() if k != "plant"}
    header = [
        f"# The calibrated twin of the logs {', '.join(Path(p).name for p in r['logs'])} (cosim twin calibrate).",
        f"# Held-out open-loop error at {', '.join(r['held_out_error_mm'])} s: "
        + ", ".join(_num3(v) for v in r["held_out_error_mm"].values()) + " mm (uncalibrated FMU: "
        + ", ".join(_num3(v) for v in r["uncalibrated_error_mm"].values()) + " mm).",
        "# Values: calibrated on the FMU's open-loop replay of the logs, +- one standard error;",
        "# 'not determined': the logs do not fix it (twin.json: not_determined, held_fixed).",
    ] + [f"# camera {n}" for n in cam_note]
    effect_lines = [
        "  effect:",
        "    plugin: twin.effect",
        "    params:",
        f"      effects: {yaml.safe_dump(eff_names, default_flow_style=True).strip()}",
        "      effect_params:",
        *[f"        {x}" for x in eff_lines],
        "      # the effects reuse the twin's own drag, thrust and net weight (its plant's values)",
        f"      plant_params: {_flow({k: float(_num(fmu[k])) for k in ('prop_coeff', 'drag_axial', 'volume')})}",
        *([f"      host: {_flow({'Cd0': float(_num(values[PAPER + '.Cd0']))})}   # the paper's angle-of-attack "
           "drag (twin_paper_forces.Cd0), which a flow's drag includes"] if paper else []),
        "      coupling: linear",
        "    inputs: {position: plant.position, velocity: plant.velocity, omega: "
        + _omega_source(comps) + "}"
    ] if forced else []
    head = {k: v for k, v in sc.items() if k not in ("components", "plugins", "name", "description", "sweep")}
    lines = header + [
        f"name: twin_{sc.get('name', 'lab')}",
        f"description: {_flow(str(sc.get('description', 'the lab loop')) + ' (on its calibrated twin)')}",
        f"plugins: {_flow([*([EFFECT_FILE] if paper else []), *(sc.get('plugins') or [])])}",
        yaml.safe_dump(head, sort_keys=False).rstrip(),
        "components:",
        "  plant:",
        f"    plugin: {'plant.fmu_forced' if forced else 'plant.fmu'}",
        "    params:",
        *[f"      {x}" for x in plant_lines],
        "    inputs:",
        *_indent(yaml.safe_dump(inputs, sort_keys=False), 6),
        *effect_lines,
        *_indent(yaml.safe_dump(others, sort_keys=False), 2),
    ]
    path = out / "twin.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def _omega_source(comps: dict) -> str:
    """The port the coil driver reads its command from (the command the plant follows)."""
    drv = comps.get("coil_driver") or {}
    src = (drv.get("inputs") or {}).get("omega")
    if isinstance(src, dict):
        src = src.get("from")
    return src or "controller.omega"


def _flow(value) -> str:
    """``value`` as one line of YAML (flow style)."""
    return yaml.safe_dump(value, default_flow_style=True, width=10000).strip().removesuffix("...").strip()


def _indent(text: str, n: int) -> list[str]:
    return [" " * n + line for line in text.rstrip().splitlines()]


def _num(v: float) -> str:
    return repr(float(f"{float(v):.6g}"))


def _num3(v) -> str:
    return "-" if v is None else f"{v:.3f}"


def _pm(std: float, unit: str, name: str, r: dict) -> str:
    """'+- std unit', 'not determined' or 'held' (a knob the calibration did not fit)."""
    if name in r.get("polish", {}).get("held", ()):
        return "held at its start value (not fitted)"
    if name in r.get("not_determined", {}) or std is None or not math.isfinite(std):
        return f"not determined (+- {std:.2g} {unit})" if std is not None and math.isfinite(std) else \
            "not determined"
    return f"+- {std:.2g} {unit}"

"""Blind bench of `cosim diagnose`: logs from an independent simulator, hidden effects; prints JSON.

The logs come from ``benchmarks/blind_sim.py`` (its own equations, no code
shared with ``cosim``): cases drawn at random (seeded) over wide regimes, in
groups (``--groups``, default ``library,none,outside``): one hidden library
effect (``library``), none (``none``: false-alarm cases), one outside the
library (``outside``), two at once (``multi``: two library effects, or one
library and one outside), or one of the look-alike family (``lookalike``:
actuation lag, camera latency, heading lag, now and then a quadratic drag) in
regimes where they mimic each other. Every case is diagnosed blind, as a user would
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
  (on top of the library effects chosen before it, when any: their joint
  drop ``chosen_reduction`` and the discovered form's drop of what they
  leave, combined)
  reaches >= 50 % of the true form's reduction), over the outside cases with
  a true form (a time-periodic force has none: no force in p, v, u can
  express it; those are counted under ``time_varying``);
* ``multi``: ``cases``; ``all_named`` (fraction whose verdict names every
  hidden library effect), ``extra_named`` (cases naming a library effect not
  hidden); ``all_named_detectable`` the same over the ``detectable`` cases
  (each hidden library effect's true form alone lowers the error by >= 10 %);
  ``detectable_jointly`` and ``all_named_detectable_jointly`` the same where
  each hidden library effect's true form lowers the error by >= 10 % once
  the other hidden effects' true forms are in (``true_given_others`` in the
  records: an effect a larger one masks alone can still show beside it);
  ``visible_named``: fraction naming every hidden library effect that its true
  form alone shows (>= 10 %); ``drawn_visible`` (cases whose every hidden
  effect is visible by the simulator's own measure, ``benchmarks/blind_visible.py``:
  with ``--draw visible``, the default, each case is redrawn until it
  is, up to 12 draws) and ``all_named_drawn_visible`` over them;
  ``declared_group`` (cases declaring a look-alike group that holds a hidden
  library effect); ``experiments`` (of those, cases whose designed
  experiment was simulated and its log added, as for ``lookalike``) and
  ``all_named_after_experiment`` (fraction naming every hidden library effect
  at once or once the experiment's log is added; ``extra_named_after_experiment``
  counts the extra names after it);
  ``by_kind``: the same for two library effects (``library``) and a
  library and an outside one (``outside``). Each hidden effect with a true
  form is refitted alone (``true_reductions`` in the records), and all of
  them together;
* ``lookalike``: ``cases``; ``wrong_named`` (cases naming an effect not
  hidden while the hidden one is in no declared look-alike group);
  ``visible`` (cases whose hidden effect the simulator's own measure shows,
  ``benchmarks/blind_visible.py``; with ``--draw visible``, the default,
  each case is redrawn until it does, up to 12 draws) and
  ``resolved_visible`` (``resolved`` over them);
  ``resolved`` (fraction named right at once, or declared in a look-alike
  group and named right once the designed experiment's log is added: the
  bench simulates the case's plant under the experiment's
  ``experiment_excitation.csv``, on the circle its ``experiment.yaml`` names,
  and diagnoses again); ``named_at_once``
  (fraction); ``declared`` (cases whose hidden effect is in a declared
  group); ``experiments`` (cases whose experiment was simulated);
* ``drift``: ``cases`` (a parameter of the plant drifts: drag, thrust or net
  weight, from log to log or slowly within logs; nothing hidden), ``flagged``
  (fraction whose diagnosis flags a drift), ``right`` (fraction flagging a
  quantity that truly changes, between or within as drawn), ``named`` (cases
  naming an effect: nothing is hidden), ``steady`` (controls: nothing
  changes, some with a camera giving a frame only every 2-5 rows) and
  ``steady_false_flags``; ``no_effect.drift_false_flags`` counts the drift
  flags of the ``none`` cases and the steady controls together;
* ``seconds_per_case`` (median wall time of the diagnoses and the true-form refits).

    .venv/bin/python benchmarks/blind.py [--cases 60] [--seed 0] [--jobs 2] [--out runs/blind]
    .venv/bin/python benchmarks/blind.py --groups multi,lookalike --multi-cases 12 --lookalike-cases 12 --out DIR
    .venv/bin/python benchmarks/blind.py --write-case outside:rotating_flow [--seed 3] --out DIR
    .venv/bin/python benchmarks/blind.py --write-case lookalike:sensor_latency --schedule CSV --out DIR

``--summarise OUT/cases.jsonl`` prints the figures of the cases recorded so
far (a bench stopped midway keeps every finished case); ``--resume`` goes on
with such a bench: the finished cases of ``OUT/cases.jsonl`` are kept and
only the others are diagnosed (same ``--cases``, ``--multi-cases``,
``--lookalike-cases`` and ``--seed``; the records of groups not run this time
are kept as they are).
``--write-case GROUP[:EFFECT]`` only simulates one case into ``DIR/logs`` (and
its true form into ``DIR/true_form.py``, its truth into ``DIR/case.json``):
logs to try ``cosim diagnose`` on by hand; GROUP is also ``multi`` (EFFECT:
two names joined by ``+``), ``lookalike`` or ``drift`` (EFFECT: between, within or
steady). With ``--schedule CSV`` (a
designed experiment's ``t_s,freq_hz``) it also simulates that experiment's
log into ``DIR/experiment/log_experiment.csv``, on the circle of the
``experiment.yaml`` beside the CSV (else on a circle of its own).

Records carry ``group`` and ``index`` (the index within the group's own draw:
``draw_cases`` for library/none/outside, ``draw_multi_cases``,
``draw_lookalike_cases``, ``draw_drift_cases``); case folders are ``case_NNN``,
``multi_NNN``, ``lookalike_NNN`` and ``drift_NNN``.
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
import blind_visible  # noqa: E402  (each hidden effect's visibility, measured with that simulator)

REDRAWN = {"multi": blind_visible.visible_case, "lookalike": blind_visible.visible_lookalike_case}  # --draw visible
DETECTABLE = 0.10  # a true-form reduction below this: the effect is invisible in these logs
MIN_T = 3.0  # the verdict's paired t below which two effects are not told apart
GOOD_SHARE = 0.5  # discovered_ok: the discovered form reaches this share of the true form's reduction


BASE_GROUPS = ("library", "none", "outside")  # drawn together by blind_sim.draw_cases
GROUPS = BASE_GROUPS + ("multi", "lookalike", "drift")
FAMILIES = ("base", "multi", "lookalike", "drift")
# the quantities a drifting parameter changes (cosim_plugins.diagnose.per_unit.QUANTITIES), by the simulator's name
CHANGES = {"drag": {"speed_per_hz", "time_constant_s", "sink_speed_mm_s"}, "thrust": {"speed_per_hz"},
           "weight": {"sink_speed_mm_s"}}


def family(group: str) -> str:
    """The draw a group's cases come from: "base" (draw_cases), "multi", "lookalike" or "drift"."""
    return group if group in FAMILIES else "base"


def case_folder(out: Path, case: blind_sim.Case) -> Path:
    """The case's folder under ``out``: case_NNN (library, none, outside), multi_NNN, lookalike_NNN or drift_NNN."""
    return out / (f"case_{case.index:03d}" if family(case.group) == "base" else f"{case.group}_{case.index:03d}")


def _diagnose(logs) -> tuple[dict, object]:
    """(record fields, Diagnosis) of a blind diagnosis of ``logs`` (``cosim diagnose LOGS --discover``)."""
    from cosim.contract import plugins
    from cosim_plugins.diagnose.pipeline import Settings, run

    plugins.reset()
    d = run(logs, settings=Settings(discover=True))  # one process: the bench runs cases side by side
    diag = d.json
    key = next(k for k, v in diag["horizons_s"].items() if v == diag["reference_horizon_s"])
    ranked = [e for e in diag["ranking"] if e.get("identifiable", True)]
    top = ranked[0] if ranked else None
    found = diag.get("discovered") or {}
    verdict = diag["verdict"]
    fields = {
        "baseline_mm": diag["baseline"]["rollout_mm"][key], "floor_mm": diag["noise_floor_mm"],
        "top": top["effect"] if top else None, "top_reduction": top["reduction"] if top else 0.0,
        "top_t": top["t_stat"] if top else 0.0, "runner_up": (top or {}).get("runner_up"),
        "named": verdict["effect"], "named_effects": list(verdict.get("effects") or []),
        "lookalikes": [list(g) for g in verdict.get("lookalikes") or []],
        "status": verdict["status"], "fit_notes": diag.get("fit_notes", []),
        "ranking": [[e["effect"], round(e["reduction"], 4)] for e in diag["ranking"]],
        "discovered": {k: found.get(k) for k in ("status", "reduction", "t_stat", "terms", "words")},
        # the chosen effects' joint drop: the discovery's reduction is measured on what they leave
        "chosen_reduction": ((diag.get("stepwise") or {}).get("joint") or {}).get("reduction", {}).get(key, 0.0),
        "drift_flagged": list((diag.get("drift") or {}).get("flagged") or []),
        "named_by": _named_by(diag, verdict.get("effects") or []),
    }
    return fields, d


def _named_by(diag: dict, named: list) -> dict:
    """{named effect: the path of the search that named it}: "stepwise" (its rounds), "given_form" (weighed
    given a discovered form: an effect dropped as tentative tried again beside it, or a group named on top of
    it) or "on_top" (the search again on top of the discovered form); "other" for none of these."""
    from cosim_plugins.diagnose.result import DISCOVERED

    sw = diag.get("stepwise") or {}
    paths = {}
    for st in (sw.get("given_discovered") or {}).get("steps") or []:
        for e in st["effects"]:
            paths[e] = "on_top"
    for st in sw.get("steps") or []:
        for e in st["effects"]:
            paths[e] = "given_form" if DISCOVERED in (st.get("given") or []) else "stepwise"
    return {e: paths.get(e, "other") for e in named}


def _true_refit(logs, forms: list) -> tuple[float, dict]:
    """(held-out reduction at the reference horizon, fitted params) of the model plus the true forms ``forms``
    [(effect-file source, effect name, path to write it to)], fitted jointly."""
    from cosim.contract import plugins
    from cosim_plugins.diagnose.pipeline import Settings, run

    for source, _, path in forms:
        path.write_text(source)
    plugins.reset()
    true = run(logs, settings=Settings(effects_files=[str(p) for _, _, p in forms], add=[n for _, n, _ in forms],
                                       candidates=[])).json
    key = next(k for k, v in true["horizons_s"].items() if v == true["reference_horizon_s"])
    return true["added"]["reduction"][key], {k: v["value"] for k, v in true["added"]["params"].items()}


def _given_others(logs, forms: dict, alone: dict) -> dict:
    """{effect: the drop of held-out error its true form brings once the other hidden effects' true forms are in}:
    1 - (1 - r_all) / (1 - r_others), r_all the reduction with every true form of ``forms`` {effect: (source,
    name, path)} fitted together, r_others with all but that one (``alone`` {effect: reduction} when one other)."""
    if len(forms) < 2:
        return dict(alone)
    r_all = _true_refit(logs, list(forms.values()))[0]
    out = {}
    for effect in forms:
        others = [e for e in forms if e != effect]
        r_others = alone[others[0]] if len(others) == 1 else _true_refit(logs, [forms[e] for e in others])[0]
        out[effect] = 1.0 - (1.0 - r_all) / max(1.0 - r_others, 1e-9)
    return out


def run_case(case: blind_sim.Case, out: Path, draw_mode: str = "visible") -> dict:
    """Simulate, diagnose blind, refit with the true form(s), and for a look-alike case declared as a group run
    the designed experiment and diagnose again; one JSON-able record. A multi or look-alike case is first
    redrawn until its hidden effects are visible (``draw_mode`` "visible": :func:`blind_visible.visible_case`,
    :func:`blind_visible.visible_lookalike_case`) unless ``draw_mode`` is "any" (the draw as it comes)."""
    from cosim.contract import plugins

    folder = case_folder(out, case)
    drawn_seed, draw = case.seed, None
    if case.group in REDRAWN and draw_mode == "visible":
        case, draw = REDRAWN[case.group](case)
    logs = blind_sim.simulate(case, folder / "logs")
    t0 = time.perf_counter()
    fields, d = _diagnose(logs)
    record = {"index": case.index, "seed": drawn_seed, "group": case.group, "effect": case.effect, "law": case.law,
              "truth": case.truth, "regime": case.regime, **fields, "true_reduction": None}
    if draw is not None:
        record["draw"] = {**draw, "case_seed": case.seed}
    if case.group == "multi":
        record.update(effects=case.effects, laws=case.laws, truths=case.truths,
                      hidden_library=[e for e in case.effects if e in blind_sim.LIBRARY],
                      true_reductions={}, true_params={})
        forms = {e: (source, name, folder / f"true_form_{e}.py")
                 for e, source, name in zip(case.effects, case.true_forms, case.true_form_names) if source}
        for effect, form in forms.items():
            red, prm = _true_refit(logs, [form])
            record["true_reductions"][effect], record["true_params"][effect] = red, prm
        record["true_given_others"] = _given_others(logs, forms, record["true_reductions"])
        record["after"] = _multi_experiment(case, folder, logs, record, d)
    elif case.true_form:
        record["true_reduction"], record["true_params"] = _true_refit(
            logs, [(case.true_form, case.true_form_name, folder / "true_form.py")])
    if case.group == "lookalike":
        record.update(_lookalike_round(case, folder, logs, fields, d))
        record["visibility"] = draw["visibility"] if draw else blind_visible.visibility(case)
    plugins.reset()
    record["seconds"] = round(time.perf_counter() - t0, 1)
    return record


def _lookalike_round(case: blind_sim.Case, folder: Path, logs: list, fields: dict, d) -> dict:
    """Named at once? Declared in a look-alike group? If declared and not named: the designed experiment's log
    (the case's plant under its ``experiment_excitation.csv``), and the verdict with that log added."""
    hidden = case.effect
    out = {"named_at_once": hidden in fields["named_effects"],
           "declared": any(hidden in g for g in fields["lookalikes"]), "experiment": None, "after": None}
    if out["named_at_once"] or not out["declared"]:
        return out
    summary = d.json.get("experiment")
    if d.experiment is None:
        out["experiment"] = {"status": "none designed"}
        return out
    extra, again = _fly_experiment(case, folder, logs, d)
    out["experiment"] = {"status": "simulated", "log": str(extra),
                         **{k: (summary or {}).get(k) for k in ("members", "kind", "params", "duration_s",
                                                                 "separation_mm", "floor_mm",
                                                                 "separation_over_floor")}}
    out["after"] = {k: again[k] for k in ("named", "named_effects", "lookalikes", "status", "top", "top_reduction")}
    out["after"]["named_right"] = hidden in again["named_effects"]
    return out


def _fly_experiment(case: blind_sim.Case, folder: Path, logs: list, d) -> tuple[Path, dict]:
    """(the experiment's log, the record fields of the diagnosis with it added): the designed experiment of ``d``
    written to ``folder/experiment``, its ``experiment_excitation.csv`` flown by the case's plant on the circle
    its ``experiment.yaml`` names (:func:`_scenario_path`)."""
    where = folder / "experiment"
    where.mkdir(parents=True, exist_ok=True)
    files = [Path(x) for x in d.experiment.write(where)]
    csv = next(p for p in files if p.suffix == ".csv")
    scenario = next(p for p in files if p.suffix == ".yaml")
    extra = blind_sim.simulate_experiment(case, csv, where, path=_scenario_path(scenario))
    return extra, _diagnose(list(logs) + [extra])[0]


def _scenario_path(scenario: Path) -> dict:
    """The path of an experiment scenario (``path: {plugin: circle, params: {radius_mm, center_mm}}``) as the
    simulator's path description: a horizontal circle, counter-clockwise from centre + (radius, 0, 0), as the
    design ran it. Only the driver reads it; the simulator's physics and controller are its own."""
    import yaml

    path = (yaml.safe_load(scenario.read_text()) or {}).get("path") or {}
    prm = path.get("params") or {}
    if path.get("plugin") != "circle" or "radius_mm" not in prm or "center_mm" not in prm:
        raise ValueError(f"{scenario}: the bench flies a circle (path: {{plugin: circle, params: {{radius_mm, "
                         f"center_mm}}}}), not {path!r}")
    return {"kind": "circle", "radius_mm": float(prm["radius_mm"]), "yaw_deg": 0.0, "tilt_deg": 0.0,
            "tilt_axis_deg": 0.0, "direction": 1, "start": 0.0, "near_wall": False,
            "offset_mm": [float(x) for x in prm["center_mm"]]}


def _multi_experiment(case: blind_sim.Case, folder: Path, logs: list, record: dict, d) -> dict | None:
    """A multi case whose verdict leaves a hidden library effect unnamed but in a declared look-alike group: the
    designed experiment's log (the case's plant under its ``experiment_excitation.csv``) added, the verdict
    again, as a user would go on; None when every hidden library effect is named at once or none is in a group."""
    hidden = set(record["hidden_library"])
    grouped = {e for g in record["lookalikes"] for e in g}
    if hidden <= set(record["named_effects"]) or not (hidden - set(record["named_effects"])) & grouped:
        return None
    if d.experiment is None:
        return {"experiment": "none designed", "named_effects": record["named_effects"], "all_named": False}
    _, again = _fly_experiment(case, folder, logs, d)
    return {"experiment": "simulated", "members": (d.json.get("experiment") or {}).get("members"),
            "named_effects": again["named_effects"], "lookalikes": again["lookalikes"],
            "all_named": hidden <= set(again["named_effects"])}


def _worker(args) -> dict:
    case, out, draw_mode = args
    try:
        return run_case(case, Path(out), draw_mode)
    except Exception as exc:  # one failed case is one failed row, never the whole bench
        return {"index": case.index, "seed": case.seed, "group": case.group, "effect": case.effect,
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

    def disc_ok(r):  # the chosen effects and the discovered form on what they leave, against the true form
        d = r["discovered"]
        reached = 1.0 - (1.0 - (r.get("chosen_reduction") or 0.0)) * (1.0 - (d["reduction"] or 0.0))
        return d["status"] == "found" and reached >= GOOD_SHARE * r["true_reduction"]

    def disc_alarm(r):
        d = r["discovered"]
        return d["status"] == "found" and (d["reduction"] or 0.0) >= DETECTABLE and (d["t_stat"] or 0.0) >= 3.0

    multi = [r for r in ok if r["group"] == "multi"]
    look = [r for r in ok if r["group"] == "lookalike"]

    def all_named(r):  # every hidden library effect named
        return set(r["hidden_library"]) <= set(r["named_effects"])

    def visible_named(r):  # every hidden library effect that its true form alone shows (>= 10 %) is named
        true = r.get("true_reductions") or {}
        return {e for e in r["hidden_library"] if (true.get(e) or 0.0) >= DETECTABLE} <= set(r["named_effects"])

    def multi_visible(r):  # every hidden effect visible by the simulator's measure (drawn so, or found so)
        return bool((r.get("draw") or {}).get("all_visible"))

    def multi_detectable(r):  # every hidden library effect's true form alone lowers the error by >= 10 %
        true = r.get("true_reductions") or {}
        return all((true.get(e) or 0.0) >= DETECTABLE for e in r["hidden_library"])

    def jointly_detectable(r):  # ... by >= 10 % once the other hidden effects' true forms are in
        given = r.get("true_given_others")
        return given is not None and all((given.get(e) or 0.0) >= DETECTABLE for e in r["hidden_library"])

    def extra_named(r):  # a library effect named that is not hidden
        return any(e in blind_sim.LIBRARY and e not in r["effects"] for e in r["named_effects"])

    def wrong_named(r):  # an effect named that is not hidden, the hidden one in no declared group
        return bool(set(r["named_effects"]) - {r["effect"]}) and not r["declared"]

    def look_visible(r):  # the hidden effect visible by the simulator's measure
        return bool(((r.get("visibility") or {}).get(r["effect"]) or {}).get("visible"))

    def resolved(r):
        return r["named_at_once"] or (r["declared"] and bool((r.get("after") or {}).get("named_right")))

    drift = [r for r in ok if r["group"] == "drift" and r["regime"].get("drift")]
    steady = [r for r in ok if r["group"] == "drift" and not r["regime"].get("drift")]

    def right_drift(r):  # a quantity the drawn parameter changes, flagged between or within logs as drawn
        d = r["regime"]["drift"]
        want = {("within:" if d["kind"] == "within" else "") + q for q in CHANGES[d["param"]]}
        return bool(want & set(r["drift_flagged"]))

    def pair_kind(r):
        return "outside" if any(e in blind_sim.OUTSIDE for e in r["effects"]) else "library"

    by_kind = {}
    for kind in ("library", "outside"):
        rows = [r for r in multi if pair_kind(r) == kind]
        by_kind[kind] = {"cases": len(rows), "all_named": frac(rows, all_named),
                         "extra_named": sum(1 for r in rows if extra_named(r))}

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
                      "discovered_alarms": sum(1 for r in none if disc_alarm(r)),
                      "drift_false_flags": sum(1 for r in none + steady if r.get("drift_flagged")),
                      "drift_checked": len(none) + len(steady)},
        "outside": {"cases": len(out_form), "discovered_ok": frac(out_form, disc_ok),
                    "time_varying": len(out) - len(out_form),
                    "time_varying_named": sum(1 for r in out if r["true_reduction"] is None and r["named"])},
        "multi": {"cases": len(multi), "all_named": frac(multi, all_named),
                  "extra_named": sum(1 for r in multi if extra_named(r)), "by_kind": by_kind,
                  # cases where an effect was named only given a discovered form (absent in older records)
                  "named_given_form": sum(1 for r in multi if {"given_form", "on_top"} & set(
                      (r.get("named_by") or {}).values())),
                  "detectable": sum(1 for r in multi if multi_detectable(r)),
                  "all_named_detectable": frac([r for r in multi if multi_detectable(r)], all_named),
                  "detectable_jointly": sum(1 for r in multi if jointly_detectable(r)),
                  "all_named_detectable_jointly": frac([r for r in multi if jointly_detectable(r)], all_named),
                  "visible_named": frac(multi, visible_named),
                  "drawn_visible": sum(1 for r in multi if multi_visible(r)),
                  "all_named_drawn_visible": frac([r for r in multi if multi_visible(r)], all_named),
                  "declared_group": sum(1 for r in multi if any(set(g) & set(r["hidden_library"])
                                                                for g in r["lookalikes"])),
                  "experiments": sum(1 for r in multi if (r.get("after") or {}).get("experiment") == "simulated"),
                  "all_named_after_experiment": frac(multi, lambda r: all_named(r)
                                                     or bool((r.get("after") or {}).get("all_named"))),
                  "extra_named_after_experiment": sum(
                      1 for r in multi if extra_named({**r, **({"named_effects": r["after"]["named_effects"]}
                                                               if r.get("after") else {})}))},
        "lookalike": {"cases": len(look), "wrong_named": sum(1 for r in look if wrong_named(r)),
                      "resolved": frac(look, resolved), "named_at_once": frac(look, lambda r: r["named_at_once"]),
                      "visible": sum(1 for r in look if look_visible(r)),
                      "resolved_visible": frac([r for r in look if look_visible(r)], resolved),
                      "declared": sum(1 for r in look if r["declared"]),
                      "experiments": sum(1 for r in look if (r.get("experiment") or {}).get("status") == "simulated")},
        "drift": {"cases": len(drift), "flagged": frac(drift, lambda r: bool(r["drift_flagged"])),
                  "right": frac(drift, right_drift), "named": sum(1 for r in drift if r["named_effects"]),
                  "steady": len(steady), "steady_false_flags": sum(1 for r in steady if r["drift_flagged"])},
        "seconds_per_case": round(float(np.median([r["seconds"] for r in ok])), 1) if ok else None,
    }


def _finished(lines: Path, cases: list, groups) -> list[dict]:
    """The error-free records of an earlier run's ``cases.jsonl`` that match this draw; the records of groups
    not run now are kept as they are."""
    if not lines.is_file():
        return []
    drawn = {(family(c.group), c.index): c for c in cases}
    kept = []
    for n, line in enumerate(lines.read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            print(f"{lines}:{n}: not a JSON line (a cut write?): diagnosed again", file=sys.stderr)
            continue
        if rec.get("group") not in groups:
            kept.append(rec)  # another group's record: carried over untouched
            continue
        case = drawn.get((family(rec.get("group", "")), rec.get("index")))
        # a multi case whose pair never showed was replaced by another pair: it matches the pair first drawn
        first = ((rec.get("draw") or {}).get("pairs") or [None])[0]
        effect = "+".join(first) if first else rec.get("effect")
        same = case is not None and (case.group, case.effect, case.seed) == (
            rec.get("group"), effect, rec.get("seed", case.seed))
        if not same:
            raise SystemExit(f"--resume: {lines}:{n} is case {rec.get('index')} {rec.get('group')} "
                             f"{rec.get('effect')}, not in this draw (other --cases/--multi-cases/"
                             "--lookalike-cases/--drift-cases/--seed?)")
        if "error" not in rec:
            kept.append(rec)
    return kept


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=60, help="number of cases (default 60)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the case draw (default 0)")
    ap.add_argument("--jobs", type=int, default=2, help="cases diagnosed at once (default 2)")
    ap.add_argument("--out", default=str(ROOT / "runs" / "blind"), help="folder for logs and cases.jsonl")
    ap.add_argument("--groups", help="comma-separated groups to run, of " + ", ".join(GROUPS)
                    + " (default library,none,outside)")
    ap.add_argument("--multi-cases", type=int, default=12, help="cases of the multi group (default 12)")
    ap.add_argument("--lookalike-cases", type=int, default=12, help="cases of the lookalike group (default 12)")
    ap.add_argument("--draw", "--multi-draw", dest="draw", choices=("visible", "any"), default="visible",
                    help="multi and look-alike cases: redrawn until each hidden effect is visible by the "
                         "simulator's own measure (visible, the default; benchmarks/blind_visible.py), or taken "
                         "as drawn (any: the draw of the multi runs before seed 45 and the look-alike runs "
                         "before seed 48)")
    ap.add_argument("--drift-cases", type=int, default=12,
                    help="cases of the drift group, one in three a steady control (default 12)")
    ap.add_argument("--only", choices=BASE_GROUPS,
                    help="run only the drawn cases of this group (the same cases as in the full draw); "
                         "the same as --groups GROUP")
    ap.add_argument("--resume", action="store_true",
                    help="keep the finished cases of OUT/cases.jsonl and diagnose only the others")
    ap.add_argument("--summarise", metavar="CASES.jsonl|OUT",
                    help="only print the figures of a (possibly unfinished) run's cases.jsonl")
    ap.add_argument("--write-case", metavar="GROUP[:EFFECT]",
                    help="only simulate one case (library|none|outside|multi|lookalike|drift, e.g. "
                         "outside:rotating_flow, multi:wall_drag+actuation_lag, drift:between) into --out")
    ap.add_argument("--schedule", metavar="CSV",
                    help="with --write-case: also simulate the experiment log of this t_s,freq_hz schedule")
    args = ap.parse_args(argv)
    if min(args.cases, args.jobs, args.multi_cases, args.lookalike_cases, args.drift_cases) < 1:
        ap.error("--cases, --multi-cases, --lookalike-cases, --drift-cases and --jobs must be at least 1")
    if args.only and args.groups:
        ap.error("give --groups or --only, not both")
    groups = [g.strip() for g in (args.groups or args.only or ",".join(BASE_GROUPS)).split(",") if g.strip()]
    unknown = [g for g in groups if g not in GROUPS]
    if unknown or not groups:
        ap.error(f"--groups {args.groups}: unknown group(s) {', '.join(unknown) or '(none given)'}; "
                 f"of {', '.join(GROUPS)}")
    if args.schedule and not args.write_case:
        ap.error("--schedule goes with --write-case")
    if args.summarise:
        path = Path(args.summarise)
        path = path / "cases.jsonl" if path.is_dir() else path
        if not path.is_file():
            ap.error(f"--summarise {args.summarise}: no such file (a bench's --out folder or its cases.jsonl)")
        rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
        print(json.dumps(summarise(sorted(rows, key=_order)), indent=2))
        return 0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.write_case:
        return _write_case(ap, args, out)
    cases = []
    if set(groups) & set(BASE_GROUPS):
        cases += [c for c in blind_sim.draw_cases(args.cases, args.seed) if c.group in groups]
    if "multi" in groups:
        cases += blind_sim.draw_multi_cases(args.multi_cases, args.seed)
    if "lookalike" in groups:
        cases += blind_sim.draw_lookalike_cases(args.lookalike_cases, args.seed)
    if "drift" in groups:
        cases += blind_sim.draw_drift_cases(args.drift_cases, args.seed)
    lines = out / "cases.jsonl"
    records = _finished(lines, cases, groups) if args.resume else []
    lines.write_text("".join(json.dumps(r) + "\n" for r in records))
    kept = {(family(r["group"]), r["index"]) for r in records}
    todo = [c for c in cases if (family(c.group), c.index) not in kept]
    if records:
        print(f"resuming: {len(records)} finished cases kept, {len(todo)} to go", file=sys.stderr, flush=True)
    total = len(records) + len(todo)
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(_worker, (c, str(out), args.draw)) for c in todo]
        for done, fut in enumerate(as_completed(futures), len(records) + 1):
            rec = fut.result()
            records.append(rec)
            with open(lines, "a") as fh:
                fh.write(json.dumps(rec) + "\n")
            print(f"[{done}/{total}] case {rec['index']} {rec['group']} {rec['effect']}: {_progress(rec)}",
                  file=sys.stderr, flush=True)
    records.sort(key=_order)
    print(json.dumps(summarise(records), indent=2))
    return 0


def _order(rec: dict):
    """Records sorted by draw (base, multi, lookalike), then index."""
    return (FAMILIES.index(family(rec.get("group", ""))), rec["index"])


def _progress(rec: dict) -> str:
    """One line on a finished case for stderr."""
    if "error" in rec:
        return rec["error"]
    if rec["group"] == "multi":
        return f"named {rec['named_effects']}, true {rec['true_reductions']}"
    if rec["group"] == "drift":
        return f"drift {rec['regime'].get('drift')}: flagged {rec['drift_flagged']}, named {rec['named_effects']}"
    if rec["group"] == "lookalike":
        after = rec.get("after") or {}
        return (f"named {rec['named_effects']}, look-alikes {rec['lookalikes']}"
                + (f"; after the experiment named {after.get('named_effects')}" if after else "")
                + f", true {rec['true_reduction']}")
    return f"top {rec['top']} ({rec['top_reduction']:+.0%}), true {rec['true_reduction']}"


def _write_case(ap, args, out: Path) -> int:
    """--write-case: one case's logs, true form(s) and truth into ``out`` (and an experiment's log)."""
    group, _, effect = args.write_case.partition(":")
    try:
        if group == "multi":
            case = blind_sim.draw_multi_case(args.seed, effect.split("+") if effect else None)
        elif group == "lookalike":
            case = blind_sim.draw_lookalike_case(args.seed, effect or None)
        elif group == "drift":
            case = blind_sim.draw_drift_case(args.seed, effect or None)
        else:
            case = blind_sim.draw_case(args.seed, group, effect or None)
        if group in REDRAWN and args.draw == "visible":
            case, draw = REDRAWN[group](case)
            print(f"drawn visible: {json.dumps(draw)}")
    except ValueError as exc:
        ap.error(f"--write-case {args.write_case}: {exc}")
    logs = blind_sim.simulate(case, out / "logs")
    for e, source in zip(case.effects, case.true_forms):
        if source:
            (out / ("true_form.py" if len(case.effects) == 1 else f"true_form_{e}.py")).write_text(source)
    (out / "case.json").write_text(json.dumps({"group": case.group, "effect": case.effect, "law": case.law,
                                               "truth": case.truth, "regime": case.regime, "effects": case.effects,
                                               "laws": case.laws, "truths": case.truths}, indent=2) + "\n")
    print(f"wrote {len(logs)} logs to {out / 'logs'} ({case.group} {case.effect or ''} {case.truth})")
    if args.schedule:
        try:
            scenario = Path(args.schedule).with_name("experiment.yaml")  # its circle, when written beside it
            path = _scenario_path(scenario) if scenario.is_file() else None
            extra = blind_sim.simulate_experiment(case, args.schedule, out / "experiment", path=path)
        except (OSError, ValueError) as exc:
            ap.error(f"--schedule {args.schedule}: {exc}")
        print(f"wrote the experiment's log {extra}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

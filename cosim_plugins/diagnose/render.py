"""A diagnosis rendered, in one place: diagnosis.json, the terminal summary and report.md.

* :func:`to_json` — diagnosis.json's content (a plain dict; :func:`write_json` writes it);
* :func:`terminal` — the summary ``cosim diagnose`` prints: errors by horizon, the ranking, the stepwise
  search, drift, notes, the legend and the verdict;
* :func:`markdown` — report.md (the plots are :mod:`.report`'s; their file names are linked).

Each takes a :class:`~cosim_plugins.diagnose.result.DiagnosisResult`.
"""

from __future__ import annotations

import json
from dataclasses import fields, is_dataclass
from pathlib import Path

from cosim_plugins.diagnose.result import DiagnosisResult, DriftResult, Stepwise
from cosim_plugins.diagnose.stepwise import STOPS
from cosim_plugins.diagnose.wording import legend, params_text
from cosim_plugins.identify.fit import json_default

# ---------------------------------------------------------------- diagnosis.json


def to_json(result: DiagnosisResult) -> dict:
    """diagnosis.json's content: every field under its name, optional sections (None) left out. Any part of a
    result (a :class:`~.result.Split`, a :class:`~.result.Verdict`, ...) gives its own section."""
    return _plain(result)


def write_json(result: DiagnosisResult, path) -> Path:
    """Write diagnosis.json (indented, numpy scalars as numbers) to ``path``; returns it."""
    path = Path(path)
    path.write_text(json.dumps(to_json(result), indent=2, default=json_default) + "\n")
    return path


def _plain(x):
    if is_dataclass(x):
        return {f.name: _plain(getattr(x, f.name)) for f in fields(x)
                if not (f.metadata.get("omit") and getattr(x, f.name) is None)}
    if isinstance(x, list):
        return [_plain(v) for v in x]
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    return x


# ---------------------------------------------------------------- terminal


def terminal(r: DiagnosisResult) -> str:
    """Printable summary of a diagnosis: errors by horizon, ranking, what the figures mean, verdict."""
    hs = list(r.horizons_s)
    key = r.reference_key
    lines = [f"{'held-out error [mm]':<28}" + "".join(f"{h + ' s':>9}" for h in hs),
             f"{r.baseline.model + ' (baseline)':<28}" + "".join(f"{_f(r.baseline.rollout_mm[h]):>9}" for h in hs)]
    if r.added:
        a = r.added
        lines.append(f"{'+ ' + ' + '.join(a.effects):<28}" + "".join(f"{_f(a.rollout_mm[h]):>9}" for h in hs))
    elif r.reference:
        ref = r.reference
        lines.append(f"{ref.model + ' (effects ref.)':<28}" + "".join(f"{_f(ref.rollout_mm[h]):>9}" for h in hs))
    lines.append(f"{'noise floor':<28}" + "".join(f"{_f(r.noise.floor_mm[h]):>9}" for h in hs))
    lines += ["", f"{'rank':<5}{'effect':<20}{'error ' + key + ' s':>12}{'reduction':>11}{'t':>7}"]
    for i, e in enumerate(r.ranking, 1):
        if not e.identifiable:
            lines.append(f"{'-':<5}{e.effect:<20}{'not identifiable from these logs':>30}")
            continue
        lines.append(f"{i:<5}{e.effect:<20}{_f(e.rollout_mm[key]):>12}{e.reduction:>+11.1%}{e.t_stat:>7.1f}")
    found = r.discovered
    if found and found.status == "found":
        lines.append(f"{'+':<5}{'discovered':<20}{_f(found.rollout_mm[key]):>12}{found.reduction:>+11.1%}"
                     f"{found.t_stat:>7.1f}   ({len(found.terms)} terms, {found.file})")
    lines += _stepwise_lines(r, key)
    lines += _drift_lines(r.drift or DriftResult(), key)
    for note in r.fit_notes or ():
        lines.append(f"note: {note}")
    lines += [""] + [f"  {line}" for line in legend()]
    lines += ["", "verdict: " + r.verdict.explanation]
    return "\n".join(lines)


def _stepwise_lines(r: DiagnosisResult, key: str) -> list[str]:
    """The rounds after the first (each candidate given the effects chosen before) and the chosen set."""
    sw = r.stepwise
    lines = []
    for n, entries in enumerate(sw.rounds[1:], 2):
        lines += ["", f"round {n}, given {_given(sw, n)}:"]
        for e in entries[:4]:
            lines.append(f"{'':<5}{e.effect:<20}{_f(e.rollout_mm):>12}{e.reduction:>+11.1%}{e.t_stat:>7.1f}"
                         if e.identifiable else f"{'':<5}{e.effect:<20}  not identifiable")
    if sw.steps:
        chosen = " -> ".join(" ~ ".join(st.effects) for st in sw.steps)
        lines += ["", f"chosen, in order: {chosen}  (joint: {_f(sw.joint.rollout_mm[key])} mm at {key} s, "
                      f"{sw.joint.reduction[key]:+.1%}; stopped: {STOPS[sw.stop]})"]
    exp = r.experiment
    if exp:
        lines.append(f"experiment: {exp.kind} for {exp.duration_s:g} s separates {' / '.join(exp.members)} by "
                     f"{_f(exp.separation_mm)} mm"
                     + (f" ({exp.separation_over_floor:.1f}x the noise floor)" if exp.separation_over_floor else ""))
    return lines


def _drift_lines(d: DriftResult, key: str) -> list[str]:
    """The drift test: the held-out drop of the per-log and per-block fits, each quantity's test, the flags."""
    if d.skipped:
        return ["", f"drift: not tested ({d.skipped})"]
    lines = []
    b, w = d.between, d.within
    fits = [(f"{', '.join(d.params or ())} free per log", b), ("a trend from log to log", (b or {}).get("trend")),
            ("a trend within the logs", w)]
    for what, fit in fits:
        if not fit:
            continue
        line = (f"drift, {what}: {_f(fit['rollout_mm'][key])} mm at {key} s ({fit['reduction']:+.1%}, "
                f"t = {fit['t_stat']:.1f})")
        if "quantities" in fit:
            line += "; " + ", ".join(f"{q} p={v['p']:.0e}" for q, v in fit["quantities"].items())
        lines.append(line)
    if lines:
        lines.append("drift flagged: " + (", ".join(d.flagged) if d.flagged else "none (the logs agree)"))
    return [""] + lines if lines else []


# ---------------------------------------------------------------- report.md


def markdown(r: DiagnosisResult, pngs=()) -> str:
    """report.md: verdict, tables, clues, the legend and the plots ``pngs`` (file names) linked."""
    key = r.reference_key
    hs = list(r.horizons_s)
    ref_s = r.reference_horizon_s
    lines = ["# Model discrepancy diagnosis", "",
             f"**Verdict:** {r.verdict.explanation}", "",
             f"Logs: {len(r.logs)} ({', '.join(r.logs[:6])}{', ...' if len(r.logs) > 6 else ''}); "
             f"held-out: {_split_text(r)}; lead-in {r.lead_in_s:g} s; reference horizon {ref_s:g} s.", "",
             "## Error and noise floor", "",
             "Camera noise estimated from the data (third differences): "
             + (", ".join(f"{a} {v:.3f}" for a, v in r.noise.sigma_mm.items()) + " mm."
                if r.noise.sigma_mm else "not enough consecutive measurements."), "",
             "| horizon [s] | " + " | ".join(hs) + " |", "|---" * (len(hs) + 1) + "|",
             f"| {r.baseline.model} error [mm] | " + " | ".join(_f(r.baseline.rollout_mm[h]) for h in hs) + " |",
             "| noise floor [mm] | " + " | ".join(_f(r.noise.floor_mm[h]) for h in hs) + " |"]
    if r.reference and not r.added:
        lines.append(f"| {r.reference.model} (reference for the effects) [mm] | "
                     + " | ".join(_f(r.reference.rollout_mm[h]) for h in hs) + " |")
    if r.added:
        a = r.added
        lines += [f"| + {' + '.join(a.effects)} [mm] | " + " | ".join(_f(a.rollout_mm[h]) for h in hs) + " |",
                  "| reduction | " + " | ".join(f"{a.reduction[h]:.0%}" for h in hs) + " |", "",
                  "Added effect parameters: " + params_text(a.params) + "."]
    lines += ["", "## Ranking of candidate effects (joint refit, held-out error)", "",
              f"| rank | effect | kind | error at {ref_s:g} s [mm] | reduction | t | parameters |",
              "|---|---|---|---|---|---|---|"]
    for i, e in enumerate(r.ranking, 1):
        if not e.identifiable:
            lines.append(f"| - | {e.effect} | {e.kind} | not identifiable from these logs | | | |")
            continue
        lines.append(f"| {i} | {e.effect} | {e.kind} | {_f(e.rollout_mm[key])} | {e.reduction:+.1%} "
                     f"| {e.t_stat:.1f} | {params_text(e.params)} |")
    lines += _stepwise_section(r, key)
    if r.fit_notes:
        lines += ["", "Notes on the fits:", ""] + [f"- {n}" for n in r.fit_notes]
    found = r.discovered
    if found:
        lines += ["", "## The form of what is missing (sparse regression of the residual force)", ""]
        if found.status == "found":
            lines += [f"- {w}" for w in found.words]
            lines += ["", f"Refitted with these {len(found.terms)} terms, the held-out error at {ref_s:g} s falls by "
                          f"{found.reduction:.0%} (t = {found.t_stat:.1f}). The effect file `{found.file}` holds "
                          f"them: rename it, edit its form and refit with `--effects-file {found.file} --add "
                          "discovered`."]
            if found.refines:
                lines += ["", f"The form's weight lies in {found.refines}'s own terms: it corrects that effect's law "
                              "on these logs rather than adding another effect."]
        else:
            lines.append(found.explanation + ".")
    lines += _drift_section(r.drift, key)
    loc = r.localisation
    lines += ["", "## Where, when and under which conditions the error concentrates", "",
              f"Error of {loc.model} at {ref_s:g} s on {loc.windows} windows of all logs "
              f"(mean {loc.mean_mm:.2f} mm). Strongest clues:", ""]
    lines += [f"- {c}" for c in loc.clues] or ["- none stand out"]
    lines += ["", "| group | features, strongest first (eta^2) |", "|---|---|"]
    for g, names in loc.groups.items():
        lines.append(f"| {g} | " + ", ".join(f"{n} ({loc.bins[n]['eta2']:.2f})" for n in names) + " |")
    lines += ["", "## How to read this report", ""]
    lines += [f"- **{line.split(':', 1)[0]}**:{line.split(':', 1)[1]}" for line in
              legend(("held-out error", "noise floor", "reduction", "t", "eta^2", "mean error vector", "value ± std"))]
    lines += ["", "## Figures", ""] + [f"![{p[:-4]}]({p})" for p in pngs]
    lines += ["", "The recording `diagnosis.rrd` shows the measured trajectory coloured by the error "
              "(`rerun diagnosis.rrd`).", ""]
    return "\n".join(lines)


def _drift_section(d: DriftResult | None, key: str) -> list[str]:
    """Markdown: the drift test, per log (values of each identifiable quantity) and per block of time."""
    if not d or d.skipped:
        return ["", "## Drift between and within the logs", "",
                f"Not tested: {d.skipped if d else 'no result'}."]
    lines = ["", "## Drift between and within the logs", "",
             f"{', '.join(d.params)} refitted free per log ({d.order}) and per block of time, the rest "
             "shared. Flagged: " + (", ".join(d.flagged) if d.flagged else "nothing (the logs agree)") + ".", ""]
    lines += [f"- {w}" for w in d.words]
    b = d.between
    if b:
        lines += ["", f"Per log: held-out error at {key} s {_f(b['rollout_mm'][key])} mm ({b['reduction']:+.1%}, "
                      f"t = {b['t_stat']:.1f}).", "", "| quantity | per log (± std) | homogeneity p | trend t | "
                      "change per log |", "|---|---|---|---|---|"]
        for q, v in b["quantities"].items():
            vals = ", ".join(f"{x:.3g} ± {e:.2g}" if x is not None and e is not None else "-"
                             for x, e in zip(v["values"], v["std"]))
            lines.append(f"| {q} | {vals} | {v['p']:.1e} | {v['slope_t']:.1f} | {v['change_per_step']:+.1%} |")
        tr = b.get("trend")
        if tr:
            lines += ["", f"A trend from log to log (each parameter on a straight line in the order recorded): "
                          f"held-out error at {key} s {_f(tr['rollout_mm'][key])} mm ({tr['reduction']:+.1%}, "
                          f"t = {tr['t_stat']:.1f})."]
    w = d.within
    if w:
        fr = w["free"]
        lines += ["", f"A trend within the logs ({w['blocks']} blocks of time; each parameter on a straight line "
                      f"in time, a level per log): held-out error at {key} s {_f(w['rollout_mm'][key])} mm "
                      f"({w['reduction']:+.1%}, t = {w['t_stat']:.1f}; against per log t = {w['t_vs_per_log']:.1f}; "
                      f"free per block: {_f(fr['rollout_mm'][key])} mm, {fr['reduction']:+.1%}).", "",
                  "| quantity | trend within the logs, per minute | t |", "|---|---|---|"]
        lines += [f"| {q} | {v['change_per_min']:+.1%} | {v['slope_t']:.1f} |" for q, v in w["quantities"].items()]
    for g in d.given_drift or ():
        lines.append(f"- once the drift is in, {g.effect} lowers the error by {g.reduction:.0%} "
                     f"(t = {g.t_stat:.1f}): " + ("kept" if g.kept else "dropped"))
    return lines


def _stepwise_section(r: DiagnosisResult, key: str) -> list[str]:
    """Markdown: each later round's ranking given the effects chosen before, the chosen set, the experiment."""
    sw = r.stepwise
    lines = ["", "## Several effects: the stepwise search", "",
             f"Each round refits every remaining candidate jointly with the effects chosen before it; one is chosen "
             f"when it passes the verdict's tests given them (at most {sw.max_effects}, --max-effects). "
             f"Stopped: {STOPS[sw.stop]}.", ""]
    if sw.steps:
        lines += ["| round | chosen | error before [mm] | after [mm] | reduction | t |", "|---|---|---|---|---|---|"]
        for n, st in enumerate(sw.steps, 1):
            name = " or ".join(st.effects) + (" (look-alikes)" if st.group else "")
            lines.append(f"| {n} | {name} | {_f(st.rollout_before_mm)} | {_f(st.rollout_mm)} | "
                         f"{st.reduction:+.1%} | {st.t_stat:.1f} |")
        j = sw.joint
        lines += ["", f"Joint: {' + '.join(j.effects)}, {_f(j.rollout_mm[key])} mm at {key} s "
                      f"({j.reduction[key]:+.1%} against the reference)."]
    for n, entries in enumerate(sw.rounds[1:], 2):
        lines += ["", f"Round {n}, given {_given(sw, n)}: "
                  + ", ".join(f"{e.effect} {e.reduction:+.1%} (t = {e.t_stat:.1f})"
                              for e in entries if e.identifiable) + "."]
    again = sw.named_on_top()
    for d in sw.dropped:
        by = {"drift": "the drift test", "discovered": "the stand-in check"}.get(d.given, "the backward check")
        lines.append(f"- {'set aside' if d.effect in again else 'dropped'} by {by}: {d.effect} ({d.reduction:+.1%}, "
                     f"t = {d.t_stat:.1f})"
                     + (f"; the form found without it ({', '.join(d.terms)}) lowers the error by "
                        f"{d.form_reduction:+.1%} (t = {d.form_t_stat:.1f}) given it"
                        if d.given == "discovered" else "")
                     + (f": the uniform part of that {d.part_of} flow" if d.part_of else ""))
    exp = r.experiment
    if exp:
        lines += ["", "## The experiment that tells the look-alikes apart", "",
                  f"{' / '.join(exp.members)} predict these logs alike. Over the excitations tried (the spin "
                  "rate within the logs' band or stopping and going, a PI controller holding the swimmer on a "
                  f"circle of {exp.path.radius_mm:.0f} mm at the centre or a side of the logs' workspace), "
                  f"{exp.kind} for {exp.duration_s:g} s separates their "
                  f"predictions most: by {_f(exp.separation_mm)} mm at {key} s"
                  + (f", {exp.separation_over_floor:.1f}x the noise floor" if exp.separation_over_floor else "")
                  + f". Run `{exp.files.scenario}` (or apply `{exp.files.excitation}` as the spin-rate "
                  "schedule on the rig), add its log.csv to these logs and diagnose again.", "",
                  "| excitation | circle | separation [mm] |", "|---|---|---|"]
        lines += [f"| {x.excitation} | {x.place} | {_f(x.separation_mm)} |" for x in exp.tried]
    return lines


def _given(sw: Stepwise, n: int) -> str:
    """The effects round ``n`` (1-based) was given, joined by ' + ' (in a file that did not record them: the
    effects chosen before it)."""
    if sw.rounds_given is not None:
        return " + ".join(sw.rounds_given[n - 1])
    return " + ".join(st.effects[0] for st in sw.steps[: n - 1])


def _split_text(r: DiagnosisResult) -> str:
    if r.split.kind == "validate":
        return f"{r.split.validate_logs} --validate log(s)"
    return f"every third {r.split.block_s:g} s block of each log"


def _f(v) -> str:
    return "-" if v is None else f"{v:.3f}"

"""Files of a diagnosis: diagnosis.json, report.md with PNG plots, diagnosis.rrd.

Plots (matplotlib, Agg):

* ``error_over_time.png``: the baseline's open-loop error at the reference
  horizon over each log's time (and the model with ``--add`` effects);
* ``error_by_condition.png``: mean error per quantile bin of every
  localisation feature (where, when, conditions), eta^2 in the titles;
* ``ranking.png``: held-out error at the reference horizon per candidate;
* ``before_after.png``: held-out error against the horizon, before and
  after the best (or added) effect, with the noise floor.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from cosim_plugins.diagnose.localise import FEATURES
from cosim_plugins.diagnose.stepwise import STOPS
from cosim_plugins.diagnose.wording import legend, params_text
from cosim_plugins.identify.dataset import log_label
from cosim_plugins.identify.fit import json_default

MAX_LOG_PLOTS = 6


def write_outputs(diag, out_dir, jobs: int = 1) -> list[Path]:
    """Write every output file of ``diag`` (a :class:`~cosim_plugins.diagnose.pipeline.Diagnosis`) into ``out_dir``,
    the plots drawn over ``jobs`` processes."""
    from cosim_plugins.diagnose.recording import write_recording

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = [out / "diagnosis.json"]
    files[0].write_text(json.dumps(diag.result, indent=2, default=json_default) + "\n")
    files += write_plots(diag, out, jobs)
    if diag.discovered_source:
        files.append(out / diag.result["discovered"]["file"])
        files[-1].write_text(diag.discovered_source)
    if diag.experiment is not None:
        files += diag.experiment.write(out)
    files.append(write_report(diag, out, [f.name for f in files if f.suffix == ".png"]))
    files.append(write_recording(diag, out / "diagnosis.rrd"))
    return files


# ---------------------------------------------------------------- plots


def write_plots(diag, out: Path, jobs: int = 1) -> list[Path]:
    """Write the diagnosis' PNG plots into ``out``, over ``jobs`` forked processes (rendering a PNG is most of
    the outputs' time); returns the paths of those drawn, in order."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from cosim_plugins.diagnose.fitting import fork_map

    plots = (("error_over_time.png", _plot_time), ("error_by_condition.png", _plot_features),
             ("ranking.png", _plot_ranking), ("before_after.png", _plot_before_after))

    def draw(i: int) -> Path | None:
        name, plot = plots[i]
        fig = plot(diag, plt)
        if fig is None:
            return None
        fig.savefig(out / name, dpi=90)
        plt.close(fig)
        return out / name

    return [path for path in fork_map(draw, len(plots), jobs, "plots") if path is not None]


def target_times(diag) -> tuple[np.ndarray, np.ndarray]:
    """(log index, time [s]) of each evaluation window's target row at the reference horizon."""
    k = diag.steps[_ref_key(diag)]
    rows = np.minimum(diag.starts + diag.lead + k, diag.timeline.n - 1)
    return diag.timeline.log[diag.starts], diag.timeline.t_s[rows]


def _ref_key(diag) -> str:
    ref = diag.result["reference_horizon_s"]
    return next(k for k, v in diag.result["horizons_s"].items() if v == ref)


def _plot_time(diag, plt):
    logs, t = target_times(diag)
    ids = [k for k in np.unique(logs) if k >= 0][:MAX_LOG_PLOTS]
    if not ids:
        return None
    fig, axes = plt.subplots(len(ids), 1, figsize=(9, 1.9 * len(ids) + 0.6), sharex=True, squeeze=False)
    floor = diag.result["noise_floor_mm"]
    for ax, k in zip(axes[:, 0], ids):
        sel = logs == k
        for label, err, color in ((f"{diag.result['baseline']['model']} (baseline)", diag.errors["baseline"],
                                   "tab:red"),
                                  (diag.errors.get("after_label"), diag.errors.get("after"), "tab:blue")):
            if err is not None:
                ax.plot(t[sel], np.linalg.norm(err[sel], axis=1), ".", ms=2, color=color, label=label)
        if floor:
            ax.axhline(floor, color="k", lw=0.8, ls="--", label="noise floor")
        ax.set_ylabel("error [mm]")
        ax.set_title(log_label(diag.result["logs"][k]), fontsize=8, loc="left")
    axes[0, 0].legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("time in log [s]")
    fig.suptitle(f"open-loop prediction error at {diag.result['reference_horizon_s']:g} s over time, each log "
                 "(all windows: training and held-out)", fontsize=10)
    _margins(fig, left=0.6, right=0.15, top=0.65, bottom=0.6, hgap=0.4)
    return fig


def _margins(fig, left: float, right: float, top: float, bottom: float, hgap: float, wgap: float = 0.0) -> None:
    """Fixed margins and gaps between a grid's axes [inches] (the grid plots' labels have known sizes: laying
    them out by measuring the text, as tight_layout does, costs a second drawing of the figure)."""
    w, h = fig.get_size_inches()
    rows, cols = fig.axes[0].get_subplotspec().get_gridspec().get_geometry()
    axes_h = (h - top - bottom - (rows - 1) * hgap) / rows
    axes_w = (w - left - right - (cols - 1) * wgap) / cols
    fig.subplots_adjust(left=left / w, right=1.0 - right / w, top=1.0 - top / h, bottom=bottom / h,
                        hspace=hgap / axes_h, wspace=wgap / axes_w)


def _plot_features(diag, plt):
    bins = diag.result["localisation"]["bins"]
    names = [n for n in FEATURES if n in bins]
    if not names:
        return None
    cols = 4
    rows = (len(names) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(12, 2.5 * rows), squeeze=False)
    overall = diag.result["localisation"]["mean_mm"]
    for ax, name in zip(axes.flat, names):
        b = bins[name]
        edges = np.asarray(b["edges"])
        ax.bar(0.5 * (edges[:-1] + edges[1:]), b["mean_mm"], width=np.diff(edges) * 0.9, color="tab:orange")
        ax.axhline(overall, color="k", lw=0.8, ls="--")
        unit, words = FEATURES[name]
        ax.set_title(f"{name} (eta^2 {b['eta2']:.2f})", fontsize=8)
        ax.set_xlabel(f"{words} [{unit}]" if unit else f"{words} [-]", fontsize=7)
        ax.set_ylabel(f"mean error at {diag.result['reference_horizon_s']:g} s [mm]", fontsize=7)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    fig.suptitle(f"error of {diag.result['localisation']['model']} by region, time and condition (dashed: mean)",
                 fontsize=10)
    _margins(fig, left=0.6, right=0.15, top=0.65, bottom=0.5, hgap=0.7, wgap=0.6)
    return fig


def _plot_ranking(diag, plt):
    r = diag.result
    key = _ref_key(diag)
    ref = r["reference"] or r["baseline"]
    labels = ["(reference)"] + [e["effect"] for e in r["ranking"]]
    values = [ref["rollout_mm"][key]] + [e["rollout_mm"][key] for e in r["ranking"]]
    fig, ax = plt.subplots(figsize=(7, 0.35 * len(labels) + 1.2))
    colors = ["tab:gray"] + ["tab:green" if e["effect"] == r["verdict"]["effect"] else "tab:blue"
                             for e in r["ranking"]]
    ax.barh(labels[::-1], values[::-1], color=colors[::-1])
    if r["noise_floor_mm"]:
        ax.axvline(r["noise_floor_mm"], color="k", ls="--", lw=0.8, label="noise floor")
        ax.legend(fontsize=7)
    ax.set_xlabel(f"held-out error at {r['reference_horizon_s']:g} s [mm]")
    ax.set_ylabel("model refitted with")
    ax.set_title("candidate effects ranked (green: the one the verdict names)", fontsize=9)
    fig.tight_layout()
    return fig


def _plot_before_after(diag, plt):
    fig, ax = plt.subplots(figsize=(6, 4))
    hs = diag.result["horizons_s"]
    for label, curve in diag.curves.items():
        keys = [k for k in hs if curve.get(k) is not None]
        style = "k--" if label == "noise floor" else "o-"
        ax.plot([hs[k] for k in keys], [curve[k] for k in keys], style, label=label)
    ax.set_xlabel("prediction horizon [s]")
    ax.set_ylabel("held-out open-loop error [mm]")
    ax.set_title("held-out error by horizon, before and after", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


# ---------------------------------------------------------------- markdown


def write_report(diag, out: Path, pngs: list[str]) -> Path:
    """Write ``out/report.md`` (verdict, tables, clues, ``pngs`` linked); returns its path."""
    r = diag.result
    key = _ref_key(diag)
    hs = list(r["horizons_s"])
    lines = ["# Model discrepancy diagnosis", "",
             f"**Verdict:** {r['verdict']['explanation']}", "",
             f"Logs: {len(r['logs'])} ({', '.join(r['logs'][:6])}{', ...' if len(r['logs']) > 6 else ''}); "
             f"held-out: {_split_text(r['split'])}; lead-in {r['lead_in_s']:g} s; reference horizon "
             f"{r['reference_horizon_s']:g} s.", "",
             "## Error and noise floor", "",
             "Camera noise estimated from the data (third differences): "
             + (", ".join(f"{a} {v:.3f}" for a, v in r["noise"]["sigma_mm"].items()) + " mm."
                if r["noise"]["sigma_mm"] else "not enough consecutive measurements."), "",
             "| horizon [s] | " + " | ".join(hs) + " |", "|---" * (len(hs) + 1) + "|",
             f"| {r['baseline']['model']} error [mm] | " + " | ".join(_f(r["baseline"]["rollout_mm"][h]) for h in hs)
             + " |",
             "| noise floor [mm] | " + " | ".join(_f(r["noise"]["floor_mm"][h]) for h in hs) + " |"]
    if r["reference"] and not r["added"]:
        lines.append(f"| {r['reference']['model']} (reference for the effects) [mm] | "
                     + " | ".join(_f(r["reference"]["rollout_mm"][h]) for h in hs) + " |")
    if r["added"]:
        a = r["added"]
        lines += [f"| + {' + '.join(a['effects'])} [mm] | " + " | ".join(_f(a["rollout_mm"][h]) for h in hs) + " |",
                  "| reduction | " + " | ".join(f"{a['reduction'][h]:.0%}" for h in hs) + " |", "",
                  "Added effect parameters: " + params_text(a["params"]) + "."]
    lines += ["", "## Ranking of candidate effects (joint refit, held-out error)", "",
              f"| rank | effect | kind | error at {r['reference_horizon_s']:g} s [mm] | reduction | t | parameters |",
              "|---|---|---|---|---|---|---|"]
    for i, e in enumerate(r["ranking"], 1):
        if not e.get("identifiable", True):
            lines.append(f"| - | {e['effect']} | {e['kind']} | not identifiable from these logs | | | |")
            continue
        lines.append(f"| {i} | {e['effect']} | {e['kind']} | {_f(e['rollout_mm'][key])} | {e['reduction']:+.1%} "
                     f"| {e['t_stat']:.1f} | {params_text(e['params'])} |")
    lines += _stepwise_section(r, key)
    if r.get("fit_notes"):
        lines += ["", "Notes on the fits:", ""] + [f"- {n}" for n in r["fit_notes"]]
    found = r.get("discovered")
    if found:
        lines += ["", "## The form of what is missing (sparse regression of the residual force)", ""]
        if found["status"] == "found":
            lines += [f"- {w}" for w in found["words"]]
            lines += ["", f"Refitted with these {len(found['terms'])} terms, the held-out error at "
                          f"{r['reference_horizon_s']:g} s falls by {found['reduction']:.0%} "
                          f"(t = {found['t_stat']:.1f}). The effect file `{found['file']}` holds them: rename it, "
                          f"edit its form and refit with `--effects-file {found['file']} --add discovered`."]
        else:
            lines.append(found["explanation"] + ".")
    lines += _drift_section(r.get("drift") or {}, key)
    loc = r["localisation"]
    lines += ["", "## Where, when and under which conditions the error concentrates", "",
              f"Error of {loc['model']} at {r['reference_horizon_s']:g} s on {loc['windows']} windows of all logs "
              f"(mean {loc['mean_mm']:.2f} mm). Strongest clues:", ""]
    lines += [f"- {c}" for c in loc["clues"]] or ["- none stand out"]
    lines += ["", "| group | features, strongest first (eta^2) |", "|---|---|"]
    for g, names in loc["groups"].items():
        lines.append(f"| {g} | " + ", ".join(f"{n} ({loc['bins'][n]['eta2']:.2f})" for n in names) + " |")
    lines += ["", "## How to read this report", ""]
    lines += [f"- **{line.split(':', 1)[0]}**:{line.split(':', 1)[1]}" for line in
              legend(("held-out error", "noise floor", "reduction", "t", "eta^2", "mean error vector", "value ± std"))]
    lines += ["", "## Figures", ""] + [f"![{p[:-4]}]({p})" for p in pngs]
    lines += ["", "The recording `diagnosis.rrd` shows the measured trajectory coloured by the error "
              "(`rerun diagnosis.rrd`).", ""]
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path


def _drift_section(d: dict, key: str) -> list[str]:
    """Markdown: the drift test, per log (values of each identifiable quantity) and per block of time."""
    if not d or d.get("skipped"):
        return ["", "## Drift between and within the logs", "", f"Not tested: {d.get('skipped', 'no result')}."]
    lines = ["", "## Drift between and within the logs", "",
             f"{', '.join(d['params'])} refitted free per log ({d['order']}) and per block of time, the rest "
             "shared. Flagged: " + (", ".join(d["flagged"]) if d["flagged"] else "nothing (the logs agree)") + ".", ""]
    lines += [f"- {w}" for w in d["words"]]
    b = d.get("between")
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
    w = d.get("within")
    if w:
        fr = w["free"]
        lines += ["", f"A trend within the logs ({w['blocks']} blocks of time; each parameter on a straight line "
                      f"in time, a level per log): held-out error at {key} s {_f(w['rollout_mm'][key])} mm "
                      f"({w['reduction']:+.1%}, t = {w['t_stat']:.1f}; against per log t = {w['t_vs_per_log']:.1f}; "
                      f"free per block: {_f(fr['rollout_mm'][key])} mm, {fr['reduction']:+.1%}).", "",
                  "| quantity | trend within the logs, per minute | t |", "|---|---|---|"]
        lines += [f"| {q} | {v['change_per_min']:+.1%} | {v['slope_t']:.1f} |" for q, v in w["quantities"].items()]
    for g in d.get("given_drift", ()):
        lines.append(f"- once the drift is in, {g['effect']} lowers the error by {g['reduction']:.0%} "
                     f"(t = {g['t_stat']:.1f}): " + ("kept" if g["kept"] else "dropped"))
    return lines


def _stepwise_section(r: dict, key: str) -> list[str]:
    """Markdown: each later round's ranking given the effects chosen before, the chosen set, the experiment."""
    sw = r["stepwise"]
    lines = ["", "## Several effects: the stepwise search", "",
             f"Each round refits every remaining candidate jointly with the effects chosen before it; one is chosen "
             f"when it passes the verdict's tests given them (at most {sw['max_effects']}, --max-effects). "
             f"Stopped: {STOPS[sw['stop']]}.", ""]
    if sw["steps"]:
        lines += ["| round | chosen | error before [mm] | after [mm] | reduction | t |", "|---|---|---|---|---|---|"]
        for n, st in enumerate(sw["steps"], 1):
            name = " or ".join(st["effects"]) + (" (look-alikes)" if st["group"] else "")
            lines.append(f"| {n} | {name} | {_f(st['rollout_before_mm'])} | {_f(st['rollout_mm'])} | "
                         f"{st['reduction']:+.1%} | {st['t_stat']:.1f} |")
        j = sw["joint"]
        lines += ["", f"Joint: {' + '.join(j['effects'])}, {_f(j['rollout_mm'][key])} mm at {key} s "
                      f"({j['reduction'][key]:+.1%} against the reference)."]
    for n, entries in enumerate(sw["rounds"][1:], 2):
        lines += ["", f"Round {n}, given {' + '.join(st['effects'][0] for st in sw['steps'][: n - 1])}: "
                  + ", ".join(f"{e['effect']} {e['reduction']:+.1%} (t = {e['t_stat']:.1f})"
                              for e in entries if e["identifiable"]) + "."]
    for d in sw["dropped"]:
        lines.append(f"- dropped by the backward check: {d['effect']} ({d['reduction']:+.1%}, t = {d['t_stat']:.1f})")
    exp = r.get("experiment")
    if exp:
        lines += ["", "## The experiment that tells the look-alikes apart", "",
                  f"{' / '.join(exp['members'])} predict these logs alike. Over the excitations tried (the spin "
                  f"rate within the logs' band, a PI controller holding the swimmer on a circle of "
                  f"{exp['path']['radius_mm']:.0f} mm), {exp['kind']} for {exp['duration_s']:g} s separates their "
                  f"predictions most: by {_f(exp['separation_mm'])} mm at {key} s"
                  + (f", {exp['separation_over_floor']:.1f}x the noise floor" if exp["separation_over_floor"] else "")
                  + f". Run `{exp['files']['scenario']}` (or apply `{exp['files']['excitation']}` as the spin-rate "
                  "schedule on the rig), add its log.csv to these logs and diagnose again.", "",
                  "| excitation | separation [mm] |", "|---|---|"]
        lines += [f"| {x['excitation']} | {_f(x['separation_mm'])} |" for x in exp["tried"]]
    return lines


def _split_text(split: dict) -> str:
    if split["kind"] == "validate":
        return f"{split['validate_logs']} --validate log(s)"
    return f"every third {split['block_s']:g} s block of each log"


def _f(v) -> str:
    return "-" if v is None else f"{v:.3f}"


"""Files of a diagnosis: diagnosis.json, report.md with PNG plots, diagnosis.rrd (their text is
:mod:`.render`'s; the plots are drawn here).

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

from pathlib import Path

import numpy as np

from cosim_plugins.diagnose.localise import FEATURES
from cosim_plugins.diagnose.render import markdown, write_json
from cosim_plugins.identify.dataset import log_label

MAX_LOG_PLOTS = 6


def write_outputs(diag, out_dir, jobs: int = 1) -> list[Path]:
    """Write every output file of ``diag`` (a :class:`~cosim_plugins.diagnose.pipeline.Diagnosis`) into ``out_dir``,
    the plots drawn over ``jobs`` processes."""
    from cosim_plugins.diagnose.recording import write_recording

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = [write_json(diag.result, out / "diagnosis.json")]
    files += write_plots(diag, out, jobs)
    if diag.discovered_source:
        files.append(out / diag.result.discovered.file)
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
    k = diag.steps[diag.result.reference_key]
    rows = np.minimum(diag.starts + diag.lead + k, diag.timeline.n - 1)
    return diag.timeline.log[diag.starts], diag.timeline.t_s[rows]


def _plot_time(diag, plt):
    logs, t = target_times(diag)
    ids = [k for k in np.unique(logs) if k >= 0][:MAX_LOG_PLOTS]
    if not ids:
        return None
    fig, axes = plt.subplots(len(ids), 1, figsize=(9, 1.9 * len(ids) + 0.6), sharex=True, squeeze=False)
    floor = diag.result.noise_floor_mm
    for ax, k in zip(axes[:, 0], ids):
        sel = logs == k
        for label, err, color in ((f"{diag.result.baseline.model} (baseline)", diag.errors["baseline"],
                                   "tab:red"),
                                  (diag.errors.get("after_label"), diag.errors.get("after"), "tab:blue")):
            if err is not None:
                ax.plot(t[sel], np.linalg.norm(err[sel], axis=1), ".", ms=2, color=color, label=label)
        if floor:
            ax.axhline(floor, color="k", lw=0.8, ls="--", label="noise floor")
        ax.set_ylabel("error [mm]")
        ax.set_title(log_label(diag.result.logs[k]), fontsize=8, loc="left")
    axes[0, 0].legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("time in log [s]")
    fig.suptitle(f"open-loop prediction error at {diag.result.reference_horizon_s:g} s over time, each log "
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
    loc = diag.result.localisation
    bins = loc.bins
    names = [n for n in FEATURES if n in bins]
    if not names:
        return None
    cols = 4
    rows = (len(names) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(12, 2.5 * rows), squeeze=False)
    overall = loc.mean_mm
    for ax, name in zip(axes.flat, names):
        b = bins[name]
        edges = np.asarray(b["edges"])
        ax.bar(0.5 * (edges[:-1] + edges[1:]), b["mean_mm"], width=np.diff(edges) * 0.9, color="tab:orange")
        ax.axhline(overall, color="k", lw=0.8, ls="--")
        unit, words = FEATURES[name]
        ax.set_title(f"{name} (eta^2 {b['eta2']:.2f})", fontsize=8)
        ax.set_xlabel(f"{words} [{unit}]" if unit else f"{words} [-]", fontsize=7)
        ax.set_ylabel(f"mean error at {diag.result.reference_horizon_s:g} s [mm]", fontsize=7)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    fig.suptitle(f"error of {loc.model} by region, time and condition (dashed: mean)",
                 fontsize=10)
    _margins(fig, left=0.6, right=0.15, top=0.65, bottom=0.5, hgap=0.7, wgap=0.6)
    return fig


def _plot_ranking(diag, plt):
    r = diag.result
    key = r.reference_key
    labels = ["(reference)"] + [e.effect for e in r.ranking]
    values = [r.effects_model.rollout_mm[key]] + [e.rollout_mm[key] for e in r.ranking]
    fig, ax = plt.subplots(figsize=(7, 0.35 * len(labels) + 1.2))
    colors = ["tab:gray"] + ["tab:green" if e.effect == r.verdict.effect else "tab:blue" for e in r.ranking]
    ax.barh(labels[::-1], values[::-1], color=colors[::-1])
    if r.noise_floor_mm:
        ax.axvline(r.noise_floor_mm, color="k", ls="--", lw=0.8, label="noise floor")
        ax.legend(fontsize=7)
    ax.set_xlabel(f"held-out error at {r.reference_horizon_s:g} s [mm]")
    ax.set_ylabel("model refitted with")
    ax.set_title("candidate effects ranked (green: the one the verdict names)", fontsize=9)
    fig.tight_layout()
    return fig


def _plot_before_after(diag, plt):
    fig, ax = plt.subplots(figsize=(6, 4))
    hs = diag.result.horizons_s
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
    """Write ``out/report.md`` (:func:`.render.markdown`, ``pngs`` linked); returns its path."""
    path = out / "report.md"
    path.write_text(markdown(diag.result, pngs))
    return path

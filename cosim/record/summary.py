"""Figures of a run and of a sweep: summary.json content, the sweep table and plot.

Run figures: the framework's ``tracking_error_mm`` (distance of the ``truth``
role to the reference path, {mean, std, max} [mm]), then those of the domain's
figure sets (hook ``cosim_summary_figures``, see :mod:`cosim.contract.figures`;
:func:`metric_keys` lists them all). They are computed as the run goes
(:mod:`cosim.record.figures`); :func:`trace_figures` computes them exactly
from a whole trace.

Components add figures of their own from their recorded outputs
(:meth:`cosim.contract.component.Component.summary_figures`, batch by batch through
its ``summary_accumulator``); a key another component
or the framework already uses is prefixed with the component's name.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cosim.contract.plugins import figure_sets
from cosim.scenario.paths import distance_to_path

#: the framework's own figure of a run with a path
TRACKING = "tracking_error_mm"
#: the other keys of a run's summary.json (see :mod:`cosim.runtime.runner`), which no component figure takes
RUN_KEYS = ("scenario", "status", "error", "steps", "sim_time_s", "wall_time_s", "realtime_factor",
            "total_wall_time_s", "files", "realtime", "end")
#: keys a run's summary.json may hold besides :data:`RUN_KEYS` that are not figures of the run
BOOKKEEPING_KEYS = ("phase", "pid", "note", "security_events", "security_event_count", "security_log")


def run_figures(recorder) -> dict[str, Any]:
    """The figures of one run, computed as it went by its :class:`~cosim.runtime.recorder.TraceRecorder`
    (see :mod:`cosim.record.figures`), then the components' own."""
    return recorder.figures.figures(metric_keys(), RUN_KEYS)


def metric_keys() -> tuple[str, ...]:
    """The keys every run's summary has (None when the run has none of that figure): the tracking
    error, then the figure sets' keys."""
    return tuple(dict.fromkeys((TRACKING, *(k for figure_set in figure_sets() for k in figure_set.keys))))


def is_figure(value: Any) -> bool:
    """Whether ``value`` is a numeric figure: a number, or a dict of such (None allowed among them)."""
    if isinstance(value, bool):
        return False
    if isinstance(value, (int, float)):
        return True
    return isinstance(value, dict) and bool(value) and all(v is None or is_figure(v) for v in value.values())


def other_figures(summary: dict[str, Any]) -> dict[str, Any]:
    """The numeric figures of a run's summary besides :data:`METRICS`: the components' own (e.g. a
    controller's ``speed_error_rad_s``), in the summary's order."""
    skip = {*metric_keys(), *RUN_KEYS, *BOOKKEEPING_KEYS}
    return {k: v for k, v in summary.items() if k not in skip and v is not None and is_figure(v)}


def _stats(values_mm: np.ndarray | None) -> dict | None:
    if values_mm is None:
        return None
    v = values_mm[np.isfinite(values_mm)]
    if not len(v):
        return None
    return {"mean": float(np.mean(v)), "std": float(np.std(v)), "max": float(np.max(v))}


def trace_figures(trace: dict[str, np.ndarray], roles: dict[str, str | None], path=None) -> dict[str, Any]:
    """The run's figures computed exactly from a whole trace (:func:`~cosim.record.trace_files.load_trace`),
    ``roles`` as ``scenario.record.ports()``, ``path`` the run's path: the reference the figures
    computed as a run goes are checked against (memory: the whole trace)."""
    def get(role):
        return trace.get(roles.get(role) or "")

    out: dict[str, Any] = dict.fromkeys(metric_keys())
    truth, t_s = get("truth"), trace["t_s"]
    if path is not None and truth is not None and truth.shape[1:] == (3,):
        out[TRACKING] = _stats(distance_to_path(path, truth, t_s) * 1e3)
    for figure_set in figure_sets():
        out.update(figure_set.exact(get, t_s))
    return out


#: the keys of a sweep row that are not labels: what the run gave, and where and by what it was made
ROW_KEYS = ("status", "dir", "error", "host", "code", "artifacts")


def label_keys(rows: list[dict]) -> list[str]:
    """The keys of a sweep's rows that label a run, in row order: those before its first metric or
    bookkeeping key (a row is ``{**labels, **metrics, status, ..., **other figures}``)."""
    labels = []
    metrics = metric_keys()
    for k in rows[0] if rows else ():
        if k in metrics or k in ROW_KEYS or k == "seeds":
            break
        labels.append(k)
    return labels


def row_figure_keys(rows: list[dict]) -> list[str]:
    """The figures of a sweep's rows besides :data:`METRICS` (a component's own), in order of appearance."""
    labels = set(label_keys(rows))
    keys: dict[str, None] = {}
    for r in rows:
        keys.update((k, None) for k in r if k not in labels and k not in (*metric_keys(), *ROW_KEYS, "seeds"))
    return list(keys)


def _figure_column(key: str, rows: list[dict]) -> tuple[str, Any]:
    """A table column of the figure ``key``: a number as it is, a dict's numbers joined by ``/``."""
    parts = list(dict.fromkeys(k for r in rows if isinstance(r.get(key), dict) for k in r[key]))
    if not parts:
        return key, lambda r: _g(r.get(key))
    return f"{key} {' / '.join(parts)}", lambda r: "/".join(_g((r.get(key) or {}).get(p)) for p in parts)


def _g(value: Any) -> str:
    if isinstance(value, dict) or value is None:
        return "-"
    return f"{value:.4g}"


def sweep_table(rows: list[dict]) -> str:
    """Markdown table: the labels, the tracking error, the figure sets' columns, then the other
    figures (the components' own)."""
    if not rows:
        return ""
    labels = label_keys(rows)
    cols = []
    if any(r.get("tracking_error_mm") for r in rows) or not row_figure_keys(rows):
        cols += [("tracking error [mm]", lambda r: _pm(r.get("tracking_error_mm"))),
                 ("max [mm]", lambda r: _f(r.get("tracking_error_mm"), "max"))]
    for figure_set in figure_sets():
        cols += figure_set.columns(rows)
    cols += [_figure_column(key, rows) for key in row_figure_keys(rows)]
    cols.append(("status", lambda r: r["status"]))
    lines = ["| " + " | ".join([*labels, *(c for c, _ in cols)]) + " |",
             "|" + "---|" * (len(labels) + len(cols))]
    for r in rows:
        lines.append("| " + " | ".join([*(str(r[k]) for k in labels), *(fn(r) for _, fn in cols)]) + " |")
    return "\n".join(lines) + "\n"


def _f(d: dict | None, key: str, digits: int = 2) -> str:
    return f"{d[key]:.{digits}f}" if d and d.get(key) is not None else "-"


def _pm(d: dict | None) -> str:
    return f"{d['mean']:.2f} ± {d['std']:.2f}" if d else "-"


def numeric_axes(rows: list[dict]) -> list[str]:
    """The labels whose values are numbers and differ between rows: the axes a plot can use."""
    return [k for k in label_keys(rows) if all(isinstance(r[k], (int, float)) for r in rows)
            and len({r[k] for r in rows}) > 1]


def _groups(rows: list[dict], axis: str) -> tuple[list[str], dict[tuple, list[dict]]]:
    """The other labels, and the rows grouped by their values, each group sorted along ``axis``."""
    others = [k for k in label_keys(rows) if k != axis]
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault(tuple(r[k] for k in others), []).append(r)
    return others, {key: sorted(members, key=lambda r: r[axis]) for key, members in groups.items()}


#: labels whose values repeat an experiment rather than change it: rows differing only in them are pooled
REPLICATE_LABELS = ("seed",)


def pool_replicates(rows: list[dict]) -> list[dict]:
    """Rows differing only in a replicate label (``seed``) pooled into one: the tracking error's
    mean is the mean of the runs' means, ``std`` their spread (sample standard deviation over the
    seeds, 0 for one), ``max`` the largest, ``min_mean``/``max_mean`` the runs' extremes and ``n``
    the number of runs; status ``ok`` only if every run's is. Rows without a replicate label pass."""
    if not rows or not any(k in label_keys(rows) for k in REPLICATE_LABELS):
        return rows
    labels = [k for k in label_keys(rows) if k not in REPLICATE_LABELS]
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault(tuple(r[k] for k in labels), []).append(r)
    out = []
    for key, members in groups.items():
        errs = [m["tracking_error_mm"] for m in members if m.get("tracking_error_mm")]
        means = np.array([e["mean"] for e in errs])
        pooled = None if not errs else {
            "mean": float(means.mean()), "std": float(means.std(ddof=1)) if len(means) > 1 else 0.0,
            "max": float(max(e["max"] for e in errs)), "min_mean": float(means.min()),
            "max_mean": float(means.max()), "n": len(errs)}
        status = "ok" if all(m["status"] == "ok" for m in members) and len(errs) == len(members) else "failed"
        out.append({**dict(zip(labels, key)), "tracking_error_mm": pooled, "status": status,
                    "seeds": [m[k] for m in members for k in REPLICATE_LABELS if k in m]})
    return out


def pooled_table(rows: list[dict]) -> str:
    """Markdown table of :func:`pool_replicates`: per combination, the mean over the seeds, the spread."""
    labels = [k for k in label_keys(rows) if k != "seeds"]
    lines = ["| " + " | ".join([*labels, "seeds", "mean error [mm]", "spread over seeds (std) [mm]",
                                "min / max of the seeds' means [mm]", "max [mm]", "status"]) + " |",
             "|" + "---|" * (len(labels) + 6)]
    for r in rows:
        e = r.get("tracking_error_mm")
        lines.append("| " + " | ".join([*(str(r[k]) for k in labels), str(len(r.get("seeds", []))),
                                         _f(e, "mean"), _f(e, "std"),
                                         f"{_f(e, 'min_mean')} / {_f(e, 'max_mean')}", _f(e, "max"),
                                         r["status"]]) + " |")
    return "\n".join(lines) + "\n"


def monotonic_within_spread(rows: list[dict], axis: str, k: float = 2.0) -> list[dict]:
    """Per group of pooled rows along ``axis``: whether the mean error never falls, from one value to
    the next, by more than ``k`` times the two points' combined spread (a drop inside the seeds'
    scatter is noise, a larger one a real non-monotonic curve). Lists the offending steps."""
    out = []
    others, groups = _groups(rows, axis)
    for key, members in groups.items():
        drops = []
        for a, b in zip(members, members[1:]):
            ea, eb = a.get("tracking_error_mm"), b.get("tracking_error_mm")
            if not ea or not eb:
                continue
            allowed = k * float(np.hypot(ea.get("std", 0.0), eb.get("std", 0.0)))
            if ea["mean"] - eb["mean"] > allowed:
                drops.append([a[axis], b[axis], round(ea["mean"], 2), round(eb["mean"], 2)])
        out.append({**dict(zip(others, key)), "axis": axis, "monotonic": not drops, "drops": drops})
    return out


def largest_below(rows: list[dict], threshold_mm: float) -> list[dict]:
    """Per group of the other labels, the largest value of each numeric axis whose mean
    tracking error stays below ``threshold_mm`` (and every smaller value's too); None if none does.
    Runs repeated over seeds are pooled first (:func:`pool_replicates`): the mean over the seeds decides."""
    rows = pool_replicates(rows)
    out = []
    for axis in numeric_axes(rows):
        others, groups = _groups(rows, axis)
        for key, members in groups.items():
            best = None
            for r in members:
                e = r.get("tracking_error_mm")
                if not e or r["status"] != "ok" or e["mean"] >= threshold_mm:
                    break
                best = r[axis]
            out.append({**dict(zip(others, key)), "axis": axis, "largest_below": best,
                        "threshold_mm": threshold_mm})
    return out


UNIT_SUFFIXES = {"_s": "s", "_ms": "ms", "_mm": "mm", "_m": "m", "_hz": "Hz", "_px": "px", "_deg": "deg"}
STYLES = [("o", "-"), ("s", "--"), ("^", "-."), ("D", ":"), ("v", "-"), ("P", "--"), ("X", "-.")]


def axis_label(name: str) -> str:
    """A sweep axis as an axis label with its unit: ``interval_s`` -> ``interval [s]``."""
    for suffix, unit in UNIT_SUFFIXES.items():
        if name.lower().endswith(suffix):
            return f"{name[: -len(suffix)].replace('_', ' ')} [{unit}]"
    return name.replace("_", " ")


def sweep_plot(rows: list[dict], out_dir: Path, threshold_mm: float | None = None, title: str = "") -> list[Path]:
    """One PNG per numeric axis: mean tracking error against it, a line per group of other labels.

    Lines differ in marker and dash and are drawn from the largest marker down, so coinciding lines stay visible.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []
    rows = pool_replicates(rows)
    if not any(r.get("tracking_error_mm") for r in rows):  # nothing to plot (a system without a path)
        return files
    for axis in numeric_axes(rows):
        others, groups = _groups(rows, axis)
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for i, (key, members) in enumerate(groups.items()):
            x = [r[axis] for r in members]
            y = [(r.get("tracking_error_mm") or {}).get("mean", np.nan) for r in members]
            marker, dash = STYLES[i % len(STYLES)]
            if any("seeds" in r for r in members):  # the seeds' spread as error bars
                ax.errorbar(x, y, yerr=[(r.get("tracking_error_mm") or {}).get("std", 0.0) for r in members],
                            fmt="none", capsize=3, lw=0.8, color=f"C{i}")
            ax.plot(x, y, color=f"C{i}", marker=marker, ls=dash, ms=max(9 - 1.5 * i, 3), mfc="none" if i % 2 else None,
                    label=", ".join(f"{k}={v}" for k, v in zip(others, key)) or "run")
        if threshold_mm:
            ax.axhline(threshold_mm, color="k", ls="--", lw=1, label=f"{threshold_mm:g} mm")
        ax.set_xlabel(axis_label(axis))
        ax.set_ylabel("mean tracking error [mm]")
        ax.set_title(f"{title + ': ' if title else ''}mean tracking error against {axis_label(axis)}", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        path = out_dir / f"sweep_{axis}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        files.append(path)
    return files

"""Figures of a run and of a sweep: summary.json content and the sweep table.

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

from typing import Any

import numpy as np

from cosim.contract.figures import error_stats
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


def trace_figures(trace: dict[str, np.ndarray], roles: dict[str, str | None], path=None) -> dict[str, Any]:
    """The run's figures computed exactly from a whole trace (:func:`~cosim.record.trace_files.load_trace`),
    ``roles`` as ``scenario.record.ports()``, ``path`` the run's path: the reference the figures
    computed as a run goes are checked against (memory: the whole trace)."""
    def get(role):
        return trace.get(roles.get(role) or "")

    out: dict[str, Any] = dict.fromkeys(metric_keys())
    truth, t_s = get("truth"), trace["t_s"]
    if path is not None and truth is not None and truth.shape[1:] == (3,):
        out[TRACKING] = error_stats(distance_to_path(path, truth, t_s) * 1e3)
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
    """Markdown table: the labels, the tracking error (when a run has a path), the figure sets'
    columns, then the other figures (the components' own), then the status. What a sweep adds
    about one figure (pooled over seeds, a threshold, a plot) is :mod:`cosim.record.sweep_report`'s."""
    if not rows:
        return ""
    labels = label_keys(rows)
    cols = []
    if any(r.get(TRACKING) for r in rows):  # runs with a path
        cols += [("tracking error [mm]", lambda r: _pm(r.get(TRACKING))),
                 ("max [mm]", lambda r: _f(r.get(TRACKING), "max"))]
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

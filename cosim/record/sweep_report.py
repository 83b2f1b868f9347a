"""What a sweep's summary says about one figure of its runs: pooled over seeds, monotonic or not
along each axis, the largest axis value that keeps it below a threshold, a plot per axis.

The figure is the scenario's ``report.figure`` (:class:`cosim.scenario.schema.ReportSpec`), a key
of a run's summary (``tracking_error_mm``), and ``report.part``, the part of it read when it has
parts (``rms`` of ``speed_error_rad_s``; by default its ``mean``; a plain number is read as it is).
Its unit is its key's suffix (``_mm`` -> mm, :func:`~cosim.contract.figures.unit_of`). Which
figure matters, and below what value, is the domain's to say in its scenarios; the framework only
reads it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cosim.contract.figures import Figure, unit_of
from cosim.record.summary import ROW_KEYS, label_keys

STYLES = [("o", "-"), ("s", "--"), ("^", "-."), ("D", ":"), ("v", "-"), ("P", "--"), ("X", "-.")]
#: labels whose values repeat an experiment rather than change it: rows differing only in them are pooled
REPLICATE_LABELS = ("seed",)


def axis_label(name: str) -> str:
    """A sweep axis as an axis label with its unit: ``interval_s`` -> ``interval [s]``."""
    stem, unit = unit_of(name)
    return stem.replace("_", " ") + (f" [{unit}]" if unit else "")


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


def replicated(rows: list[dict]) -> bool:
    """Whether ``rows`` repeat runs over a replicate label (``seed``): then they are pooled."""
    return bool(rows) and any(k in label_keys(rows) for k in REPLICATE_LABELS)


def figure_label(rows: list[dict], figure: Figure) -> str:
    """The figure in words as ``rows`` hold it: ``mean tracking error`` (a figure with parts, or
    pooled over seeds), ``rms speed error`` (a part), ``saturated fraction`` (one run's number)."""
    if figure.part or replicated(rows) or any(isinstance(r.get(figure.key), dict) for r in rows):
        return figure.label
    return figure.words


def pool_replicates(rows: list[dict], figure: Figure) -> list[dict]:
    """Sweep rows pooled into one per combination of the labels other than a replicate label
    (``seed``), each ``{**labels, status, figure.name: pooled, seeds}``; ``pooled`` is the figure's
    mean over the runs (``mean``), their spread (``std``: sample standard deviation, 0 for one run),
    the largest value any run had (``max``: a run's own ``max`` when the figure has one), the runs'
    extremes (``min_mean``/``max_mean``) and their number (``n``), or None when no run has it;
    status ``ok`` only if every run's is and every run has the figure. Rows pass as they are when
    none has a replicate label."""
    if not replicated(rows):
        return rows
    labels = [k for k in label_keys(rows) if k not in REPLICATE_LABELS]
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault(tuple(r[k] for k in labels), []).append(r)
    out = []
    for key, members in groups.items():
        having = [m for m in members if figure.value(m) is not None]
        means = np.array([figure.value(m) for m in having])
        pooled = None if not having else {
            "mean": float(means.mean()), "std": float(means.std(ddof=1)) if len(means) > 1 else 0.0,
            "max": float(max(figure.peak(m) for m in having)), "min_mean": float(means.min()),
            "max_mean": float(means.max()), "n": len(having)}
        status = "ok" if all(m["status"] == "ok" for m in members) and len(having) == len(members) else "failed"
        out.append({**dict(zip(labels, key)), "status": status, figure.name: pooled,
                    "seeds": [m[k] for m in members for k in REPLICATE_LABELS if k in m]})
    return out


def _mean(row: dict, figure: Figure) -> float | None:
    """The figure of a row, pooled (its ``mean``) or not."""
    if "seeds" in row:
        return (figure.pooled(row) or {}).get("mean")
    return figure.value(row)


def _spread(row: dict, figure: Figure) -> float:
    return (figure.pooled(row) or {}).get("std", 0.0) if "seeds" in row else 0.0


def _f(d: dict | None, key: str, digits: int = 2) -> str:
    return f"{d[key]:.{digits}f}" if d and d.get(key) is not None else "-"


def pooled_table(rows: list[dict], figure: Figure) -> str:
    """Markdown table of :func:`pool_replicates`: per combination, the figure's mean over the seeds,
    its spread, the seeds' extremes and the largest value of any run."""
    labels = [k for k in label_keys(rows) if k != "seeds"]
    heads = [figure.with_unit(figure.label), figure.with_unit("spread over seeds (std)"),
             figure.with_unit("min / max of the seeds' means"), figure.with_unit("max")]
    lines = ["| " + " | ".join([*labels, "seeds", *heads, "status"]) + " |",
             "|" + "---|" * (len(labels) + 6)]
    for r in rows:
        e = figure.pooled(r)
        lines.append("| " + " | ".join([*(str(r[k]) for k in labels), str(len(r.get("seeds", []))),
                                         _f(e, "mean"), _f(e, "std"),
                                         f"{_f(e, 'min_mean')} / {_f(e, 'max_mean')}", _f(e, "max"),
                                         r["status"]]) + " |")
    return "\n".join(lines) + "\n"


def monotonic_within_spread(rows: list[dict], axis: str, figure: Figure, k: float = 2.0) -> list[dict]:
    """Per group of pooled rows along ``axis``: whether the figure's mean never falls, from one value
    to the next, by more than ``k`` times the two points' combined spread (a drop inside the seeds'
    scatter is noise, a larger one a real non-monotonic curve). Lists the offending steps as
    ``[axis value, next axis value, mean, next mean]``."""
    out = []
    others, groups = _groups(rows, axis)
    for key, members in groups.items():
        drops = []
        for a, b in zip(members, members[1:]):
            ma, mb = _mean(a, figure), _mean(b, figure)
            if ma is None or mb is None:
                continue
            allowed = k * float(np.hypot(_spread(a, figure), _spread(b, figure)))
            if ma - mb > allowed:
                drops.append([a[axis], b[axis], round(ma, 2), round(mb, 2)])
        out.append({**dict(zip(others, key)), "axis": axis, "monotonic": not drops, "drops": drops})
    return out


def largest_below(rows: list[dict], figure: Figure, threshold: float) -> list[dict]:
    """Per group of the other labels, the largest value of each numeric axis at which the figure's
    mean stays below ``threshold`` (in the figure's unit), as at every smaller value; None if not
    even the smallest does. Runs repeated over seeds are pooled first (:func:`pool_replicates`):
    the mean over the seeds decides. Each entry: ``{**other labels, axis, largest_below, figure,
    threshold}``."""
    rows = pool_replicates(rows, figure)
    out = []
    for axis in numeric_axes(rows):
        others, groups = _groups(rows, axis)
        for key, members in groups.items():
            best = None
            for r in members:
                mean = _mean(r, figure)
                if mean is None or r["status"] != "ok" or mean >= threshold:
                    break
                best = r[axis]
            out.append({**dict(zip(others, key)), "axis": axis, "largest_below": best,
                        "figure": figure.name, "threshold": threshold})
    return out


def largest_below_lines(found: list[dict], label: str, figure: Figure, threshold: float) -> list[str]:
    """:func:`largest_below`'s entries as printed lines: ``largest kp with rms speed error below
    25 rad/s: 0.1 (load=high)``, the other labels in brackets when there are any; ``label`` the
    figure in words (:func:`figure_label`)."""
    lines = []
    for item in found:
        group = " ".join(f"{k}={v}" for k, v in item.items()
                         if k not in ("axis", "largest_below", "figure", "threshold"))
        unit = f" {figure.unit}" if figure.unit else ""
        lines.append(f"largest {item['axis']} with {label} below {threshold:g}{unit}: "
                     f"{item['largest_below']}" + (f" ({group})" if group else ""))
    return lines


def sweep_plot(rows: list[dict], out_dir: Path, figure: Figure, threshold: float | None = None,
               title: str = "") -> list[Path]:
    """One PNG per numeric axis, ``out_dir/sweep_AXIS.png``: the figure's mean against it (the
    seeds' spread as error bars), a line per group of other labels, ``threshold`` as a dashed line.
    No file when no run has the figure.

    Lines differ in marker and dash and are drawn from the largest marker down, so coinciding lines stay visible.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []
    label = figure_label(rows, figure)
    rows = pool_replicates(rows, figure)
    if not any(_mean(r, figure) is not None for r in rows):
        return files
    for axis in numeric_axes(rows):
        others, groups = _groups(rows, axis)
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for i, (key, members) in enumerate(groups.items()):
            x = [r[axis] for r in members]
            y = [np.nan if (m := _mean(r, figure)) is None else m for r in members]
            marker, dash = STYLES[i % len(STYLES)]
            if any("seeds" in r for r in members):  # the seeds' spread as error bars
                ax.errorbar(x, y, yerr=[_spread(r, figure) for r in members],
                            fmt="none", capsize=3, lw=0.8, color=f"C{i}")
            ax.plot(x, y, color=f"C{i}", marker=marker, ls=dash, ms=max(9 - 1.5 * i, 3), mfc="none" if i % 2 else None,
                    label=", ".join(f"{k}={v}" for k, v in zip(others, key)) or "run")
        if threshold is not None:
            ax.axhline(threshold, color="k", ls="--", lw=1,
                       label=f"{threshold:g} {figure.unit}".rstrip())
        ax.set_xlabel(axis_label(axis))
        ax.set_ylabel(figure.with_unit(label))
        ax.set_title(f"{title + ': ' if title else ''}{label} against {axis_label(axis)}", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        path = out_dir / f"sweep_{axis}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        files.append(path)
    return files


def report_figure(key: str | None, part: str | None, rows: list[dict], default: str) -> Figure | None:
    """The figure a sweep reports on: the scenario's ``report.figure`` and ``report.part``; without
    them, ``default`` (the framework's tracking error) when a row has it; None when neither."""
    if key:
        return Figure(key, part)
    fallback = Figure(default)
    return fallback if any(fallback.value(r) is not None for r in rows) else None


def figure_missing(rows: list[dict], figure: Figure) -> str | None:
    """A sentence when no row has ``figure`` (a misspelt ``report.figure``), naming the figures the rows have."""
    if not rows or any(figure.value(r) is not None for r in rows):
        return None
    have = sorted({k for r in rows for k, v in r.items() if isinstance(v, (int, float, dict))
                   and not isinstance(v, bool) and k not in (*label_keys(rows), *ROW_KEYS)})
    return (f"report: figure {figure.name!r}: no run of the sweep has it; its runs' figures: "
            f"{', '.join(have) or '(none)'}")


def report(rows: list[dict], figure: Figure | None, threshold: float | None) -> dict[str, Any]:
    """What a sweep's summary.json adds about ``figure``: ``pooled`` rows and ``monotonic`` curves
    when the runs repeat over seeds, ``largest_below_threshold`` when a threshold is given."""
    out: dict[str, Any] = {}
    if figure is None:
        return out
    pooled = pool_replicates(rows, figure)
    if pooled is not rows:
        out["pooled"] = pooled
        out["monotonic"] = [m for axis in numeric_axes(pooled) for m in monotonic_within_spread(pooled, axis, figure)]
    if threshold is not None:
        out["largest_below_threshold"] = largest_below(rows, figure, threshold)
    return out

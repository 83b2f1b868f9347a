"""The summary-figures contract: figures a domain computes of every run from its recorded roles.

The framework computes one figure of any run with a reference path, the
tracking error (``tracking_error_mm``: the distance of the ``truth`` role to
the path). A domain adds its own (an estimation error, a solver's time, ...)
with a :class:`FigureSet` registered through the ``cosim_summary_figures``
hook: the keys it puts into every run's ``summary.json`` (None when the run
lacks what a figure needs), an accumulator fed batch by batch as the run goes
(memory bounded whatever the run's length), the same figures computed exactly
from a whole trace, and the columns it adds to a sweep's table.

A sweep reports on one figure its scenario names (``report.figure`` and ``report.part``,
read by :class:`Figure`; its unit is its key's suffix, :func:`unit_of`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Protocol

import numpy as np

#: ``get(role)``: the whole trace of a recorded role, ``(n ticks, *shape)``, or None when unbound.
RoleGetter = Callable[[str], "np.ndarray | None"]


def error_stats(values_mm: np.ndarray | None) -> dict | None:
    """{mean, std, max} of the finite values of an error trace (n,) [mm]; None if there is none."""
    if values_mm is None:
        return None
    v = values_mm[np.isfinite(values_mm)]
    if not len(v):
        return None
    return {"mean": float(np.mean(v)), "std": float(np.std(v)), "max": float(np.max(v))}


class FigureAccumulator(Protocol):
    """A run's figures of one :class:`FigureSet`, computed as the run goes."""

    def add(self, recorder, start: int, stop: int) -> None:
        """Take ticks ``start:stop`` of the recorder (``recorder.signal(role, start, stop)``,
        ``recorder.t_s[start:stop]``)."""

    def figures(self) -> dict[str, Any]:
        """The figures of every tick taken, by key (a key the run has none of: None)."""


class FigureSet:
    """Base of a domain's summary figures; subclasses set :attr:`keys` and implement the methods."""

    #: the summary keys this set fills, in the order they appear in ``summary.json``
    keys: tuple[str, ...] = ()

    def accumulator(self, recorder) -> FigureAccumulator:
        """A fresh accumulator for the run of ``recorder`` (its roles tell what it can compute)."""
        raise NotImplementedError(f"{type(self).__name__}: a figure set implements accumulator()")

    def exact(self, get: RoleGetter, t_s: np.ndarray) -> dict[str, Any]:
        """The same figures computed exactly from a whole trace (``t_s``: shape (n,) [s]); the
        reference the accumulated ones are checked against."""
        raise NotImplementedError(f"{type(self).__name__}: a figure set implements exact()")

    def columns(self, rows: list[dict]) -> list[tuple[str, Callable[[dict], str]]]:
        """``(header, cell of a row)`` of the columns it adds to a sweep's table (by default none)."""
        return []


#: a key's unit by its suffix, longest first (``speed_rad_s`` is in rad/s, not s)
UNIT_SUFFIXES = {"_rad_s": "rad/s", "_m_s": "m/s", "_ms": "ms", "_mm": "mm", "_hz": "Hz", "_px": "px",
                 "_deg": "deg", "_s": "s", "_m": "m"}


def unit_of(name: str) -> tuple[str, str]:
    """``name`` without its unit suffix, and the unit: ``interval_s`` -> ``("interval", "s")``;
    ``("name", "")`` when it has none of :data:`UNIT_SUFFIXES`."""
    for suffix in sorted(UNIT_SUFFIXES, key=len, reverse=True):
        if name.lower().endswith(suffix) and len(name) > len(suffix):
            return name[: -len(suffix)], UNIT_SUFFIXES[suffix]
    return name, ""


@dataclass(frozen=True)
class Figure:
    """One figure of a run's summary, as a sweep report reads it: ``key`` (a key of a run's
    summary.json) and the ``part`` of it (e.g. ``rms``; None: a dict's ``mean``, or the number itself)."""

    key: str
    part: str | None = None

    @property
    def name(self) -> str:
        """``key`` or ``key.part``: the key of the pooled figure in a row pooled over seeds."""
        return f"{self.key}.{self.part}" if self.part else self.key

    @property
    def unit(self) -> str:
        """The figure's unit, from its key's suffix ('' when it has none)."""
        return unit_of(self.key)[1]

    @property
    def words(self) -> str:
        """The key in words, without its unit: ``tracking error``, ``saturated fraction``."""
        return unit_of(self.key)[0].replace("_", " ")

    @property
    def label(self) -> str:
        """The part read, in words: ``mean tracking error``, ``rms speed error``."""
        return f"{self.part or 'mean'} {self.words}"

    def with_unit(self, text: str) -> str:
        """``text [unit]``, or ``text`` alone when the figure has no unit."""
        return f"{text} [{self.unit}]" if self.unit else text

    def value(self, row: dict) -> float | None:
        """The figure in ``row`` (a run's summary or a sweep row): the part, a dict's mean or the
        number; None when the row has none of it."""
        v = row.get(self.key)
        if isinstance(v, dict):
            v = v.get(self.part or "mean")
        elif self.part is not None:
            return None
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            return None
        return float(v)

    def peak(self, row: dict) -> float | None:
        """The figure's ``max`` part when it has one (a run's own largest value), else its value."""
        v = row.get(self.key)
        if self.part is None and isinstance(v, dict) and isinstance(v.get("max"), (int, float)):
            return float(v["max"])
        return self.value(row)

    def pooled(self, row: dict) -> dict | None:
        """The figure of a row of :func:`pool_replicates`."""
        return row.get(self.name)

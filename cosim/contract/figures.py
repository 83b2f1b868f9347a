"""The summary-figures contract: figures a domain computes of every run from its recorded roles.

The framework computes one figure of any run with a reference path, the
tracking error (``tracking_error_mm``: the distance of the ``truth`` role to
the path). A domain adds its own (an estimation error, a solver's time, ...)
with a :class:`FigureSet` registered through the ``cosim_summary_figures``
hook: the keys it puts into every run's ``summary.json`` (None when the run
lacks what a figure needs), an accumulator fed batch by batch as the run goes
(memory bounded whatever the run's length), the same figures computed exactly
from a whole trace, and the columns it adds to a sweep's table.
"""

from __future__ import annotations

from typing import Any, Callable, Protocol

import numpy as np

#: ``get(role)``: the whole trace of a recorded role, ``(n ticks, *shape)``, or None when unbound.
RoleGetter = Callable[[str], "np.ndarray | None"]


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

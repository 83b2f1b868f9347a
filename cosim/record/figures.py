"""The run's summary figures, computed batch by batch as the run goes (see :mod:`cosim.record.summary`
for what each figure is): the tracking error (running moments, :mod:`cosim.record.streaming`),
the domain's figure sets (:mod:`cosim.contract.figures`) and the components' own figures. Memory
does not grow with the run.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cosim.contract.plugins import figure_sets
from cosim.record.streaming import Moments


class RunFigures:
    """Accumulates the figures of one :class:`~cosim.runtime.recorder.TraceRecorder`'s run: the
    tracking error, the domain's figure sets' and the components' own."""

    def __init__(self, recorder):
        self.tracking = Moments() if recorder.tracks_path else None
        self.sets = [figure_set.accumulator(recorder) for figure_set in figure_sets()]
        wiring = recorder.wiring
        self.components = {name: acc for name in wiring.order
                           if (acc := wiring.classes[name].summary_accumulator()) is not None}

    def add(self, recorder, start: int, stop: int, tracking_error_m: np.ndarray | None) -> None:
        """Ticks ``start:stop`` of ``recorder`` (held in its buffer), with their tracking error [m]
        (shape (stop - start,)) when the run has a path."""
        if stop <= start:
            return
        if self.tracking is not None and tracking_error_m is not None:
            self.tracking.add(tracking_error_m * 1e3)
        for acc in self.sets:
            acc.add(recorder, start, stop)
        for name, acc in self.components.items():
            acc.add({p.name: recorder.arrays[(name, p.name)][start - recorder.base: stop - recorder.base]
                     for p in recorder.wiring.outputs[name]})

    def figures(self, metrics: tuple, run_keys: tuple) -> dict[str, Any]:
        """The summary's figures: every one of ``metrics`` (None when the run has none of it), then
        the components' (a key of ``metrics``, ``run_keys`` or another component prefixed with the
        component's name)."""
        out: dict[str, Any] = {k: None for k in metrics}
        if self.tracking is not None:
            out["tracking_error_mm"] = self.tracking.figures()
        for acc in self.sets:
            out.update(acc.figures())
        for name, acc in self.components.items():
            for key, value in acc.figures().items():
                out[f"{name}.{key}" if key in out or key in metrics or key in run_keys else key] = value
        return out

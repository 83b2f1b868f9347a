"""The run's summary figures, computed batch by batch as the run goes (see :mod:`cosim.record.summary`
for what each figure is). Memory does not grow with the run: means, spreads and maxima are
running moments, medians and 99th percentiles come from fixed histograms
(:mod:`cosim.record.streaming`, relative error <= 5e-4), and the detection error keeps
``HISTORY_S`` of the true position to interpolate it at each measurement's capture time.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

from cosim.record.streaming import Moments, Quantiles

#: how far back [s of simulated time] a measurement's capture time may lie behind its row
HISTORY_S = 10.0


class RunFigures:
    """Accumulates the figures of one :class:`~cosim.runtime.recorder.TraceRecorder`'s run."""

    def __init__(self, recorder):
        has = {role: recorder.signal(role, 0, 0) is not None for role in
               ("truth", "estimate", "prediction_error", "solve_time", "measured", "capture_time")}
        self.tracking = Moments() if recorder.tracks_path else None
        self.estimation = Moments() if has["truth"] and has["estimate"] else None
        self.innovation = np.zeros(4) if has["prediction_error"] else None  # sums of |x|, |y|, |z| [mm], |e|^2 [mm^2]
        self.frames = 0
        self.solve = Quantiles("solve time [ms]") if has["solve_time"] else None
        self.detection = Quantiles("detection error [mm]") if has["measured"] and has["truth"] else None
        self._history_ticks = max(int(round(HISTORY_S / recorder.scenario.dt_s)), 1)
        self._history_t = np.zeros(0)
        self._history_truth = np.zeros((0, 3))
        self.too_old = 0  # measurements captured before the history kept
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
        truth = recorder.signal("truth", start, stop)
        if self.estimation is not None:
            self.estimation.add(np.linalg.norm(recorder.signal("estimate", start, stop) - truth, axis=1) * 1e3)
        if self.innovation is not None:
            innov = recorder.signal("prediction_error", start, stop)
            rows = innov[np.all(np.isfinite(innov), axis=1)] * 1e3
            self.innovation += [*np.abs(rows).sum(axis=0)[:3], (rows ** 2).sum()]
            self.frames += len(rows)
        if self.solve is not None:
            self.solve.add(recorder.signal("solve_time", start, stop) * 1e3)
        if self.detection is not None:
            self._add_detection(recorder, start, stop, truth)
        for name, acc in self.components.items():
            acc.add({p.name: recorder.arrays[(name, p.name)][start - recorder.base: stop - recorder.base]
                     for p in recorder.wiring.outputs[name]})

    def _add_detection(self, recorder, start: int, stop: int, truth: np.ndarray) -> None:
        t_s = recorder.t_s[start:stop]
        times = np.concatenate([self._history_t, t_s])
        positions = np.concatenate([self._history_truth, truth])
        capture = recorder.signal("capture_time", start, stop)
        at = t_s if capture is None else np.where(np.isfinite(capture), capture, t_s)
        measured = recorder.signal("measured", start, stop)
        if start > len(self._history_t):  # older rows are gone: a capture before the kept ones cannot be placed
            old = (at < times[0]) & np.all(np.isfinite(measured), axis=1)
            if old.any():
                self.too_old += int(old.sum())
                measured = np.where(old[:, None], np.nan, measured)
        truth_at = np.stack([np.interp(at, times, positions[:, i]) for i in range(3)], axis=1)
        self.detection.add(np.linalg.norm(measured - truth_at, axis=1) * 1e3)
        self._history_t = times[-self._history_ticks:]
        self._history_truth = positions[-self._history_ticks:]

    def figures(self, metrics: tuple, run_keys: tuple) -> dict[str, Any]:
        """The summary's figures: every one of ``metrics`` (None when the run has none of it), then
        the components' (a key of ``metrics``, ``run_keys`` or another component prefixed with the
        component's name)."""
        out: dict[str, Any] = {k: None for k in metrics}
        if self.tracking is not None:
            out["tracking_error_mm"] = self.tracking.figures()
        if self.estimation is not None:
            out["estimation_error_mm"] = self.estimation.figures()
        if self.innovation is not None and self.frames:
            mae = self.innovation[:3] / self.frames
            out["prediction_error_mm"] = {"x": float(mae[0]), "y": float(mae[1]), "z": float(mae[2]),
                                          "rmse": float(np.sqrt(self.innovation[3] / self.frames)),
                                          "frames": self.frames}
        out["solve_ms"] = _median_p99(self.solve)
        out["detection_error_mm"] = _median_p99(self.detection)
        if self.too_old:
            print(f"cosim: {self.too_old} measurements captured over {HISTORY_S:g} s before their row were "
                  "left out of detection_error_mm", file=sys.stderr)
        for name, acc in self.components.items():
            for key, value in acc.figures().items():
                out[f"{name}.{key}" if key in out or key in metrics or key in run_keys else key] = value
        return out


def _median_p99(quantiles: Quantiles | None) -> dict | None:
    if quantiles is None or not quantiles.n:
        return None
    return {"median": quantiles.quantile(0.5), "p99": quantiles.quantile(0.99)}

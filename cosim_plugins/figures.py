"""The swimmer's summary figures of every run (all in mm or ms), registered as a figure set.

* ``estimation_error_mm``: distance of the estimate to the true position, {mean, std, max};
* ``prediction_error_mm``: per-axis mean absolute and Euclidean RMS of the
  estimator's innovation (measurement minus prediction at each frame),
  {x, y, z, rmse, frames};
* ``solve_ms``: the controller's computation per step, {median, p99};
* ``detection_error_mm``: distance of each measurement to the true position
  at its capture time (the ``capture_time`` role; a camera without one is
  taken to deliver at capture), {median, p99}.

They are computed as the run goes: the means, spreads and maxima equal the
whole run's up to rounding, the medians and p99 are within a relative 5e-4 of
``np.percentile``'s (the framework's streaming statistics); the detection
error keeps :data:`HISTORY_S` of the true position to interpolate it at each
measurement's capture time. :meth:`SwimmerFigures.exact` computes them
exactly from a whole trace. The framework adds ``tracking_error_mm`` before them.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

from cosim.api import Moments, Quantiles
from cosim.contract.figures import FigureSet, error_stats

#: how far back [s of simulated time] a measurement's capture time may lie behind its row
HISTORY_S = 10.0


def detection_error_m(measured_m: np.ndarray, truth_m: np.ndarray, t_s: np.ndarray,
                      capture_time_s: np.ndarray | None = None) -> np.ndarray:
    """Distance [m] of each measurement (n, 3) to the truth (n, 3) at its capture time.

    ``t_s`` (n,): the rows' times; ``capture_time_s`` (n,): when each row's
    measurement was captured (NaN or absent: at the row's own time); the
    truth is interpolated linearly between rows. NaN where no measurement.
    """
    if not len(t_s):  # a run stopped before its first step
        return np.zeros(0)
    at = t_s if capture_time_s is None else np.where(np.isfinite(capture_time_s), capture_time_s, t_s)
    truth_at = np.stack([np.interp(at, t_s, truth_m[:, i]) for i in range(3)], axis=1)
    return np.linalg.norm(measured_m - truth_at, axis=1)


def _quantiles(values: np.ndarray) -> dict | None:
    """{median, p99} of the finite ``values``, None if there is none."""
    v = values[np.isfinite(values)]
    if not len(v):
        return None
    return {"median": float(np.median(v)), "p99": float(np.percentile(v, 99))}


def _median_p99(quantiles: Quantiles | None) -> dict | None:
    if quantiles is None or not quantiles.n:
        return None
    return {"median": quantiles.quantile(0.5), "p99": quantiles.quantile(0.99)}


def _f(d: dict | None, key: str, digits: int = 2) -> str:
    return f"{d[key]:.{digits}f}" if d and d.get(key) is not None else "-"


def _pm(d: dict | None) -> str:
    return f"{d['mean']:.2f} ± {d['std']:.2f}" if d else "-"


class SwimmerFigures(FigureSet):
    """The estimation, prediction and detection errors [mm] and the controller's solve time [ms] of a run."""

    keys = ("estimation_error_mm", "prediction_error_mm", "solve_ms", "detection_error_mm")

    def accumulator(self, recorder) -> "SwimmerAccumulator":
        """The figures of ``recorder``'s run, batch by batch."""
        return SwimmerAccumulator(recorder)

    def exact(self, get, t_s: np.ndarray) -> dict[str, Any]:
        """The figures of a whole trace (``get(role)``: the role's rows or None)."""
        out: dict[str, Any] = dict.fromkeys(self.keys)
        truth, estimate = get("truth"), get("estimate")
        if truth is not None and estimate is not None:
            out["estimation_error_mm"] = error_stats(np.linalg.norm(estimate - truth, axis=1) * 1e3)
        innov = get("prediction_error")
        if innov is not None:
            rows = innov[np.all(np.isfinite(innov), axis=1)] * 1e3
            if len(rows):
                mae = np.abs(rows).mean(axis=0)
                out["prediction_error_mm"] = {"x": float(mae[0]), "y": float(mae[1]), "z": float(mae[2]),
                                              "rmse": float(np.sqrt((rows**2).sum(axis=1).mean())),
                                              "frames": len(rows)}
        if get("solve_time") is not None:
            out["solve_ms"] = _quantiles(get("solve_time") * 1e3)
        if get("measured") is not None and truth is not None:
            error_m = detection_error_m(get("measured"), truth, t_s, get("capture_time"))
            out["detection_error_mm"] = _quantiles(error_m * 1e3)
        return out

    def columns(self, rows: list[dict]) -> list:
        """The estimation error, the prediction error per axis and the solve time, when a row has them."""
        cols = []
        if any(r.get("estimation_error_mm") for r in rows):
            cols.append(("estimation error [mm]", lambda r: _pm(r.get("estimation_error_mm"))))
        if any(r.get("prediction_error_mm") for r in rows):
            cols.append(("prediction x / y / z / RMSE [mm]", lambda r: "/".join(
                _f(r.get("prediction_error_mm"), k) for k in ("x", "y", "z", "rmse"))))
        if any(r.get("solve_ms") for r in rows):
            cols.append(("solve median / p99 [ms]", lambda r: "/".join(
                _f(r.get("solve_ms"), k, 3) for k in ("median", "p99"))))
        return cols


class SwimmerAccumulator:
    """:class:`SwimmerFigures` of one run, accumulated batch by batch."""

    def __init__(self, recorder):
        has = {role: recorder.signal(role, 0, 0) is not None for role in
               ("truth", "estimate", "prediction_error", "solve_time", "measured", "capture_time")}
        self.estimation = Moments() if has["truth"] and has["estimate"] else None
        self.innovation = np.zeros(4) if has["prediction_error"] else None  # sums of |x|, |y|, |z| [mm], |e|^2 [mm^2]
        self.frames = 0
        self.solve = Quantiles("solve time [ms]") if has["solve_time"] else None
        self.detection = Quantiles("detection error [mm]") if has["measured"] and has["truth"] else None
        self._history_ticks = max(int(round(HISTORY_S / recorder.scenario.dt_s)), 1)
        self._history_t = np.zeros(0)
        self._history_truth = np.zeros((0, 3))
        self.too_old = 0  # measurements captured before the history kept

    def add(self, recorder, start: int, stop: int) -> None:
        """Ticks ``start:stop`` of ``recorder`` (held in its buffer)."""
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

    def figures(self) -> dict[str, Any]:
        """The run's figures so far (None: the run has none of that figure)."""
        out: dict[str, Any] = dict.fromkeys(SwimmerFigures.keys)
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
        return out

"""diagnosis.rrd: the measured trajectory coloured by the model's open-loop error.

Entities (positions in metres, as in the run recordings; time line ``sim_time``
runs through the logs one after another):

* ``world/tank``: the 150 mm tank;
* ``world/error_map``: every measured position of every log, coloured by the
  baseline's error at the reference horizon for the prediction ending there
  (grey: no prediction), static;
* ``world/swimmer``: the measured position over time, same colours;
* ``plots/error_mm/baseline`` (and ``.../with_added``), ``plots/error_mm/noise_floor``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

TANK_HALF_M = 0.075
GREY = np.array([150, 150, 150, 255], dtype=np.uint8)


def colours(err_mm: np.ndarray, vmax: float) -> np.ndarray:
    """(n, 4) uint8 RGBA: a blue-green-yellow-red ramp over 0..vmax; grey where err is NaN."""
    x = np.clip(np.nan_to_num(err_mm / max(vmax, 1e-9)), 0.0, 1.0)
    knots = np.array([[40, 70, 200], [40, 180, 120], [240, 210, 40], [220, 40, 40]], dtype=float)
    pos = x * (len(knots) - 1)
    i = np.minimum(pos.astype(int), len(knots) - 2)
    f = (pos - i)[:, None]
    rgb = knots[i] * (1 - f) + knots[i + 1] * f
    out = np.concatenate([rgb, np.full((len(x), 1), 255.0)], axis=1).astype(np.uint8)
    out[~np.isfinite(err_mm)] = GREY
    return out


def row_errors(diag, key: str) -> np.ndarray:
    """(n,) error norm [mm] attributed to each row of the timeline (the window's target row), NaN elsewhere."""
    err = diag.errors.get(key)
    out = np.full(diag.timeline.n, np.nan)
    if err is None:
        return out
    k = diag.steps[diag.result.reference_key]
    rows = diag.starts + diag.lead + k
    ok = np.all(np.isfinite(err), axis=1) & (rows < diag.timeline.n)
    out[rows[ok]] = np.linalg.norm(err[ok], axis=1)
    return out


def write_recording(diag, path: Path) -> Path:
    """Write the diagnosis as a rerun recording at ``path`` (the trajectory coloured by the error); returns it."""
    tl = diag.timeline
    rec = rr.RecordingStream(application_id="cosim_diagnose", recording_id="diagnosis")
    rec.save(str(path), default_blueprint=rrb.Blueprint(rrb.Horizontal(
        rrb.Spatial3DView(origin="world", name="error along the trajectory"),
        rrb.TimeSeriesView(origin="plots/error_mm", name="open-loop error [mm]"), column_shares=[3, 2])))
    rec.log("world/tank", rr.Boxes3D(half_sizes=[[TANK_HALF_M] * 3], colors=[[120, 160, 255, 60]]), static=True)
    t = _concatenated_time(tl)
    base = row_errors(diag, "baseline")
    vmax = float(np.nanpercentile(base, 95)) if np.isfinite(base).any() else 1.0
    meas = np.all(np.isfinite(tl.p), axis=1)
    pos_m = tl.p[meas] * 1e-3
    cols = colours(base[meas], vmax)
    rec.log("world/error_map", rr.Points3D(pos_m, colors=cols, radii=0.0006), static=True)
    rec.send_columns("world/swimmer", indexes=[rr.TimeColumn("sim_time", duration=t[meas])],
                     columns=rr.Points3D.columns(positions=pos_m, colors=cols, radii=np.full(len(pos_m), 0.0015)))
    for name, errs in (("baseline", base), ("with_added", row_errors(diag, "after"))):
        ok = np.isfinite(errs)
        if ok.any():
            rec.send_columns(f"plots/error_mm/{name}", indexes=[rr.TimeColumn("sim_time", duration=t[ok])],
                             columns=rr.Scalars.columns(scalars=errs[ok]))
    floor = diag.result.noise_floor_mm
    if floor:
        rec.send_columns("plots/error_mm/noise_floor", indexes=[rr.TimeColumn("sim_time", duration=t[[0, -1]])],
                         columns=rr.Scalars.columns(scalars=[floor, floor]))
    rec.flush()
    rec.disconnect()
    return path


def _concatenated_time(tl) -> np.ndarray:
    """(n,) a time line through all logs one after another [s] (break rows get the previous time)."""
    t = np.zeros(tl.n)
    offset, last = 0.0, 0.0
    for i in range(tl.n):
        if tl.log[i] < 0:
            offset = last + 1.0
            t[i] = last
            continue
        t[i] = offset + tl.t_s[i]
        last = t[i]
    return t

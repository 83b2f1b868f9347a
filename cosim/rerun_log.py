"""The run's rerun recording: one function per thing logged, the blueprint in one place.

Everything is sent in columns (``send_columns``) on the ``sim_time``
timeline, one call per entity, so a 290 s run costs a few calls, not one
per tick. Positions are in metres (the 3D view shows the tank in m).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

TANK_HALF_M = 0.075
AXIS_LEN_M = 0.006  # the swimmer's length
FIELD_SCALE_M_PER_T = 5.0  # 1 mT draws 5 mm
PATH_LOG_HZ = 10.0


def blueprint() -> rrb.Blueprint:
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name="tank"),
            rrb.Vertical(
                rrb.TimeSeriesView(origin="plots/tracking_error_mm", name="tracking error [mm]"),
                rrb.TimeSeriesView(origin="plots/omega", name="omega [rad/s]"),
                rrb.TimeSeriesView(origin="plots/coil_current", name="coil current amplitude [A]"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def _time(t_s: np.ndarray) -> list:
    return [rr.TimeColumn("sim_time", duration=t_s)]


def log_tank(rec: rr.RecordingStream) -> None:
    rec.log("world/tank", rr.Boxes3D(half_sizes=[[TANK_HALF_M] * 3], colors=[[120, 160, 255, 60]]), static=True)


def log_path(rec: rr.RecordingStream, path, t_s: np.ndarray) -> None:
    if path is None:
        return
    if not path.time_varying:
        rec.log("world/path", rr.LineStrips3D([path.points(0.0)], colors=[[255, 200, 0]]), static=True)
        return
    step = max(int(round(1.0 / (PATH_LOG_HZ * (t_s[1] - t_s[0])))), 1) if len(t_s) > 1 else 1
    for t in t_s[::step]:
        rec.set_time("sim_time", duration=float(t))
        rec.log("world/path", rr.LineStrips3D([path.points(float(t))], colors=[[255, 200, 0]]))


def log_points(rec, entity: str, t_s: np.ndarray, positions_m: np.ndarray, color, radius_m: float) -> None:
    keep = np.all(np.isfinite(positions_m), axis=1)
    if not keep.any():
        return
    rec.log(entity, rr.Points3D.from_fields(colors=[color], radii=[radius_m]), static=True)
    rec.send_columns(entity, indexes=_time(t_s[keep]), columns=rr.Points3D.columns(positions=positions_m[keep]))


def log_arrows(rec, entity: str, t_s, origins_m, vectors_m, color) -> None:
    keep = np.all(np.isfinite(origins_m), axis=1) & np.all(np.isfinite(vectors_m), axis=1)
    if not keep.any():
        return
    rec.log(entity, rr.Arrows3D.from_fields(colors=[color]), static=True)
    rec.send_columns(entity, indexes=_time(t_s[keep]),
                     columns=rr.Arrows3D.columns(origins=origins_m[keep], vectors=vectors_m[keep]))


def log_scalars(rec, entity: str, t_s: np.ndarray, values: np.ndarray) -> None:
    keep = np.isfinite(values)
    if keep.any():
        rec.send_columns(entity, indexes=_time(t_s[keep]), columns=rr.Scalars.columns(scalars=values[keep]))


def write_recording(recorder, out_path: Path) -> None:
    """Write ``out_path`` (.rrd) from a :class:`~cosim.recorder.TraceRecorder`."""
    rec = rr.RecordingStream(application_id="cosim", recording_id=recorder.scenario.name)
    rec.save(str(out_path), default_blueprint=blueprint())
    n = recorder.ticks
    t_s = recorder.t_s[:n]
    log_tank(rec)
    log_path(rec, recorder.path, t_s)
    truth = recorder.signal("truth")
    if truth is not None:
        log_points(rec, "world/swimmer/true", t_s, truth, [40, 200, 80], 1.25e-3)
        axis = recorder.signal("axis")
        if axis is not None:
            log_arrows(rec, "world/swimmer/axis", t_s, truth, axis * AXIS_LEN_M, [40, 200, 80])
        field = recorder.signal("field")
        if field is not None:
            log_arrows(rec, "world/field", t_s, truth, field * FIELD_SCALE_M_PER_T, [230, 80, 230])
    for role, color in (("measured", [255, 80, 60]), ("estimate", [60, 140, 255])):
        sig = recorder.signal(role)
        if sig is not None:
            log_points(rec, f"world/swimmer/{'measured' if role == 'measured' else 'estimated'}",
                       t_s, sig, color, 0.8e-3)
    if recorder.tracking_error_m is not None:
        log_scalars(rec, "plots/tracking_error_mm", t_s, recorder.tracking_error_m * 1e3)
    omega = recorder.signal("omega")
    if omega is not None:
        for i, axis_name in enumerate("xyz"):
            log_scalars(rec, f"plots/omega/{axis_name}", t_s, omega[:, i])
    current = recorder.signal("coil_current")
    if current is not None:
        for i in range(current.shape[1]):
            log_scalars(rec, f"plots/coil_current/{i + 1}", t_s, current[:, i])
    rec.flush()
    rec.disconnect()

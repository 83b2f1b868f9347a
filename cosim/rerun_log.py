"""The run's rerun recording, written as the run goes: one function per thing logged, the blueprint in one place.

:class:`RecordingWriter` opens the ``.rrd`` file at the start of a run and
appends each batch of ticks the recorder hands it (about one a second), so
a run that is stopped or killed keeps what was recorded. Everything is sent
in columns (``send_columns``) on the ``sim_time`` timeline, one call per
entity and batch, not one per tick. Positions are in metres (the 3D view
shows the tank in m). Faults and stops are logged as text under ``events``.
A component that logs something of its own (camera images) streams it to a
part beside it (:func:`component_recording`) that joins it when the run ends
(:func:`merge_parts`); the layout has the views it asks for.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

APPLICATION_ID = "cosim"
TIMELINE = "sim_time"  # simulated time [s], the timeline of every file of a run's recording
TANK_HALF_M = 0.075
AXIS_LEN_M = 0.006  # the swimmer's length
FIELD_SCALE_M_PER_T = 5.0  # 1 mT draws 5 mm
PATH_LOG_HZ = 10.0
MERGE_TIMEOUT_S = 600.0


def blueprint(views: list | tuple = ()) -> rrb.Blueprint:
    """The layout: the 3D view, the plots, and a column of the ``views`` components add."""
    columns = [
        rrb.Spatial3DView(origin="world", name="tank"),
        rrb.Vertical(
            rrb.TimeSeriesView(origin="plots/tracking_error_mm", name="tracking error [mm]"),
            rrb.TimeSeriesView(origin="plots/omega", name="omega [rad/s]"),
            rrb.TimeSeriesView(origin="plots/coil_current", name="coil current amplitude [A]"),
            rrb.TextLogView(origin="events", name="faults and stops"),
            row_shares=[3, 3, 3, 1],
        ),
    ]
    if views:
        columns.append(rrb.Vertical(*views))
    return rrb.Blueprint(rrb.Horizontal(*columns, column_shares=[3, 2, 2][: len(columns)]),
                         collapse_panels=True)


def component_recording(run_dir: Path, recording_id: str, component: str) -> rr.RecordingStream:
    """A component's own part of the run's recording, streamed to ``run_dir/recording.<component>.rrd``.

    It shares the run's application and recording ids, so the viewer opened on
    the run folder's ``recording*.rrd`` files shows one recording (rerun merges
    files by recording id, https://rerun.io/docs/howto/shared-recordings) under
    the layout of ``recording.rrd``; when the run ends, :func:`merge_parts` folds
    it into ``recording.rrd``. Log on the :data:`TIMELINE` timeline.
    """
    rec = rr.RecordingStream(application_id=APPLICATION_ID, recording_id=recording_id)
    rec.save(str(Path(run_dir) / f"recording.{component}.rrd"))
    return rec


def merge_parts(run_dir: Path) -> list[Path]:
    """Fold the parts components recorded (``recording.<component>.rrd``) into ``recording.rrd``
    once the run is over (``rerun rrd merge``), so the run has one recording file; returns the
    parts merged. If merging fails the parts stay (``cosim replay`` opens them with it) and a
    line says why."""
    run_dir = Path(run_dir)
    main, parts = run_dir / "recording.rrd", sorted(Path(run_dir).glob("recording.*.rrd"))
    if not parts or not main.is_file():
        return []
    merged = run_dir / "recording.rrd.merging"
    try:
        done = subprocess.run([sys.executable, "-m", "rerun", "rrd", "merge", str(main), *map(str, parts),
                               "-o", str(merged)], capture_output=True, text=True, timeout=MERGE_TIMEOUT_S)
        reason = None if done.returncode == 0 else (done.stderr.strip().splitlines() or ["no output"])[-1]
    except subprocess.TimeoutExpired:
        reason = f"it took over {MERGE_TIMEOUT_S:g} s"
    if reason is not None or not merged.is_file():
        merged.unlink(missing_ok=True)
        print(f"cosim: recording parts {', '.join(p.name for p in parts)} kept beside recording.rrd "
              f"(merging failed: {reason or 'rerun wrote no file'})", file=sys.stderr)
        return []
    os.replace(merged, main)
    for part in parts:
        part.unlink()
    return parts


def _time(t_s: np.ndarray) -> list:
    return [rr.TimeColumn(TIMELINE, duration=t_s)]


def log_path(rec: rr.RecordingStream, path, t_s: np.ndarray, ticks: np.ndarray, dt_s: float) -> None:
    """A moving path at ``PATH_LOG_HZ``: at those of ``ticks`` (n,), times ``t_s`` (n,), on that grid."""
    if path is None or not path.time_varying:
        return
    step = max(int(round(1.0 / (PATH_LOG_HZ * dt_s))), 1)
    for t in t_s[ticks % step == 0]:
        rec.set_time(TIMELINE, duration=float(t))
        rec.log("world/path", rr.LineStrips3D([path.points(float(t))], colors=[[255, 200, 0]]))


def log_points(rec, entity: str, t_s: np.ndarray, positions_m: np.ndarray) -> None:
    keep = np.all(np.isfinite(positions_m), axis=1)
    if keep.any():
        rec.send_columns(entity, indexes=_time(t_s[keep]), columns=rr.Points3D.columns(positions=positions_m[keep]))


def log_arrows(rec, entity: str, t_s, origins_m, vectors_m) -> None:
    keep = np.all(np.isfinite(origins_m), axis=1) & np.all(np.isfinite(vectors_m), axis=1)
    if keep.any():
        rec.send_columns(entity, indexes=_time(t_s[keep]),
                         columns=rr.Arrows3D.columns(origins=origins_m[keep], vectors=vectors_m[keep]))


def log_scalars(rec, entity: str, t_s: np.ndarray, values: np.ndarray) -> None:
    keep = np.isfinite(values)
    if keep.any():
        rec.send_columns(entity, indexes=_time(t_s[keep]), columns=rr.Scalars.columns(scalars=values[keep]))


#: the run's points and arrows: (entity, recorded role, colour, point radius [m] or None for an arrow)
STYLES = (
    ("world/swimmer/true", "truth", [40, 200, 80], 1.25e-3),
    ("world/swimmer/measured", "measured", [255, 80, 60], 0.8e-3),
    ("world/swimmer/estimated", "estimate", [60, 140, 255], 0.8e-3),
    ("world/swimmer/axis", "axis", [40, 200, 80], None),
    ("world/field", "field", [230, 80, 230], None),
)


class RecordingWriter:
    """The ``.rrd`` file of one run, appended batch by batch (see the module docstring)."""

    def __init__(self, out_path: Path, recording_id: str, path=None, views: list | tuple = ()):
        self.path = path
        self.rec = rec = rr.RecordingStream(application_id=APPLICATION_ID, recording_id=recording_id)
        rec.save(str(out_path), default_blueprint=blueprint(views))
        rec.log("world/tank", rr.Boxes3D(half_sizes=[[TANK_HALF_M] * 3], colors=[[120, 160, 255, 60]]),
                static=True)
        if path is not None and not path.time_varying:
            rec.log("world/path", rr.LineStrips3D([path.points(0.0)], colors=[[255, 200, 0]]), static=True)
        self._styled: set[str] = set()
        rec.flush()

    def append(self, recorder, start: int, stop: int, tracking_error_m: np.ndarray | None) -> None:
        """Ticks ``start:stop`` of a :class:`~cosim.recorder.TraceRecorder`, with their
        tracking error (stop - start,) [m] if there is a path."""
        rec, t_s = self.rec, recorder.t_s[start:stop]
        log_path(rec, self.path, t_s, np.arange(start, stop), recorder.scenario.dt_s)
        sig = {role: recorder.signal(role, start, stop) for _, role, _, _ in STYLES}
        for entity, role, color, radius in STYLES:
            if sig[role] is None or (not radius and sig["truth"] is None):
                continue
            if entity not in self._styled:
                self._styled.add(entity)
                rec.log(entity, rr.Points3D.from_fields(colors=[color], radii=[radius]) if radius
                        else rr.Arrows3D.from_fields(colors=[color]), static=True)
            if radius:
                log_points(rec, entity, t_s, sig[role])
            else:
                scale = AXIS_LEN_M if role == "axis" else FIELD_SCALE_M_PER_T
                log_arrows(rec, entity, t_s, sig["truth"], sig[role] * scale)
        if tracking_error_m is not None:
            log_scalars(rec, "plots/tracking_error_mm", t_s, tracking_error_m * 1e3)
        omega = recorder.signal("omega", start, stop)
        if omega is not None:
            for i, axis_name in enumerate("xyz"):
                log_scalars(rec, f"plots/omega/{axis_name}", t_s, omega[:, i])
        current = recorder.signal("coil_current", start, stop)
        if current is not None:
            for i in range(current.shape[1]):
                log_scalars(rec, f"plots/coil_current/{i + 1}", t_s, current[:, i])
        rec.flush(timeout_sec=0.0)

    def event(self, t_s: float, text: str, level: str = "WARN") -> None:
        """A fault or a stop, shown in the viewer's log panel at ``t_s``."""
        self.rec.set_time(TIMELINE, duration=float(t_s))
        self.rec.log("events", rr.TextLog(text, level=level))

    def close(self) -> None:
        self.rec.flush()
        self.rec.disconnect()

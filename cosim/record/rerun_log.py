"""The run's rerun recording, written as the run goes: one function per thing logged, the blueprint in one place.

:class:`RecordingWriter` opens the ``.rrd`` file at the start of a run and
appends each batch of ticks the recorder hands it (about one a second), so
a run that is stopped or killed keeps what was recorded. Everything is sent
in columns (``send_columns``) on the ``sim_time`` timeline, one call per
entity and batch, not one per tick. The framework draws the reference path
under ``world/`` and the tracking error when the run has a path; the domain's
views (:mod:`cosim.contract.views`) draw the rest (its recorded positions, say). Faults and stops are logged as
text under ``events``. A component that logs something of its own (a
sensor's images) streams it to a part beside it (:func:`component_recording`) that
joins it when the run ends (:func:`merge_parts`); the layout has the views it
asks for.

The files are written without rerun's footer (:data:`WRITE_FOOTER`): to write one,
rerun keeps a manifest entry for every chunk sent until the file closes, which
grows with the run's length (see :func:`save`).
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
PATH_LOG_HZ = 10.0
MERGE_TIMEOUT_S = 600.0
#: Whether a run's ``.rrd`` files end with rerun's footer, a manifest of every chunk. Off: rerun keeps
#: that manifest in memory for the whole life of the file (about 0.5 kB per chunk; a loop of a
#: dozen components sends ~15 chunks per batch, one batch a second of wall time, so ~20 MB over a
#: 12 h run with ``--processes``) and builds the footer from it when the file closes. Without it the file is a
#: whole recording that the viewer opens as before (rerun's own reader scans it instead of reading
#: its manifest); ``rerun rrd optimize`` can add a footer afterwards (it reads the whole file).
WRITE_FOOTER = False


def blueprint(spatial: bool, plots: list | tuple = (), views: list | tuple = ()) -> rrb.Blueprint:
    """The layout: the 3D view (``spatial``), a column of the tracking error, the domain's ``plots``
    and the events, and a column of the ``views`` components add."""
    column = [*plots, rrb.TextLogView(origin="events", name="faults and stops")]
    columns = [rrb.Vertical(*column, row_shares=[3] * (len(column) - 1) + [1])]
    if spatial:
        columns.insert(0, rrb.Spatial3DView(origin="world", name="world"))
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
    save(rec, Path(run_dir) / f"recording.{component}.rrd")
    return rec


def save(rec: rr.RecordingStream, path: Path, default_blueprint: rrb.Blueprint | None = None) -> None:
    """Stream ``rec`` to the file ``path``, with a footer only if :data:`WRITE_FOOTER`. rerun warns on
    standard error about every file it writes without one; that is this module's choice, so the line
    is kept off standard error (for the length of this call only)."""
    if WRITE_FOOTER:
        rec.save(str(path), default_blueprint=default_blueprint, write_footer=True)
        return
    sys.stderr.flush()
    saved, null = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        rec.save(str(path), default_blueprint=default_blueprint, write_footer=False)
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


def set_aside_parts(run_dir: Path) -> list[Path]:
    """Rename the recording parts already in ``run_dir`` (``recording.<component>.rrd``: an earlier
    run's, in a folder this run now writes) to ``earlier.recording.<component>.rrd``, so that
    :func:`merge_parts` and ``cosim replay`` never take them for this run's; returns their new paths
    and says so on stderr."""
    moved = []
    for part in sorted(Path(run_dir).glob("recording.*.rrd")):
        if part.is_file() and not part.is_symlink():
            target = part.with_name(f"earlier.{part.name}")
            os.replace(part, target)
            moved.append(target)
    if moved:
        print(f"cosim: set aside {len(moved)} recording part(s) of an earlier run in {run_dir}: "
              f"{', '.join(p.name for p in moved)}", file=sys.stderr)
    return moved


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
    """Send the finite rows of ``positions_m`` (n, 3) [m] at times ``t_s`` (n,) [s] as 3D points."""
    keep = np.all(np.isfinite(positions_m), axis=1)
    if keep.any():
        rec.send_columns(entity, indexes=_time(t_s[keep]), columns=rr.Points3D.columns(positions=positions_m[keep]))


def log_arrows(rec, entity: str, t_s, origins_m, vectors_m) -> None:
    """Send arrows from ``origins_m`` along ``vectors_m`` (both (n, 3) [m]) at ``t_s`` (n,) [s], finite rows only."""
    keep = np.all(np.isfinite(origins_m), axis=1) & np.all(np.isfinite(vectors_m), axis=1)
    if keep.any():
        rec.send_columns(entity, indexes=_time(t_s[keep]),
                         columns=rr.Arrows3D.columns(origins=origins_m[keep], vectors=vectors_m[keep]))


def log_scalars(rec, entity: str, t_s: np.ndarray, values: np.ndarray) -> None:
    """Send the finite values of ``values`` (n,) at times ``t_s`` (n,) [s] as a time series."""
    keep = np.isfinite(values)
    if keep.any():
        rec.send_columns(entity, indexes=_time(t_s[keep]), columns=rr.Scalars.columns(scalars=values[keep]))


class RecordingWriter:
    """The ``.rrd`` file of one run, appended batch by batch (see the module docstring).

    ``recorder``: the :class:`~cosim.runtime.recorder.TraceRecorder`; ``views``: the domain's
    views that apply to the run; ``component_views``: the blueprint views components add.
    """

    def __init__(self, out_path: Path, recorder, views: list | tuple = (), component_views: list | tuple = ()):
        self.recorder, self.views, self.path = recorder, list(views), recorder.path
        plots = [rrb.TimeSeriesView(origin="plots/tracking_error_mm", name="tracking error [mm]")] \
            if recorder.tracks_path else []
        plots += [v for view in self.views for v in view.layout()]
        self.rec = rec = rr.RecordingStream(application_id=APPLICATION_ID,
                                            recording_id=recorder.scenario.recording_id)
        spatial = any(view.spatial for view in self.views)  # a view draws into the 3D world
        save(rec, Path(out_path), blueprint(spatial, plots, component_views))
        if self.path is not None and not self.path.time_varying:
            rec.log("world/path", rr.LineStrips3D([self.path.points(0.0)], colors=[[255, 200, 0]]), static=True)
        for view in self.views:
            view.start(rec, recorder)
        rec.flush()

    def append(self, start: int, stop: int, tracking_error_m: np.ndarray | None) -> None:
        """Ticks ``start:stop`` of the recorder, with their tracking error (stop - start,) [m] if
        there is a path."""
        rec, recorder = self.rec, self.recorder
        t_s = recorder.t_s[start:stop]
        log_path(rec, self.path, t_s, np.arange(start, stop), recorder.scenario.dt_s)
        if tracking_error_m is not None:
            log_scalars(rec, "plots/tracking_error_mm", t_s, tracking_error_m * 1e3)
        for view in self.views:
            view.draw(rec, recorder, start, stop, t_s)
        rec.flush(timeout_sec=0.0)

    def event(self, t_s: float, text: str, level: str = "WARN") -> None:
        """A fault or a stop, shown in the viewer's log panel at ``t_s``."""
        self.rec.set_time(TIMELINE, duration=float(t_s))
        self.rec.log("events", rr.TextLog(text, level=level))

    def close(self) -> None:
        self.rec.flush()
        self.rec.disconnect()

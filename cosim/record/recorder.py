"""Observers that record a run, and the files they write as it goes.

:class:`TraceRecorder` keeps every port's value at every tick in memory
(preallocated arrays, for the run's figures) and writes them out as the run
goes, in batches: the log and the trace at least every ``FLUSH_EVERY_S`` of
wall time and of simulated time, the recording every ``FLUSH_EVERY_S`` of
wall time:

* the files the domain's views write (:mod:`cosim.record.views`, e.g. a
  raw log in the domain's own format);
* ``trace.part``: every port's rows so far (float64, the layout in
  ``trace.part.json``), turned into ``trace.npz`` when the run ends (the full
  trace: ``t_s`` plus one array per ``component.port``, shape
  (ticks, *port shape), SI units) and then removed;
* ``recording.rrd``: the rerun recording (see :mod:`cosim.record.rerun_log`); a
  component that logs images or the like itself writes its part next to it
  (``recording.<component>.rrd``, the same recording id), and its views join
  the layout here.

So a run stopped, failed or killed keeps what it recorded: a killed
process loses at most the last batch; :func:`load_trace` reads a
``trace.part`` left behind.
"""

from __future__ import annotations

import contextlib
import json
import time
from pathlib import Path

import numpy as np

from cosim.contract.errors import OutputWriteError
from cosim.runtime.portcache import port_slots
from cosim.runtime.wiring import Wiring
from cosim.scenario.paths import distance_to_path
from cosim.scenario.schema import Scenario

#: longest stretch of wall time, and of simulated time [s], not yet written out
FLUSH_EVERY_S = 1.0


class TraceRecorder:
    """Keeps every component's outputs at every tick and writes ``trace.npz`` and the views' files."""
    def __init__(self, scenario: Scenario, wiring: Wiring, out_dir: Path, path=None):
        self.scenario, self.wiring, self.out_dir, self.path = scenario, wiring, Path(out_dir), path
        n = scenario.n_steps
        self.t_s = np.arange(n) * scenario.dt_s
        #: per component, every output at every tick: (n, width) float64, the ports laid end to end
        self.rows = {c: np.full((n, sum(int(np.prod(p.shape)) for p in ports)), np.nan)
                     for c in wiring.order if (ports := wiring.outputs[c])}
        #: every port's (n, *shape) view into its component's rows, by (component, port)
        self.arrays = {key: view for c in self.rows for key, view in _port_views(c, wiring.outputs[c], self.rows[c])}
        self.ticks = 0  # ticks recorded
        self.written = 0  # ticks written to the log and the trace
        self.drawn = 0  # ticks written to the recording
        self.closed = False
        self.files: dict[str, Path] = {}
        self.tracking_error_m = np.full(n, np.nan)  # (n,) distance of truth to path [m], as far as drawn
        self.roles = scenario.record.ports()  # {role: "component.port" or None}
        truth = self.signal("truth", 0, 0)
        #: whether the run has a tracking error: a path, and a ``truth`` role recording positions
        self.tracks_path = path is not None and truth is not None and truth.shape[1:] == (3,)
        #: the layout's views the components add for what they log themselves
        self.views = [v for c in wiring.order for v in wiring.classes[c].recording_views(c)]
        self._batch_ticks = max(int(round(FLUSH_EVERY_S / scenario.dt_s)), 1)
        self._last_write = time.monotonic()
        self._part = self._rrd = None
        self._files: dict = {}  # the views' files, by key
        self._file_ticks: dict = {}  # ticks written to each of them, by key

    def open(self) -> None:
        """Create the output files (headers only); called before the first tick."""
        from cosim.record import rerun_log
        from cosim.record.views import registered_views

        self.out_dir.mkdir(parents=True, exist_ok=True)
        run_views = [view for view in registered_views().values() if view.applies(self)]
        for view in run_views:
            self._files.update(view.open_files(self, self.out_dir))
        self.files.update({key: file.path for key, file in self._files.items()})
        layout = [[f"{c}.{p}", list(a.shape[1:])] for (c, p), a in self.arrays.items()]
        (self.out_dir / "trace.part.json").write_text(json.dumps({"dtype": "<f8", "columns": [["t_s", []], *layout]}))
        self._part = open(self.out_dir / "trace.part", "wb")
        self._rrd = rerun_log.RecordingWriter(self.out_dir / "recording.rrd", self, run_views, self.views)
        self.files["recording"] = self.out_dir / "recording.rrd"

    def on_tick(self, tick: int, t: float, rows: dict[str, np.ndarray]) -> None:
        """``rows``: each component's outputs at ``tick`` (flat, the ports laid end to end); a
        component missing from it (its step failed) stays NaN."""
        if self.closed:
            return
        for comp, row in rows.items():
            self.rows[comp][tick] = row
        self.ticks = tick + 1
        if time.monotonic() - self._last_write >= FLUSH_EVERY_S:
            self.write_out(recording=True)
        elif self.ticks - self.written >= self._batch_ticks:
            self.write_out(recording=False)

    def signal(self, role: str, start: int = 0, stop: int | None = None) -> np.ndarray | None:
        """The recorded array of a role of ``scenario.record`` (e.g. 'truth'), rows ``start:stop``
        (default: up to the ticks run); None when the role is unbound or its port is not recorded."""
        ref = self.roles.get(role)
        if not ref:
            return None
        comp, _, port = ref.partition(".")
        arr = self.arrays.get((comp, port))
        return None if arr is None else arr[start: self.ticks if stop is None else stop]

    def write_out(self, recording: bool = True) -> None:
        """Append the ticks recorded since the last call to the log and the trace
        (and, with ``recording``, to the rerun recording)."""
        if self._part is None:
            return
        start, stop = self.written, self.ticks
        if stop > start:
            t_s = self.t_s[start:stop]
            for key, file in self._files.items():  # each from where it stands: a retry after a failed write
                begin = self._file_ticks.get(key, start)  # appends no row twice
                if stop > begin:
                    with _writing(file.path):
                        file.append(self, begin, stop)
                    self._file_ticks[key] = stop
            table = np.hstack([t_s[:, None], *(rows[start:stop] for rows in self.rows.values())])
            with _writing(self.out_dir / "trace.part"):
                self._part.write(np.ascontiguousarray(table, dtype="<f8").tobytes())
                self._part.flush()
            self.written = stop
        if recording:
            self._last_write = time.monotonic()
            start = self.drawn
            if stop > start:
                error = None
                if self.tracks_path:
                    error = self.tracking_error_m[start:stop] = distance_to_path(
                        self.path, self.signal("truth", start, stop), self.t_s[start:stop])
                self._rrd.append(start, stop, error)
                self.drawn = stop

    def security_event(self, text: str) -> None:
        """Log a dropped sample or reply (see :mod:`cosim.runtime.node`) in the recording's event log, at
        the last tick recorded; a no-op once the files are closed."""
        if self._rrd is not None and not self.closed:
            self._rrd.event(max(self.ticks - 1, 0) * self.scenario.dt_s, f"security: {text}", "WARN")

    def finish(self, error: str | None, event: str | None = None) -> None:
        """Write the rest and close the files; ``event`` (a fault or a stop) goes into the recording.

        A file that cannot be written (a full disk) does not keep the others from being written and
        closed; the first such failure is raised afterwards as an
        :class:`~cosim.contract.errors.OutputWriteError`, and ``trace.part`` stays unless
        ``trace.npz`` was written."""
        if self.closed:
            return
        self.closed = True
        if self._part is None:
            self.open()
        failures = []
        try:
            self.write_out()
        except OutputWriteError as exc:
            failures.append(exc)
        if event:
            self._rrd.event(self.ticks * self.scenario.dt_s, event, "ERROR" if error else "WARN")
        self._rrd.close()
        for path, close in [*((f.path, f.close) for f in self._files.values()),
                            (self.out_dir / "trace.part", self._part.close)]:
            try:
                with _writing(path):
                    close()
            except OutputWriteError as exc:
                failures.append(exc)
        n = self.ticks
        trace = {f"{c}.{p}": a[:n] for (c, p), a in self.arrays.items()}
        try:
            with _writing(self.out_dir / "trace.npz"):
                np.savez_compressed(self.out_dir / "trace.npz", t_s=self.t_s[:n], **trace)
            self.files["trace"] = self.out_dir / "trace.npz"
            (self.out_dir / "trace.part").unlink()
            (self.out_dir / "trace.part.json").unlink()
        except OutputWriteError as exc:
            failures.append(exc)
        if failures:
            raise failures[0]
        if not self.tracks_path:
            self.tracking_error_m = None
        else:
            self.tracking_error_m = self.tracking_error_m[:n]


@contextlib.contextmanager
def _writing(path: Path):
    """Turn an OSError while writing ``path`` into an :class:`OutputWriteError` naming it."""
    try:
        yield
    except OSError as exc:
        raise OutputWriteError(path, exc) from exc


def _port_views(comp: str, ports, rows: np.ndarray):
    """``((comp, port), (n, *shape) view)`` of each port into its component's ``rows`` (n, width)."""
    for port, (start, end, _) in zip(ports, port_slots(ports)):
        view = rows[:, start] if port.shape == () else rows[:, start:end].reshape(len(rows), *port.shape)
        if not np.may_share_memory(view, rows):  # a copy would never see the ticks recorded
            raise AssertionError(f"{comp}.{port.name}: not a view of the component's rows")
        yield (comp, port.name), view


def load_trace(run_dir: str | Path) -> dict[str, np.ndarray]:
    """A run's trace: ``trace.npz``, or the ``trace.part`` of a run that was killed.

    Returns ``{"t_s": (n,), "component.port": (n, *shape), ...}``.
    """
    run_dir = Path(run_dir)
    if (run_dir / "trace.npz").is_file():
        with np.load(run_dir / "trace.npz") as data:
            return {k: data[k] for k in data.files}
    part, layout = run_dir / "trace.part", run_dir / "trace.part.json"
    if not (part.is_file() and layout.is_file()):
        from cosim.contract.errors import UserError

        raise UserError(f"run {run_dir}: no trace.npz (nor a trace.part of a run that was cut short)")
    columns = json.loads(layout.read_text())["columns"]
    widths = [int(np.prod(shape)) for _, shape in columns]
    flat = np.frombuffer(part.read_bytes(), dtype="<f8")
    rows = len(flat) // sum(widths)  # a row cut by the kill is dropped
    table = flat[: rows * sum(widths)].reshape(rows, sum(widths))
    edges = np.cumsum([0, *widths])
    return {name: table[:, a:b].reshape(rows, *shape) for (name, shape), a, b in zip(columns, edges, edges[1:])}

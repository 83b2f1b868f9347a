"""Observers that record a run, and the files they write as it goes, in memory bounded whatever its length.

:class:`TraceRecorder` holds the ports' values of the ticks not yet written out
(at most one chunk: ``CHUNK_BYTES`` of rows), computes the summary's figures
as it goes (:mod:`cosim.record.figures`), and writes out as the run goes, in
batches: the log and the trace at least every ``FLUSH_EVERY_S`` of wall time
and of simulated time, the recording every ``FLUSH_EVERY_S`` of wall time and
whenever the chunk is full:

* the files the domain's views write (:mod:`cosim.contract.views`, e.g. a
  raw log in the domain's own format);
* the trace: ``trace.chunks/`` while the run goes (a chunk file per full chunk
  plus the rows of the one under way, see :mod:`cosim.record.trace_files`),
  joined into ``trace.npz`` when the run ends (the full trace: ``t_s`` plus
  one array per ``component.port``, shape (ticks, *port shape), SI units);
* ``recording.rrd``: the rerun recording (see :mod:`cosim.record.rerun_log`); a
  component that logs images or the like itself writes its part next to it
  (``recording.<component>.rrd``, the same recording id), and its views join
  the layout here.

With ``rotate_s`` the files are cut into parts of that much simulated time,
each in its own folder ``part-000/``, ``part-001/``, ... (its own recording,
trace and log; the recordings share the run's recording id, so the viewer opens
them as one). So a run stopped, failed or killed keeps what it recorded: a
killed process loses at most the last batch; :func:`load_trace` reads the
chunks left behind.
"""

from __future__ import annotations

import contextlib
import threading
import time
from pathlib import Path

import numpy as np

from cosim.contract.errors import OutputWriteError
from cosim.contract.views import registered_views
from cosim.record import rerun_log
from cosim.record.figures import RunFigures
from cosim.record.trace_files import CURRENT, ChunkedTrace, iter_trace, load_trace  # noqa: F401 (the readers live there)
from cosim.runtime.portcache import port_slots
from cosim.runtime.wiring import Wiring
from cosim.scenario.paths import distance_to_path
from cosim.scenario.schema import Scenario

#: longest stretch of wall time, and of simulated time [s], not yet written out
FLUSH_EVERY_S = 1.0
#: the rows held in memory at most [bytes]: the ticks of one chunk of the trace
CHUNK_BYTES = 16 * 2**20
#: the name of a recording part's folder, by its number
PART_DIR = "part-{:03d}"


class TickTimes:
    """The times of the ticks [s], ``tick * dt_s``, computed when sliced (no array of the run's length)."""

    def __init__(self, dt_s: float):
        self.dt_s = dt_s

    def __getitem__(self, ticks: slice) -> np.ndarray:
        if not isinstance(ticks, slice) or ticks.start is None or ticks.stop is None or ticks.step not in (None, 1):
            raise TypeError("tick times are read as a slice start:stop of ticks")
        return np.arange(ticks.start, ticks.stop) * self.dt_s


class TraceRecorder:
    """``rotate_s``: simulated time [s] per recording part (None: one part, in ``out_dir`` itself)."""

    def __init__(self, scenario: Scenario, wiring: Wiring, out_dir: Path, path=None, rotate_s: float | None = None):
        self.scenario, self.wiring, self.out_dir, self.path = scenario, wiring, Path(out_dir), path
        self.t_s = TickTimes(scenario.dt_s)
        widths = {c: sum(int(np.prod(p.shape)) for p in ports) for c in wiring.order if (ports := wiring.outputs[c])}
        #: ticks held in memory: one chunk, and at least one batch
        self._batch_ticks = max(int(round(FLUSH_EVERY_S / scenario.dt_s)), 1)
        self.capacity = max(CHUNK_BYTES // (8 * (1 + sum(widths.values()))), self._batch_ticks)
        #: per component, its outputs at the ticks held: (capacity, width) float64, the ports laid end to end;
        #: row ``tick - base`` holds tick ``tick``
        self.rows = {c: np.full((self.capacity, w), np.nan) for c, w in widths.items()}
        #: every port's (capacity, *shape) view into its component's rows, by (component, port)
        self.arrays = {key: view for c in self.rows for key, view in _port_views(c, wiring.outputs[c], self.rows[c])}
        self.base = 0  # the first tick held
        self.ticks = 0  # ticks recorded
        self.written = 0  # ticks written to the log and the trace
        self.drawn = 0  # ticks written to the recording (and into the figures)
        self.closed = False
        self.files: dict[str, Path] = {}
        self.parts: list[Path] = []  # the parts' folders, with rotate_s
        self.roles = scenario.record.ports()  # {role: "component.port" or None}
        truth = self.signal("truth", 0, 0)
        #: whether the run has a tracking error: a path, and a ``truth`` role recording positions
        self.tracks_path = path is not None and truth is not None and truth.shape[1:] == (3,)
        #: the layout's views the components add for what they log themselves
        self.views = [v for c in wiring.order for v in wiring.classes[c].recording_views(c)]
        if rotate_s is not None and not rotate_s > 0:
            raise ValueError(f"rotate_s={rotate_s}: a part must last > 0 s")
        self.part_ticks = None if rotate_s is None else max(int(round(rotate_s / scenario.dt_s)), 1)
        self.part_start = 0  # the first tick of the part under way
        #: the next tick at which the chunk is full or a new part is due
        self._cut = self.capacity if self.part_ticks is None else min(self.capacity, self.part_ticks)
        self._last_write = time.monotonic()
        self._trace = self._rrd = None
        self._files: dict = {}  # the views' files, by key
        self._file_ticks: dict = {}  # ticks written to each of the files, by key
        self._joining: list[threading.Thread] = []  # the parts' traces being joined into trace.npz
        self.figures = RunFigures(self)

    def open(self) -> None:
        """Create the output files (headers only); called before the first tick."""
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self._open_part()

    def _open_part(self) -> None:
        folder = self.out_dir
        if self.part_ticks is not None:
            folder = self.out_dir / PART_DIR.format(len(self.parts))
            folder.mkdir(parents=True, exist_ok=True)
            self.parts.append(folder)
        self.part_dir = folder
        run_views = [view for view in registered_views().values() if view.applies(self)]
        self._files = {}
        for view in run_views:
            self._files.update(view.open_files(self, folder))
        layout = [(f"{c}.{p}", a.shape[1:]) for (c, p), a in self.arrays.items()]
        self._trace = ChunkedTrace(folder, layout, self.scenario.dt_s)
        self._trace.open()
        self._trace_start = self.written  # the first tick of the trace's chunk under way
        self._rrd = rerun_log.RecordingWriter(folder / "recording.rrd", self, run_views, self.views)
        if self.part_ticks is None:
            self.files.update({key: file.path for key, file in self._files.items()})
            self.files["recording"] = folder / "recording.rrd"

    def on_tick(self, tick: int, t: float, rows: dict[str, np.ndarray]) -> None:
        """``rows``: each component's outputs at ``tick`` (flat, the ports laid end to end); a
        component missing from it (its step failed) stays NaN."""
        if self.closed:
            return
        if tick >= self._cut:  # one test a tick: the chunk is full, or a new part is due
            if self.part_ticks is not None and tick - self.part_start >= self.part_ticks:
                self._close_part()
                self.part_start = tick
                self._open_part()
            else:
                self._seal()
            self._cut = self.base + self.capacity
            if self.part_ticks is not None:
                self._cut = min(self._cut, self.part_start + self.part_ticks)
        i = tick - self.base
        for comp, row in rows.items():
            self.rows[comp][i] = row
        self.ticks = tick + 1
        if time.monotonic() - self._last_write >= FLUSH_EVERY_S:
            self.write_out(recording=True)
        elif self.ticks - self.written >= self._batch_ticks:
            self.write_out(recording=False)

    def signal(self, role: str, start: int | None = None, stop: int | None = None) -> np.ndarray | None:
        """The recorded array of a role of ``scenario.record`` (e.g. 'truth'), ticks ``start:stop``
        (default: the ticks held, from :attr:`base` up to the ticks run), shape (stop - start, *port
        shape); None when the role is unbound or its port is not recorded. Only the ticks held can
        be read: those not yet written out and drawn."""
        ref = self.roles.get(role)
        if not ref:
            return None
        comp, _, port = ref.partition(".")
        arr = self.arrays.get((comp, port))
        if arr is None:
            return None
        start = self.base if start is None else start
        stop = self.ticks if stop is None else stop
        if stop <= start:  # no tick (e.g. a shape check): (0, *port shape)
            return arr[:0]
        if start < self.base:
            raise IndexError(f"{role}: ticks {start}:{stop} asked, the recorder holds ticks from {self.base} "
                             f"(it keeps the ticks not yet written out, at most {self.capacity})")
        return arr[start - self.base: stop - self.base]

    def _held(self, start: int, stop: int) -> dict[str, np.ndarray]:
        """Every trace column at ticks ``start:stop`` (held), ``{name: (stop - start, *shape)}``."""
        a, b = start - self.base, stop - self.base
        return {"t_s": self.t_s[start:stop], **{f"{c}.{p}": arr[a:b] for (c, p), arr in self.arrays.items()}}

    def write_out(self, recording: bool = True) -> None:
        """Append the ticks recorded since the last call to the log and the trace
        (and, with ``recording``, to the rerun recording and the figures)."""
        if self._trace is None:
            return
        start, stop = self.written, self.ticks
        if stop > start:
            for key, file in self._files.items():  # each from where it stands: a retry after a failed write
                begin = self._file_ticks.get(key, start)  # appends no row twice
                if stop > begin:
                    with _writing(file.path):
                        file.append(self, begin, stop)
                    self._file_ticks[key] = stop
            a, b = start - self.base, stop - self.base
            with _writing(self._trace.dir / CURRENT):
                self._trace.append(np.hstack([self.t_s[start:stop][:, None],
                                              *(rows[a:b] for rows in self.rows.values())]))
            self.written = stop
        if recording:
            self._last_write = time.monotonic()
            start = self.drawn
            if stop > start:
                error = None
                if self.tracks_path:
                    error = distance_to_path(self.path, self.signal("truth", start, stop), self.t_s[start:stop])
                self.figures.add(self, start, stop, error)
                self._rrd.append(start, stop, error)
                self.drawn = stop

    def _seal(self) -> None:
        """Write out every tick held, seal the trace's chunk, and start holding from the next tick."""
        self.write_out(recording=True)
        self._trace.seal(self._held(self._trace_start, self.ticks))
        self._trace_start = self.ticks
        self._drop_held()

    def _drop_held(self) -> None:
        self.base = self.ticks
        for rows in self.rows.values():
            rows.fill(np.nan)

    def security_event(self, text: str) -> None:
        """Log a dropped sample or reply (see :mod:`cosim.runtime.node`) in the recording's event log, at
        the last tick recorded; a no-op once the files are closed."""
        if self._rrd is not None and not self.closed:
            self._rrd.event(max(self.ticks - 1, 0) * self.scenario.dt_s, f"security: {text}", "WARN")

    def _close_part(self, last: bool = False) -> None:
        """Write out and close the files of the part under way; its trace.npz is made from its chunks
        (in a thread while the run goes on, unless it is the ``last``). A file that cannot be written (a
        full disk) keeps none of the others from being closed; the first failure is raised at the end."""
        failures = []
        try:
            self.write_out(recording=True)
        except OutputWriteError as exc:
            failures.append(exc)
        self._rrd.close()
        for file in self._files.values():
            try:
                with _writing(file.path):
                    file.close()
            except OutputWriteError as exc:
                failures.append(exc)
        held = self._held(self._trace_start, self.ticks)
        if last:  # joined here, from the rows held: nothing else writes into them any more
            for job in self._joining:
                job.join()
            try:
                with _writing(self.part_dir / "trace.npz"):
                    self._trace.finish(held, self.part_dir / "trace.npz")
            except OutputWriteError as exc:
                failures.append(exc)
        else:  # joined in a thread, from a copy of the rows held (the next part's ticks overwrite them)
            rest = {k: np.array(v) for k, v in held.items()}
            job = threading.Thread(target=self._trace.finish, args=(rest, self.part_dir / "trace.npz"),
                                   name="cosim-trace-join", daemon=False)
            job.start()
            self._joining = [j for j in self._joining if j.is_alive()] + [job]
        self._drop_held()
        if self.part_ticks is None:
            self.files["trace"] = self.part_dir / "trace.npz"
        if failures:
            raise failures[0]

    def finish(self, error: str | None, event: str | None = None) -> None:
        """Write the rest and close the files; ``event`` (a fault or a stop) goes into the recording."""
        if self.closed:
            return
        self.closed = True
        if self._trace is None:
            self.open()
        failure = None
        try:
            self.write_out()
        except OutputWriteError as exc:
            failure = exc
        if event:
            self._rrd.event(self.ticks * self.scenario.dt_s, event, "ERROR" if error else "WARN")
        try:
            self._close_part(last=True)
        except OutputWriteError as exc:
            failure = failure or exc
        if failure is not None:
            raise failure

    def file_names(self) -> dict:
        """summary.json's ``files``: each file's name (with ``rotate_s``, ``{"parts": [folder, ...]}``;
        each part holds the same files)."""
        if self.part_ticks is not None:
            return {"parts": [p.name for p in self.parts]}
        return {k: v.name for k, v in self.files.items()}


def _port_views(comp: str, ports, rows: np.ndarray):
    """``((comp, port), (n, *shape) view)`` of each port into its component's ``rows`` (n, width)."""
    for port, (start, end, _) in zip(ports, port_slots(ports)):
        view = rows[:, start] if port.shape == () else rows[:, start:end].reshape(len(rows), *port.shape)
        if not np.may_share_memory(view, rows):  # a copy would never see the ticks recorded
            raise AssertionError(f"{comp}.{port.name}: not a view of the component's rows")
        yield (comp, port.name), view


@contextlib.contextmanager
def _writing(path: Path):
    """Turn an OSError while writing ``path`` into an :class:`OutputWriteError` naming it."""
    try:
        yield
    except OSError as exc:
        raise OutputWriteError(path, exc) from exc

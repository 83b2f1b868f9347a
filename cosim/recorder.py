"""Observers that record a run, and the files they write.

:class:`TraceRecorder` keeps every port's value at every tick in memory
(preallocated arrays) and, when the run finishes or fails, writes:

* ``trace.npz``: the full trace of every port (``t_s`` plus one array per
  ``component.port``, shape (ticks, *port shape)), SI units;
* ``log.csv``: the raw log in the paper's format (see :mod:`cosim.data`);
* ``recording.rrd``: the rerun recording (see :mod:`cosim.rerun_log`).

Writing happens on failure too, so a crashed run leaves everything it
recorded readable.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cosim.data import write_log
from cosim.paths import distance_to_path
from cosim.scenario import Scenario
from cosim.wiring import Wiring


class TraceRecorder:
    def __init__(self, scenario: Scenario, wiring: Wiring, out_dir: Path, path=None):
        self.scenario, self.wiring, self.out_dir, self.path = scenario, wiring, Path(out_dir), path
        n = scenario.n_steps
        self.t_s = np.arange(n) * scenario.dt_s
        self.arrays = {(c, p.name): np.full((n, *p.shape), np.nan) for c in wiring.order for p in wiring.outputs[c]}
        self.ticks = 0
        self.closed = False
        self.files: dict[str, Path] = {}
        self.tracking_error_m: np.ndarray | None = None  # (ticks,) distance of truth to path [m]

    def on_tick(self, tick: int, t: float, values) -> None:
        if self.closed:
            return
        for key, value in values.items():
            self.arrays[key][tick] = value
        self.ticks = tick + 1

    def signal(self, role: str) -> np.ndarray | None:
        """The recorded array of a role of ``scenario.record`` (e.g. 'truth'), cut to the ticks run."""
        ref = getattr(self.scenario.record, role)
        if not ref:
            return None
        comp, _, port = ref.partition(".")
        arr = self.arrays.get((comp, port))
        return None if arr is None else arr[: self.ticks]

    def finish(self, error: str | None) -> None:
        if self.closed:
            return
        self.closed = True
        from cosim import rerun_log

        self.out_dir.mkdir(parents=True, exist_ok=True)
        n = self.ticks
        trace = {f"{c}.{p}": a[:n] for (c, p), a in self.arrays.items()}
        np.savez_compressed(self.out_dir / "trace.npz", t_s=self.t_s[:n], **trace)
        self.files["trace"] = self.out_dir / "trace.npz"
        omega, measured = self.signal("omega"), self.signal("measured")
        if omega is not None and measured is not None:
            write_log(self.out_dir / "log.csv", np.round(self.t_s[:n] * 1e3, 6), omega, measured)
            self.files["log"] = self.out_dir / "log.csv"
        truth = self.signal("truth")
        if truth is not None and self.path is not None:
            self.tracking_error_m = distance_to_path(self.path, truth, self.t_s[:n])
        rerun_log.write_recording(self, self.out_dir / "recording.rrd")
        self.files["recording"] = self.out_dir / "recording.rrd"

"""A dataset prepared for batched window rollouts (the diagnose engine's data side).

Rows are the stacked logs of a :class:`~cosim_plugins.identify.dataset.Dataset`
(one break row between logs). Units: mm, mm/s, Hz, s.

A window starting at row i covers rows i..i+L: the rollout starts from a
state at row i and steps the commands u_i..u_{i+L-1}; it is usable up to
``run[i]`` steps (consecutive regular steps with finite commands).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np


@dataclass
class Timeline:
    """Arrays of one dataset for rollouts.

    Attributes (n rows):
        dt_s: control period [s].
        p: (n, 3) measured positions [mm], NaN where missing.
        u: (n, 3) logged commands [Hz], NaN where missing.
        run: (n,) number of consecutive usable steps starting at each row.
        segments: (start, stop) row ranges of gap-free command segments
            (steps start..stop-1 usable), for input transforms.
        x_lin: (n, 6) a state estimate per row [mm, mm/s] (measured position,
            central-difference velocity; interpolated between measurements)
            used as the rollouts' starting point before the initial state is solved.
        t_s: (n,) time within its log [s]; log: (n,) log index (-1 on break rows).
    """

    dt_s: float
    p: np.ndarray
    u: np.ndarray
    run: np.ndarray
    segments: list
    x_lin: np.ndarray
    t_s: np.ndarray
    log: np.ndarray

    @classmethod
    def from_dataset(cls, ds) -> "Timeline":
        ok = ds.step_ok.astype(bool)
        n = len(ok)
        # run length of True from each row: the distance to the next False row (or the end)
        stop = np.where(ok, n, np.arange(n))
        run = (np.minimum.accumulate(stop[::-1])[::-1] - np.arange(n)).astype(np.int64)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])))
        segments = [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]
        t_s, log = _times(ds)
        return cls(dt_s=float(ds.dt_s), p=ds.p, u=ds.u, run=run, segments=segments,
                   x_lin=_linearisation_states(ds.p, ok, ds.dt_s), t_s=t_s, log=log)

    @property
    def n(self) -> int:
        return len(self.p)

    @cached_property
    def segment_start(self) -> np.ndarray:
        """(n,) the first row of each row's command segment (the row itself outside segments)."""
        first = np.arange(self.n)
        for a, b in self.segments:
            first[a:b] = a
        return first

    @cached_property
    def previous(self) -> np.ndarray:
        """(n,) each row's previous row within its command segment (itself at a segment's start)."""
        return np.maximum(np.arange(self.n) - 1, self.segment_start)

    @property
    def measured(self) -> np.ndarray:
        return np.all(np.isfinite(self.p), axis=1)

    def effective_commands(self, input_effects, params: dict) -> np.ndarray:
        """(n, 3) commands after the input transforms (applied per segment, in order); NaN rows stay NaN."""
        u = self.u.copy()
        for effect in input_effects:
            prm = _own(effect, params)
            for a, b in self.segments:
                u[a:b] = effect.transform(u[a:b], self.dt_s, prm)
        return u

    def window_starts(self, length: int, min_measured: float, rows: int | None = None,
                      measured_start: bool = True) -> np.ndarray:
        """Rows i with ``run[i] >= length``, at least ``min_measured`` (a fraction, and at least 3) of
        the first ``rows`` (default length + 1) rows of the window measured, and p_i measured if
        ``measured_start``."""
        rows = length + 1 if rows is None else rows
        meas = self.measured.astype(np.int64)
        csum = np.concatenate([[0], np.cumsum(meas)])
        i = np.arange(max(self.n - rows + 1, 0))
        ok = (self.run[i] >= length) & np.all(np.isfinite(self.x_lin[i]), axis=1)
        if measured_start:
            ok &= self.measured[i]
        ok &= (csum[i + rows] - csum[i]) >= max(3, np.ceil(min_measured * rows))
        return i[ok]


def _own(effect, params: dict) -> dict:
    """An effect's parameters by short name, from fully qualified ``params``."""
    return {q.name: params[f"{effect.name}.{q.name}"] for q in effect.params}


def _times(ds) -> tuple[np.ndarray, np.ndarray]:
    t = np.full(len(ds.p), np.nan)
    log = np.full(len(ds.p), -1, dtype=np.int64)
    row = 0
    for k, lg in enumerate(ds.logs):
        t[row:row + lg.n] = lg.t_s - lg.t_s[0]
        log[row:row + lg.n] = k
        row += lg.n + 1  # one break row per log
    return t, log


def _linearisation_states(p: np.ndarray, ok: np.ndarray, dt: float) -> np.ndarray:
    """(n, 6) [p, v]: v from the central difference where both neighbours are usable, else one-sided."""
    n = len(p)
    v = np.full((n, 3), np.nan)
    fwd = np.full((n, 3), np.nan)
    bwd = np.full((n, 3), np.nan)
    fwd[:-1] = np.where(ok[:-1, None], (p[1:] - p[:-1]) / dt, np.nan)
    bwd[1:] = fwd[:-1]
    v = np.where(np.isfinite(fwd) & np.isfinite(bwd), 0.5 * (fwd + bwd), np.where(np.isfinite(fwd), fwd, bwd))
    v = np.where(np.isfinite(v), v, 0.0)
    x = np.concatenate([p, v], axis=1)
    meas = np.all(np.isfinite(p), axis=1)
    if meas.sum() >= 2:  # rows without a measurement: interpolated (only a starting guess; the fit corrects it)
        idx = np.arange(n)
        for c in range(3):
            x[~meas, c] = np.interp(idx[~meas], idx[meas], p[meas, c])
        fin = meas & np.isfinite(fwd).all(axis=1)
        if fin.any():
            for c in range(3):
                x[~meas, 3 + c] = np.interp(idx[~meas], idx[fin], fwd[fin, c])
    else:
        x[~meas] = np.nan
    return x

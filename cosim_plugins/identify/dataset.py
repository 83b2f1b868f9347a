"""Training data built from raw logs: states, one-step pairs, multi-step windows.

State (paper, Sec. II-A): x_i = [P_i (mm), V_i (mm/s)] with the backward
difference V_i = (P_i - P_{i-1}) / dt. Input u_i = omega_i (Hz), applied over
[t_i, t_{i+1}). A state is valid when P_i and P_{i-1} are measured and the
step between them is regular (within 25 % of the nominal period); pairs and
windows never cross a gap, an irregular step or a log boundary.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosim.contract.errors import UserError
from cosim_plugins.raw_log import Log, read_logs

#: A step whose length differs from the nominal period by more than this is a break.
DT_TOLERANCE = 0.25


@dataclass
class Dataset:
    """Logs stacked into one timeline with breaks between them.

    Attributes (n = total rows + one break row per log):
        dt_s: nominal control period [s].
        p: (n, 3) measured position [mm], NaN when not usable.
        x: (n, 6) state [p mm, v mm/s], NaN when not valid.
        u: (n, 3) command [Hz], applied over [t_i, t_{i+1}).
        step_ok: (n,) True when the step i -> i+1 is regular and u_i finite.
        logs: the source logs.
    """

    dt_s: float
    p: np.ndarray
    x: np.ndarray
    u: np.ndarray
    step_ok: np.ndarray
    logs: list

    @classmethod
    def from_logs(cls, logs: list[Log]) -> "Dataset":
        if not logs:
            raise UserError("no logs given")
        dts = [lg.dt_s for lg in logs]
        dt = float(np.median(dts))
        for lg, d in zip(logs, dts):
            if abs(d - dt) > DT_TOLERANCE * dt:
                raise UserError(f"log {lg.path}: period {d * 1e3:g} ms differs from the others' {dt * 1e3:g} ms")
        ps, us, oks = [], [], []
        for lg in logs:
            steps = np.diff(lg.t_s)
            ok = np.zeros(lg.n, dtype=bool)
            ok[:-1] = np.abs(steps - dt) <= DT_TOLERANCE * dt
            ok &= np.all(np.isfinite(lg.omega_hz), axis=1)
            ps += [lg.p_mm, np.full((1, 3), np.nan)]
            us += [lg.omega_hz, np.full((1, 3), np.nan)]
            oks += [ok, np.zeros(1, dtype=bool)]
        p, u, step_ok = np.concatenate(ps), np.concatenate(us), np.concatenate(oks)
        x = np.full((len(p), 6), np.nan)
        x[1:, :3] = p[1:]
        x[1:, 3:] = (p[1:] - p[:-1]) / dt
        x[1:][~step_ok[:-1]] = np.nan
        return cls(dt_s=dt, p=p, x=x, u=u, step_ok=step_ok, logs=list(logs))

    @classmethod
    def from_paths(cls, paths) -> "Dataset":
        return cls.from_logs(read_logs([Path(p) for p in paths]))

    @property
    def state_ok(self) -> np.ndarray:
        """(n,) True where x_i is valid."""
        return np.all(np.isfinite(self.x), axis=1)

    @property
    def pos_ok(self) -> np.ndarray:
        return np.all(np.isfinite(self.p), axis=1)

    def quality(self) -> list[dict]:
        return [lg.quality() for lg in self.logs]

    def pair_index(self) -> np.ndarray:
        """Indices i with a valid one-step pair (x_i, u_i, x_{i+1})."""
        ok = self.state_ok[:-1] & self.step_ok[:-1] & self.state_ok[1:]
        return np.flatnonzero(ok)

    def pairs(self, index: np.ndarray | None = None):
        """One-step pairs: X (N, 6), U (N, 3), X_next (N, 6) at ``index`` (default all)."""
        i = self.pair_index() if index is None else index
        return self.x[i], self.u[i], self.x[i + 1]

    def window_index(self, k: int) -> np.ndarray:
        """Starts i of k-step windows: x_i valid, P_{i+1..i+k} measured, steps regular."""
        n = len(self.p)
        if n <= k:
            return np.zeros(0, dtype=int)
        bad = (~(self.pos_ok & np.roll(self.step_ok, 1))).astype(np.int64)
        bad[0] = 1
        csum = np.concatenate([[0], np.cumsum(bad)])
        i = np.arange(n - k)
        # positions i+1..i+k measured and steps i..i+k-1 regular (step_ok[j-1] for j in i+1..i+k)
        ok = (csum[i + k + 1] - csum[i + 1]) == 0
        ok &= self.state_ok[i] & self.step_ok[i]
        return i[ok]

    def windows(self, k: int, index: np.ndarray | None = None):
        """k-step windows: X0 (W, 6), U (W, k, 3), P (W, k, 3) measured positions after each step."""
        i = self.window_index(k) if index is None else index
        j = i[:, None] + np.arange(k)[None, :]
        return self.x[i], self.u[j], self.p[j + 1]

    def split_pairs(self, frac: float = 0.8, seed: int = 0):
        """Random split of the pair indices: (train_index, test_index)."""
        idx = self.pair_index()
        perm = np.random.default_rng(seed).permutation(len(idx))
        cut = int(round(frac * len(idx)))
        return np.sort(idx[perm[:cut]]), np.sort(idx[perm[cut:]])


def log_label(path: str) -> str:
    """A log's name that tells logs apart: ``runs/003_case=tilted/log.csv`` -> ``003_case=tilted/log.csv``."""
    p = Path(path)
    return f"{p.parent.name}/{p.name}" if p.parent.name else p.name

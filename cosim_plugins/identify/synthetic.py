"""Synthetic raw logs for tests and benchmarks (until the co-simulation runs).

A plant (any ``plant(x (n, 6), u (n, 3) Hz, dt_s) -> x_next`` with x = [p mm,
v mm/s], e.g. a physical model's ``predict``) follows closed paths under a
pure-pursuit steering law fed by a noisy camera; the run is written in the
raw log format with gaps, reflection outliers and lost detections (repeats)
mixed in. The paper's training set is 6 circles (radius 35 mm) and 6
racetracks (30 mm straights, 40 mm radius curves), tilted about y by 0, +-30,
+-45 and 90 degrees: :func:`paper_cases`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosim_plugins.raw_log import write_log

#: Parameters of the synthetic plant (physical model units: uN, mm, s, Hz).
#: Velocity time constant m / (1000 Cd1) = 0.15 s, ~20 mm/s at 12 Hz.
TRUE_PARAMS = {"k": 0.138, "Cd0": 0.04, "Cd1": 0.0827, "Cl0": -0.025, "Fvs": -0.33, "Fmax": -0.15}
TILTS_DEG = (0.0, -30.0, 30.0, -45.0, 45.0, 90.0)


def circle(radius_mm=35.0, tilt_deg=0.0, n=720) -> np.ndarray:
    """(n, 3) closed circle in the xy plane, tilted about y [mm]."""
    s = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return _tilt(np.column_stack([radius_mm * np.cos(s), radius_mm * np.sin(s), np.zeros(n)]), tilt_deg)


def racetrack(straight_mm=30.0, radius_mm=40.0, tilt_deg=0.0, step_mm=0.25) -> np.ndarray:
    """(n, 3) closed racetrack (two straights along x, two half circles), tilted about y [mm]."""
    h = straight_mm / 2
    ns = max(2, int(straight_mm / step_mm))
    nc = max(4, int(np.pi * radius_mm / step_mm))
    a = np.linspace(-np.pi / 2, np.pi / 2, nc, endpoint=False)
    x_s = np.linspace(-h, h, ns, endpoint=False)
    parts = [
        np.column_stack([x_s, -radius_mm * np.ones(ns)]),
        np.column_stack([h + radius_mm * np.cos(a), radius_mm * np.sin(a)]),
        np.column_stack([-x_s, radius_mm * np.ones(ns)]),
        np.column_stack([-h - radius_mm * np.cos(a), -radius_mm * np.sin(a)]),
    ]
    xy = np.concatenate(parts)
    return _tilt(np.column_stack([xy, np.zeros(len(xy))]), tilt_deg)


def _tilt(points, tilt_deg):
    c, s = np.cos(np.radians(tilt_deg)), np.sin(np.radians(tilt_deg))
    rot = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return points @ rot.T


def paper_cases() -> dict[str, np.ndarray]:
    """The 12 training paths of the paper, by file stem."""
    cases = {}
    for kind, make in (("circle", circle), ("racetrack", racetrack)):
        for tilt in TILTS_DEG:
            cases[f"{kind}_{int(tilt):+d}"] = make(tilt_deg=tilt)
    return cases


@dataclass
class Defects:
    """Camera imperfections: noise std [mm] and per-row probabilities."""

    noise_mm: float = 0.1
    gap_rate: float = 0.01
    outlier_rate: float = 0.002
    outlier_mm: float = 8.0
    repeat_rate: float = 0.003


def simulate(plant, paths: list[np.ndarray], n_rows: int, dt_s: float = 0.02, seed: int = 0,
             defects: Defects | None = None, speed_hz: float = 12.0, lookahead_mm: float = 8.0,
             bias_hz=(0.0, 0.0, 0.0), cmd_noise_hz: float = 1.5, steer_on_truth: bool = False):
    """Simulate all paths at once (one swimmer per path).

    Returns:
        dict with ``t_ms`` (n_rows,), ``omega_rad_s`` (b, n_rows, 3),
        ``p_m`` (b, n_rows, 3) as measured (NaN for gaps), ``truth_mm``
        (b, n_rows, 6) plant states at the measurement times.
    """
    defects = defects or Defects()
    rng = np.random.default_rng(seed)
    b = len(paths)
    x = np.zeros((b, 6))
    x[:, :3] = [pth[0] for pth in paths]
    last = x[:, :3].copy()
    speed = np.full(b, speed_hz)
    pursuers = [_Pursuit(pth, lookahead_mm) for pth in paths]
    truth = np.empty((b, n_rows, 6))
    meas = np.empty((b, n_rows, 3))
    cmd = np.empty((b, n_rows, 3))
    for i in range(n_rows):
        truth[:, i] = x
        m = x[:, :3] + defects.noise_mm * rng.standard_normal((b, 3))
        r = rng.random((b, 3))
        gap = r[:, 0] < defects.gap_rate
        out = (r[:, 1] < defects.outlier_rate) & ~gap
        rep = (r[:, 2] < defects.repeat_rate) & ~gap & ~out & (i > 0)
        jump = rng.standard_normal((b, 3))
        m[out] += defects.outlier_mm * jump[out] / np.linalg.norm(jump[out], axis=1, keepdims=True)
        if i > 0:
            m[rep] = meas[rep, i - 1]
            m[rep & np.isnan(m[:, 0])] = np.nan
        m[gap] = np.nan
        meas[:, i] = m
        seen = np.isfinite(m[:, 0]) & ~out
        last[seen] = m[seen]
        if steer_on_truth:  # diagnostics: no measurement noise in the loop
            last = x[:, :3].copy()
        speed += 0.05 * (speed_hz - speed) + 0.3 * rng.standard_normal(b)
        u = np.empty((b, 3))
        for j, pursuer in enumerate(pursuers):
            u[j] = pursuer.direction(last[j]) * speed[j]
        u += np.asarray(bias_hz) + cmd_noise_hz * rng.standard_normal((b, 3))
        cmd[:, i] = u
        x = plant(x, u, dt_s)
    t_ms = np.arange(n_rows) * dt_s * 1e3
    return {"t_ms": t_ms, "omega_rad_s": 2 * np.pi * cmd, "p_m": meas * 1e-3, "truth_mm": truth}


class _Pursuit:
    """Pure pursuit on a closed polyline: direction to the point ``lookahead_mm``
    ahead of the nearest one (searched near the previous nearest point)."""

    def __init__(self, path, lookahead_mm, search=40):
        self.path = path
        seg = np.linalg.norm(np.diff(path, axis=0, append=path[:1]), axis=1)
        self.step = max(1, int(round(lookahead_mm / max(seg.mean(), 1e-9))))
        self.near = None
        self.search = search

    def direction(self, p):
        n = len(self.path)
        if self.near is None:
            cand = np.arange(n)
        else:
            cand = (self.near + np.arange(-self.search, self.search + 1)) % n
        d = np.einsum("ij,ij->i", self.path[cand] - p, self.path[cand] - p)
        self.near = int(cand[np.argmin(d)])
        e = self.path[(self.near + self.step) % n] - p
        return e / max(np.linalg.norm(e), 1e-9)


def write_cases(out_dir, plant, n_rows: int, cases: dict[str, np.ndarray] | None = None, **kw) -> list[Path]:
    """Simulate ``cases`` (default :func:`paper_cases`) and write one raw log per case."""
    cases = cases or paper_cases()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    res = simulate(plant, list(cases.values()), n_rows, **kw)
    files = []
    for j, stem in enumerate(cases):
        path = out_dir / f"{stem}.csv"
        write_log(path, res["t_ms"], res["omega_rad_s"][j], res["p_m"][j])
        files.append(path)
    return files

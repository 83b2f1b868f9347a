"""The raw log format: read (with data-quality cleaning) and write.

A raw log is a CSV file with the header ``t_ms,omega_x,omega_y,omega_z,p_x,p_y,p_z``
(ms, rad/s, m), one row per control period (20 ms). Row i holds the position
measured at t_i and the command applied over [t_i, t_{i+1}). Empty or NaN
``p_*`` fields mean no measurement arrived.

:func:`read_log` converts to the paper's units (s, Hz = omega / 2 pi, mm) and
cleans the positions: gaps (empty/NaN), lost detections (a position repeated
exactly from the previous row) and reflection outliers (a jump inconsistent
with its neighbours, found by a robust median test) all become NaN, with a
mask for each so the counts can be reported. Bad input raises
:class:`~cosim.contract.errors.UserError` naming the file (and the line) and the problem.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cosim.contract.errors import UserError

HEADER = "t_ms,omega_x,omega_y,omega_z,p_x,p_y,p_z"
COLUMNS = tuple(HEADER.split(","))
MIN_ROWS = 3
#: |p| above this many metres means the column was written in mm.
MAX_ABS_P_M = 1.0
#: Default outlier threshold: distance from the neighbours' median [mm].
OUTLIER_MM = 3.0
#: Half-width of the neighbourhood used by the outlier test [rows].
OUTLIER_HALF_WINDOW = 2


@dataclass
class Log:
    """One cleaned raw log in the paper's units.

    Attributes:
        path: the file read (or a label).
        t_s: (n,) time [s], strictly increasing.
        omega_hz: (n, 3) command applied over [t_i, t_{i+1}) [Hz] (NaN if missing).
        p_mm: (n, 3) measured position [mm]; NaN where not usable.
        gap, repeat, outlier: (n,) bool masks: no measurement / exact repeat of
            the previous row / rejected as a jump. Disjoint; their union is
            where ``p_mm`` is NaN.
    """

    path: str
    t_s: np.ndarray
    omega_hz: np.ndarray
    p_mm: np.ndarray
    gap: np.ndarray
    repeat: np.ndarray
    outlier: np.ndarray
    meta: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.t_s)

    @property
    def dt_s(self) -> float:
        """Nominal control period [s] (median row spacing)."""
        return float(np.median(np.diff(self.t_s)))

    @property
    def valid(self) -> np.ndarray:
        """(n,) True where the position is usable."""
        return ~(self.gap | self.repeat | self.outlier)

    def quality(self) -> dict:
        """Short data-quality summary (counts of rows and of each defect)."""
        return {
            "file": self.path,
            "rows": self.n,
            "gaps": int(self.gap.sum()),
            "outliers": int(self.outlier.sum()),
            "repeats": int(self.repeat.sum()),
            "duration_s": round(float(self.t_s[-1] - self.t_s[0]), 3),
        }


def read_log(path: str | Path, outlier_mm: float = OUTLIER_MM) -> Log:
    """Read, check, convert and clean one raw log; see the module docstring."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"log {path}: no such file")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"log {path}: cannot read: {exc}") from exc
    raw = _parse(text, path)
    return _clean(raw, str(path), outlier_mm)


def read_logs(paths, outlier_mm: float = OUTLIER_MM) -> list[Log]:
    """Read several logs (see :func:`read_log`)."""
    if not paths:
        raise UserError("no log files given")
    return [read_log(p, outlier_mm) for p in paths]


def write_log(path: str | Path, t_ms, omega_rad_s, p_m) -> None:
    """Write a raw log in one go (see :class:`LogWriter` for the row format)."""
    with LogWriter(path) as log:
        log.append(t_ms, omega_rad_s, p_m)


class LogWriter:
    """A raw log written as it comes: the header at once, then rows appended and flushed.

    :meth:`append` takes ``t_ms`` (n,) [ms] (written as integers when all of
    a batch are integral), ``omega_rad_s`` (n, 3) [rad/s] and ``p_m`` (n, 3)
    [m] (NaN fields written empty). Floats use ``%.9g`` (no ``-0``); the
    output is deterministic for given rows, however they are batched as long
    as every batch's times are integral (or none's).
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._fh = open(self.path, "w", newline="\n")
        self._fh.write(HEADER + "\n")
        self._fh.flush()

    def append(self, t_ms, omega_rad_s, p_m) -> None:
        t = np.asarray(t_ms, dtype=float).reshape(-1)
        if not len(t):
            return
        w = np.asarray(omega_rad_s, dtype=float).reshape(len(t), 3)
        p = np.asarray(p_m, dtype=float).reshape(len(t), 3)
        t_int = bool(np.all(np.isfinite(t))) and bool(np.all(t == np.round(t))) and np.abs(t).max() < 2**53
        row = ("%d" if t_int else "%.12g") + ",%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n"
        table = np.column_stack([t, w, p]) + 0.0  # -0.0 + 0.0 is +0.0
        body = (row * len(t)) % tuple(table.ravel().tolist())
        self._fh.write(body.replace("nan", ""))
        self._fh.flush()

    def close(self) -> None:
        self._fh.close()

    def __enter__(self) -> "LogWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


# ---------------------------------------------------------------- parsing


def _parse(text: str, path: Path) -> np.ndarray:
    """Text -> (n, 7) float array in file units; checks header and numbers."""
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise UserError(f"log {path}: empty file; expected header {HEADER!r}")
    header = lines[0].strip().lstrip("\ufeff").replace(" ", "")
    if header != HEADER:
        raise UserError(f"log {path}: wrong header {lines[0].strip()!r}; expected {HEADER!r}")
    body = [ln for ln in lines[1:]]
    while body and not body[-1].strip():
        body.pop()
    if len(body) < MIN_ROWS:
        raise UserError(f"log {path}: too few rows ({len(body)}); need at least {MIN_ROWS}")
    try:  # fast path: C parser after filling empty fields
        filled = "\n".join(body)
        for _ in range(2):
            filled = filled.replace(",,", ",nan,")
        filled = filled.replace(",\n", ",nan\n")
        if filled.endswith(","):
            filled += "nan"
        arr = np.loadtxt(io.StringIO(filled), delimiter=",", dtype=float, ndmin=2)
        if arr.shape != (len(body), 7):
            raise ValueError("shape")
        return arr
    except ValueError:
        return _parse_slow(body, path)


def _parse_slow(body: list[str], path: Path) -> np.ndarray:
    """Line-by-line parser: finds and names the first bad line."""
    out = np.empty((len(body), 7))
    for i, line in enumerate(body):
        lineno = i + 2
        fields = line.split(",")
        if len(fields) != 7:
            raise UserError(f"log {path} line {lineno}: expected 7 comma-separated fields, got {len(fields)}")
        for j, s in enumerate(fields):
            s = s.strip()
            if not s:
                out[i, j] = math.nan
                continue
            try:
                out[i, j] = float(s)
            except ValueError:
                raise UserError(f"log {path} line {lineno}: non-numeric value {s!r} in column {COLUMNS[j]}") from None
    return out


# ---------------------------------------------------------------- checks and cleaning


def _clean(raw: np.ndarray, path: str, outlier_mm: float) -> Log:
    t_ms, w, p = raw[:, 0], raw[:, 1:4], raw[:, 4:7]
    for j, name in enumerate(COLUMNS):
        if not np.any(np.isfinite(raw[:, j])):
            raise UserError(f"log {path}: column {name} has no values (all empty/NaN)")
    bad_t = ~np.isfinite(t_ms)
    if bad_t.any():
        raise UserError(f"log {path} line {int(np.argmax(bad_t)) + 2}: missing or non-finite time")
    dt = np.diff(t_ms)
    if np.any(dt <= 0):
        raise UserError(f"log {path} line {int(np.argmax(dt <= 0)) + 3}: time is not strictly increasing")
    if np.median(dt) < 1.0:
        raise UserError(f"log {path}: time steps of {np.median(dt):g} look like seconds; t_ms must be in ms")
    pmax = float(np.nanmax(np.abs(p)))
    if pmax > MAX_ABS_P_M:
        raise UserError(
            f"log {path}: positions look like mm (max |p| = {pmax:g} > {MAX_ABS_P_M:g}); p_x,p_y,p_z must be in metres"
        )
    p_mm = p * 1e3
    gap = ~np.all(np.isfinite(p_mm), axis=1)
    p_mm[gap] = np.nan
    repeat = np.zeros(len(t_ms), dtype=bool)
    repeat[1:] = ~gap[1:] & ~gap[:-1] & np.all(p_mm[1:] == p_mm[:-1], axis=1)
    p_mm[repeat] = np.nan
    outlier = _outliers(p_mm, outlier_mm)
    p_mm[outlier] = np.nan
    return Log(
        path=path,
        t_s=t_ms * 1e-3,
        omega_hz=w / (2 * np.pi),
        p_mm=p_mm,
        gap=gap,
        repeat=repeat,
        outlier=outlier,
    )


def _outliers(p_mm: np.ndarray, threshold_mm: float) -> np.ndarray:
    """(n,) True where a position is far from the median of its neighbourhood.

    The neighbourhood is the ``2h+1`` valid samples centred on each row (in
    valid-sample order, so gaps are skipped). The threshold is the larger of
    ``threshold_mm`` and 6 robust standard deviations of the residuals.
    """
    h = OUTLIER_HALF_WINDOW
    ok = np.flatnonzero(np.all(np.isfinite(p_mm), axis=1))
    out = np.zeros(len(p_mm), dtype=bool)
    if len(ok) < 2 * h + 1:
        return out
    q = p_mm[ok]
    padded = np.concatenate([np.full((h, 3), np.nan), q, np.full((h, 3), np.nan)])
    win = np.lib.stride_tricks.sliding_window_view(padded, 2 * h + 1, axis=0)  # (m, 3, 2h+1)
    med = np.nanmedian(win, axis=2)
    r = np.linalg.norm(q - med, axis=1)
    mad = np.median(np.abs(r - np.median(r)))
    thr = max(threshold_mm, 6 * 1.4826 * mad)
    out[ok[r > thr]] = True
    return out

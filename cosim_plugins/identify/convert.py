"""``cosim convert``: a lab's own recordings into the raw log format.

A rig seldom logs the raw format directly: its controller logs the command
at its own times (a rotation vector, or an axis and a spin frequency), and
its tracker logs detections at the cameras' frame times, some frames
missing, in mm, m or pixels. :func:`to_raw_log` puts both on one regular
control grid of period ``dt_s``:

* row i is at ``t_i = t_0 + i dt`` from the first command to the last;
* ``omega`` is the last command given at or before ``t_i`` (the coils hold
  it over ``[t_i, t_{i+1})``), converted to a rotation vector [rad/s];
* ``p`` is the detection nearest to ``t_i`` within half a period, empty when
  there is none (a lost or skipped frame); several within reach: the nearest.

Input files are CSV with a header. Commands: a time column (``t_s`` or
``t_ms``) and either ``omega_x,omega_y,omega_z`` [rad/s] or
``axis_x,axis_y,axis_z,freq_hz`` (the field's rotation axis, any length, and
its spin frequency). Positions: a time column and ``x,y,z`` in the unit
given (``mm``, ``m``, or ``px`` with a pixel size). Errors name the file,
the line and the problem.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from cosim.contract.errors import UserError
from cosim_plugins.raw_log import write_log


def read_table(path: Path) -> tuple[list[str], np.ndarray, list[int]]:
    """(header names, float rows (n, k) with NaN for empty fields, line number of each row)."""
    if not path.is_file():
        raise UserError(f"{path}: no such file")
    lines = path.read_text().splitlines()
    if not lines:
        raise UserError(f"{path}: empty file")
    names = [h.strip() for h in lines[0].split(",")]
    rows, numbers = [], []
    for i, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        fields = line.split(",")
        if len(fields) != len(names):
            raise UserError(f"{path} line {i}: {len(fields)} fields, the header has {len(names)}")
        try:
            rows.append([float(f) if f.strip() else math.nan for f in fields])
        except ValueError:
            raise UserError(f"{path} line {i}: not a number in {line.strip()!r}") from None
        numbers.append(i)
    if not rows:
        raise UserError(f"{path}: no data rows")
    return names, np.array(rows), numbers


def _times_s(path: Path, names: list[str], data: np.ndarray, lines: list[int]) -> np.ndarray:
    """The time column [s] (``t_s`` or ``t_ms``); must be finite and strictly increasing."""
    if "t_s" in names:
        t = data[:, names.index("t_s")]
    elif "t_ms" in names:
        t = data[:, names.index("t_ms")] * 1e-3
    else:
        raise UserError(f"{path}: no time column: name it t_s or t_ms (header: {','.join(names)})")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise UserError(f"{path} line {lines[bad[0]]}: empty or non-numeric time")
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        raise UserError(f"{path} line {lines[back[0] + 1]}: time {t[back[0] + 1]:g} s does not increase")
    return t


def read_commands(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(t (n,) [s], omega (n, 3) [rad/s]) from a commands file (see the module doc)."""
    names, data, lines = read_table(path)
    t = _times_s(path, names, data, lines)
    if all(c in names for c in ("omega_x", "omega_y", "omega_z")):
        omega = data[:, [names.index(c) for c in ("omega_x", "omega_y", "omega_z")]]
    elif all(c in names for c in ("axis_x", "axis_y", "axis_z", "freq_hz")):
        axis = data[:, [names.index(c) for c in ("axis_x", "axis_y", "axis_z")]]
        norm = np.linalg.norm(axis, axis=1)
        f = data[:, names.index("freq_hz")]
        zero_axis = np.flatnonzero((norm == 0) & (f != 0))
        if zero_axis.size:
            raise UserError(f"{path} line {lines[zero_axis[0]]}: a spin frequency with a zero rotation axis")
        omega = 2 * math.pi * f[:, None] * axis / np.where(norm > 0, norm, 1.0)[:, None]
    else:
        raise UserError(f"{path}: commands need omega_x,omega_y,omega_z [rad/s] or axis_x,axis_y,axis_z,freq_hz "
                        f"(header: {','.join(names)})")
    bad = np.flatnonzero(~np.all(np.isfinite(omega), axis=1))
    if bad.size:
        raise UserError(f"{path} line {lines[bad[0]]}: a command must be given in full (empty or NaN field)")
    return t, omega


def read_positions(path: Path, unit: str, pixel_mm: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(t (m,) [s], p (m, 3) [m], NaN rows for frames without a detection) from a positions file."""
    names, data, lines = read_table(path)
    t = _times_s(path, names, data, lines)
    if not all(c in names for c in ("x", "y", "z")):
        raise UserError(f"{path}: positions need columns x,y,z (header: {','.join(names)})")
    p = data[:, [names.index(c) for c in ("x", "y", "z")]]
    scale = {"m": 1.0, "mm": 1e-3}.get(unit)
    if unit == "px":
        if not pixel_mm or pixel_mm <= 0:
            raise UserError("positions in px need --pixel-mm (the size of one pixel in the tank, e.g. 0.19)")
        scale = pixel_mm * 1e-3
    if scale is None:
        raise UserError(f"position unit {unit!r}: use mm, m or px")
    return t, p * scale


def to_raw_log(cmd_t_s, omega, pos_t_s, p_m, dt_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t (n,) [s] from 0, omega (n, 3) [rad/s] held, p (n, 3) [m] or NaN) on the grid of period ``dt_s``.

    ``cmd_t_s`` (c,), ``omega`` (c, 3): commands; ``pos_t_s`` (m,), ``p_m`` (m, 3): detections (NaN: none).
    """
    if dt_s <= 0:
        raise UserError(f"--dt {dt_s:g}: the control period must be positive")
    t0 = float(cmd_t_s[0])
    n = int(math.floor((float(cmd_t_s[-1]) - t0) / dt_s + 1e-9)) + 1
    grid = t0 + dt_s * np.arange(n)
    held = np.searchsorted(cmd_t_s, grid + 1e-9 * dt_s, side="right") - 1  # last command at or before t_i
    ok = np.all(np.isfinite(p_m), axis=1)
    pt, pp = np.asarray(pos_t_s)[ok], np.asarray(p_m)[ok]
    p = np.full((n, 3), np.nan)
    if len(pt):
        after = np.minimum(np.searchsorted(pt, grid), len(pt) - 1)  # the detection at or after t_i (or the last)
        before = np.maximum(after - 1, 0)
        j = np.where(np.abs(pt[before] - grid) <= np.abs(pt[after] - grid), before, after)
        near = np.abs(pt[j] - grid) <= dt_s / 2
        p[near] = pp[j[near]]
    return grid - t0, omega[held], p


def convert(commands: Path, positions: Path, out: Path, dt_s: float, unit: str = "mm",
            pixel_mm: float | None = None) -> dict:
    """Read both files, write the raw log ``out``; returns counts for the summary line."""
    cmd_t, omega = read_commands(commands)
    pos_t, p = read_positions(positions, unit, pixel_mm)
    t, om, pos = to_raw_log(cmd_t, omega, pos_t, p, dt_s)
    out.parent.mkdir(parents=True, exist_ok=True)
    t_ms = t * 1e3
    # whole milliseconds (to 1 ns, absolute: a relative tolerance would round a long log's 0.1 us per row away)
    write_log(out, np.round(t_ms) if np.allclose(t_ms, np.round(t_ms), rtol=0.0, atol=1e-6) else t_ms, om, pos)
    outside = int(np.sum((pos_t < cmd_t[0] - dt_s / 2) | (pos_t > cmd_t[-1] + dt_s / 2)))
    return {"rows": len(t), "measured": int(np.all(np.isfinite(pos), axis=1).sum()), "detections": len(pos_t),
            "outside": outside, "duration_s": float(t[-1])}

"""Reference paths: the contract path plugins follow, and geometry helpers.

A path is a dense polyline in metres, possibly moving with time (e.g. a
continuously rotating circle). Path plugins register factories via
the ``cosim_register_paths`` hook; :func:`make_path` builds one by name.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from cosim.contract.errors import UserError

#: Spacing of the dense polyline every path returns [m].
SPACING_M = 0.5e-3


class Path:
    """Base class. Subclasses set ``closed`` and implement :meth:`base_points`.

    ``base_points()`` returns the polyline at t = 0, shape (n, 3) [m], ordered
    in the direction of travel; time-varying paths override :meth:`points`.
    """

    closed: bool = True
    time_varying: bool = False

    def base_points(self) -> np.ndarray:
        raise NotImplementedError

    def points(self, t_s: float = 0.0) -> np.ndarray:
        """Polyline at time ``t_s`` [s], shape (n, 3) [m]."""
        if not hasattr(self, "_cache"):
            self._cache = resample(self.base_points(), SPACING_M, self.closed)
        return self._cache

    @property
    def length_m(self) -> float:
        pts = self.points(0.0)
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
        if self.closed:
            seg += np.linalg.norm(pts[0] - pts[-1])
        return float(seg)


def resample(points: np.ndarray, spacing_m: float, closed: bool) -> np.ndarray:
    """Resample a polyline (n, 3) to even arc-length spacing (the closing segment included if closed)."""
    pts = np.asarray(points, dtype=float)
    if closed:
        pts = np.vstack([pts, pts[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    n = max(int(np.ceil(s[-1] / spacing_m)), 2)
    s_new = np.linspace(0.0, s[-1], n, endpoint=not closed)
    return np.stack([np.interp(s_new, s, pts[:, i]) for i in range(3)], axis=1)


def rotation_y(angle_rad: float) -> np.ndarray:
    """Rotation matrix about +y, shape (3, 3)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def distance_to_path(path: Path, positions_m: np.ndarray, times_s: np.ndarray | None = None) -> np.ndarray:
    """Distance [m] from each position (n, 3) to the path polyline (at each time if it moves); (n,)."""
    positions_m = np.asarray(positions_m, dtype=float)
    out = np.full(len(positions_m), np.nan)
    if not path.time_varying:
        pts = path.points(0.0)
        for start in range(0, len(positions_m), 512):
            chunk = positions_m[start : start + 512]
            d2 = ((chunk[:, None, :] - pts[None, :, :]) ** 2).sum(axis=2)
            out[start : start + 512] = np.sqrt(d2.min(axis=1))
        return out
    for i, (p, t) in enumerate(zip(positions_m, times_s)):
        out[i] = np.sqrt(((path.points(float(t)) - p) ** 2).sum(axis=1).min())
    return out


def make_path(plugin: str, params: Mapping[str, Any] | None = None) -> Path:
    """Build the registered path ``plugin`` with ``params``; errors name the path and parameter."""
    from cosim.contract.plugins import lookup

    factory = lookup("path", plugin)
    try:
        return factory(**dict(params or {}))
    except TypeError as exc:
        raise UserError(f"path {plugin!r}: bad parameters: {exc}") from None
    except ValueError as exc:
        raise UserError(f"path {plugin!r}: {exc}") from None

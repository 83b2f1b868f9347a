"""The reference-path contract: what a path plugin (hook ``cosim_register_paths``) builds.

A reference path is a polyline in metres, possibly moving with time (a
rotating circle). A plugin subclasses :class:`ReferencePath`, implements
:meth:`~ReferencePath.base_points` and says how densely its polyline is
sampled (:attr:`~ReferencePath.spacing_m`, resampled by :func:`resample`);
a path that moves overrides :meth:`~ReferencePath.points`. The framework
measures the distance of a trajectory to it (see
:func:`cosim.scenario.paths.distance_to_path`) and draws it.
"""

from __future__ import annotations

import numpy as np


class ReferencePath:
    """Base of a reference path: set ``closed``, ``spacing_m`` and implement :meth:`base_points`."""

    #: the last point joins the first
    closed: bool = True
    #: the path moves: :meth:`points` depends on its time argument
    time_varying: bool = False
    #: arc-length spacing [m] the polyline of :meth:`base_points` is resampled to; None: as it is
    spacing_m: float | None = None

    def base_points(self) -> np.ndarray:
        """The polyline at t = 0, shape (n, 3) [m], in the direction of travel."""
        raise NotImplementedError(f"{type(self).__name__}: a reference path implements base_points()")

    def points(self, t_s: float = 0.0) -> np.ndarray:
        """The polyline at time ``t_s`` [s], shape (n, 3) [m] (a fixed path: the same at every time)."""
        if not hasattr(self, "_cache"):
            base = np.asarray(self.base_points(), dtype=float)
            self._cache = base if self.spacing_m is None else resample(base, self.spacing_m, self.closed)
        return self._cache

    def motion(self, t_s: float) -> tuple[np.ndarray, np.ndarray] | None:
        """For a path that moves rigidly: ``(rotation (3, 3), offset (3,) [m])`` with
        ``points(t_s) = points(0) @ rotation.T + offset``, so a consumer can work on the path at
        t = 0 and move positions into its frame instead of the path's points every step; None
        (the default) for a path that does not say so."""
        return None

    @property
    def length_m(self) -> float:
        """The polyline's length at t = 0 [m] (the closing segment included if ``closed``)."""
        pts = self.points(0.0)
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
        if self.closed:
            seg += np.linalg.norm(pts[0] - pts[-1])
        return float(seg)


def resample(points: np.ndarray, spacing_m: float, closed: bool) -> np.ndarray:
    """A polyline (n, 3) [m] resampled to even arc-length spacing ``spacing_m`` [m] (the closing
    segment included if ``closed``); shape (m, 3)."""
    pts = np.asarray(points, dtype=float)
    if closed:
        pts = np.vstack([pts, pts[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    n = max(int(np.ceil(s[-1] / spacing_m)), 2)
    s_new = np.linspace(0.0, s[-1], n, endpoint=not closed)
    return np.stack([np.interp(s_new, s, pts[:, i]) for i in range(3)], axis=1)

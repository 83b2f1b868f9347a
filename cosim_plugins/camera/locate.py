"""The swimmer's position from a frame pair: blobs in each view, paired by consistency.

Every blob of the top view is paired with every blob of the side view and
each pair triangulated (:mod:`~cosim_plugins.camera.triangulate`). A pair
is the swimmer only if

* its two blobs agree: reprojection error <= ``gate_px`` (a glint seen in
  one view only pairs with nothing);
* its point lies in the tank (a reflection in a wall is seen behind it);
* it is within reach of the last position: ``jump_mm`` plus
  ``max_speed_mm_s`` times the time since (a reflection in the water
  surface agrees with the other view, but lies far off); after
  ``max_rejects`` rejected pairs in a row the last position is forgotten,
  so a swimmer that really moved is found again.

Of the pairs that pass, the one nearest the last position is taken (none
known: the one with the strongest blobs, darkness times area). The last position also tells each
view where to look first. Statuses (the ``detection`` output): ``FOUND``,
``LOST`` (a frame lost, or no blob in a view), ``REJECTED`` (blobs in both
views, no consistent pair).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cosim_plugins.camera.calibration import VIEWS, Calibration
from cosim_plugins.camera.detect import BlobParams, Blobs, find_blobs
from cosim_plugins.camera.triangulate import triangulate

FOUND, LOST, REJECTED = 0, 1, 2


@dataclass(frozen=True)
class PairParams:
    """How the two views' detections are paired and gated: pixel gate, tank size [mm], jump and speed limits."""
    gate_px: float = 2.0
    tank_mm: float = 75.0  # half-width of the tank: points beyond are reflections
    jump_mm: float = 2.0
    max_speed_mm_s: float = 200.0
    max_rejects: int = 5


@dataclass
class Fix:
    """One pair's result: ``position_m`` (3,) (NaN unless found), ``reprojection_px`` (NaN unless
    found), ``status``, the ``blobs`` of each view (None where the frame was lost) and the index
    of the blob taken in each (None unless found)."""

    position_m: np.ndarray
    reprojection_px: float
    status: int
    blobs: tuple[Blobs | None, Blobs | None]
    chosen: tuple[int, int] | None = None


class PairLocator:
    """Finds the swimmer in frame pairs, remembering its last position (see the module docstring)."""

    def __init__(self, calibration: Calibration, blob: BlobParams, pair: PairParams):
        self.cams = [calibration[v] for v in VIEWS]
        self.blob, self.pair = blob, pair
        self.last_m: np.ndarray | None = None
        self.last_t = 0.0
        self.rejects = 0

    def locate(self, t_s: float, images) -> Fix:
        """The fix of the pair ``images`` (top, side: (height, width) uint8 or None) captured at ``t_s``."""
        blobs = tuple(None if img is None else find_blobs(img, self.blob, self._expected(i))
                      for i, img in enumerate(images))
        if any(b is None or not len(b) for b in blobs):
            return Fix(np.full(3, np.nan), np.nan, LOST, blobs)
        top, side = blobs
        ia, ib = np.divmod(np.arange(len(top) * len(side)), len(side))
        points, error_px = triangulate(self.cams[0], self.cams[1], top.centres[ia], side.centres[ib])
        ok = (error_px <= self.pair.gate_px) & np.all(np.abs(points) <= self.pair.tank_mm * 1e-3, axis=1)
        if self.last_m is not None:
            reach_m = (self.pair.jump_mm + self.pair.max_speed_mm_s * max(t_s - self.last_t, 0.0)) * 1e-3
            distance = np.linalg.norm(points - self.last_m, axis=1)
            ok &= distance <= reach_m
            rank = distance
        else:  # the strongest consistent pair: reflections and glints are mostly fainter
            rank = -(top.darkness * top.areas)[ia] - (side.darkness * side.areas)[ib]
        if not ok.any():
            self.rejects += 1
            if self.rejects >= self.pair.max_rejects:
                self.last_m = None  # look for it afresh
            return Fix(np.full(3, np.nan), np.nan, REJECTED, blobs)
        k = int(np.flatnonzero(ok)[np.argmin(rank[ok])])
        self.last_m, self.last_t, self.rejects = points[k], t_s, 0
        return Fix(points[k].copy(), float(error_px[k]), FOUND, blobs, (int(ia[k]), int(ib[k])))

    def _expected(self, view: int) -> np.ndarray | None:
        """Where the last position shows in ``view`` [px], if there is one."""
        if self.last_m is None:
            return None
        return self.cams[view].project(self.last_m[None])[0]

"""Pure pursuit on a 3D polyline: the reference all controllers share.

The tracker projects the swimmer onto the path's segments (the closest point,
searched in a window of segments around the last one, so a path that passes
near itself is followed in order) and returns the point a look-ahead arc
length further along the path, interpolated on its segment:
``L = lookahead_m + gain_s * |v|`` (the paper's Table V: 9 mm, 0.001).

Both points are continuous in the position (see
:mod:`cosim_plugins.controllers.polyline`): a micrometre's move of the
measured position moves the reference by about a micrometre. (The tracker
once took the nearest path point and rounded the look-ahead to whole
points; a micrometre could then jump the reference by a path spacing,
0.5 mm, and the command with it.)
"""

from __future__ import annotations

import numpy as np

from cosim.contract.paths import ReferencePath
from cosim_plugins.controllers.polyline import Polyline, polyline
from cosim_plugins.vec3 import norm

#: the search window [segments] behind and ahead of the last closest segment
WINDOW_BACK, WINDOW_AHEAD = 20, 200


class PurePursuit:
    """The look-ahead point on a path: the closest point, advanced along the path by the look-ahead distance."""
    def __init__(self, path: ReferencePath, lookahead_m: float = 9e-3, gain_s: float = 0.001):
        self.path, self.lookahead_m, self.gain_s = path, lookahead_m, gain_s
        #: the path segment holding the last closest point (None before the first call)
        self.index: int | None = None
        #: the last closest point's arc length from the path's first point [m]
        self.arc_m: float | None = None
        self._pts: np.ndarray | None = None  # the points the geometry below belongs to
        self._line: Polyline | None = None
        self._moves_rigidly = path.time_varying and path.motion(0.0) is not None

    def line(self, t_s: float) -> Polyline:
        """The path's geometry at ``t_s`` [s] (built again only when the path's points change); for
        a path that moves rigidly (:meth:`~cosim.contract.paths.ReferencePath.motion`), at t = 0."""
        if self._moves_rigidly:
            if self._line is None:
                self._line = polyline(self.path.points(0.0), self.path.closed, WINDOW_BACK, WINDOW_AHEAD)
            return self._line
        pts = self.path.points(t_s)
        if pts is not self._pts:  # a static path returns the same array every step
            self._pts, self._line = pts, polyline(pts, self.path.closed, WINDOW_BACK, WINDOW_AHEAD)
        return self._line

    def _rigid(self, t_s: float):
        """The path's rigid motion at ``t_s`` (rotation (3, 3), offset (3,) [m]), or None."""
        return self.path.motion(t_s) if self._moves_rigidly else None

    def reference(self, position_m: np.ndarray, velocity_m_s: np.ndarray, t_s: float):
        """``(target (3,), closest (3,), at_end)`` for the swimmer at ``position_m`` (3,) [m]
        moving at ``velocity_m_s`` (3,) [m/s]: ``at_end`` when an open path's end is within the
        look-ahead (the target is then the end). A path that moves rigidly is searched at t = 0,
        with the position moved into that frame and the points moved back."""
        motion = self._rigid(t_s)
        line = self.line(t_s)
        if motion is not None:
            rotation, offset = motion
            position_m = (position_m - offset) @ rotation
        self.index, fraction = line.closest(position_m, self.index)
        self.arc_m = line.arc(self.index, fraction)
        target, at_end = line.at_arc(self.arc_m + self.lookahead_m + self.gain_s * norm(velocity_m_s))
        closest = line.point(self.index, fraction)
        if motion is not None:
            target, closest = rotation @ target + offset, rotation @ closest + offset
        return target, closest, at_end

    def along(self, ahead_m: np.ndarray, t_s: float) -> np.ndarray:
        """The path points (k, 3) [m] at arc lengths ``ahead_m`` (k,) [m] beyond the last closest
        point (wrapping on a closed path, stopping at an open one's end); after :meth:`reference`."""
        if self.arc_m is None:
            raise RuntimeError("PurePursuit.along: no closest point yet (call reference first)")
        points = self.line(t_s).at_arcs(self.arc_m + np.asarray(ahead_m, dtype=float))
        motion = self._rigid(t_s)
        if motion is None:
            return points
        rotation, offset = motion
        return points @ rotation.T + offset

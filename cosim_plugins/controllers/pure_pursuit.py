"""Pure pursuit on a 3D polyline: the reference all controllers share.

The tracker keeps the index of the closest path point (searched in a window
ahead of the last one, so a path that passes near itself is followed in
order) and returns the point a look-ahead distance further along the path:
``L = lookahead_m + gain_s * |v|`` (the paper's Table V: 9 mm, 0.001).
"""

from __future__ import annotations

import numpy as np

from cosim.contract.paths import ReferencePath
from cosim_plugins.vec3 import norm

WINDOW_BACK, WINDOW_AHEAD = 20, 200


class PurePursuit:
    """The look-ahead point on a path: the closest point, advanced along the path by the look-ahead distance."""
    def __init__(self, path: ReferencePath, lookahead_m: float = 9e-3, gain_s: float = 0.001):
        self.path, self.lookahead_m, self.gain_s = path, lookahead_m, gain_s
        self.index: int | None = None
        self._pts: np.ndarray | None = None  # the polyline the spacing below belongs to
        self._spacing_m = 0.0
        self._coords: np.ndarray | None = None  # the polyline's (3, n) coordinate rows

    def reference(self, position_m: np.ndarray, velocity_m_s: np.ndarray, t_s: float):
        """``(target (3,), closest (3,), at_end)`` for the swimmer at ``position_m``."""
        pts = self.path.points(t_s)
        n = len(pts)
        if pts is not self._pts:  # a static path returns the same array every step
            self._pts, self._spacing_m = pts, norm(pts[1] - pts[0])
            self._coords = np.ascontiguousarray(pts.T)  # (3, n): x, y, z rows, for _closest
        self.index = self._closest(self._coords, position_m)
        ahead = int(round((self.lookahead_m + self.gain_s * norm(velocity_m_s)) / self._spacing_m))
        target_idx = self.index + ahead
        at_end = False
        if self.path.closed:
            target_idx %= n
        elif target_idx >= n - 1:
            target_idx, at_end = n - 1, True
        return pts[target_idx], pts[self.index], at_end

    def _closest(self, coords: np.ndarray, position_m: np.ndarray) -> int:
        """Index of the path point closest to ``position_m`` (3,) [m], given the path's
        coordinates ``coords`` (3, n) [m]: over the whole path the first time, then in the
        window around the last index (wrapping if closed)."""
        n = coords.shape[1]
        if self.index is None:
            start, stop = 0, n
        else:
            start, stop = self.index - WINDOW_BACK, self.index + WINDOW_AHEAD
            if not self.path.closed:
                start, stop = max(start, 0), min(stop, n)
        if 0 <= start and stop <= n:
            window = coords[:, start:stop]  # a view: no copy
        elif stop - start <= n:  # a closed path's window across its start: its end, then its beginning
            window = np.concatenate((coords[:, start % n:], coords[:, :stop % n]), axis=1)
        else:  # a closed path shorter than the window: points repeat
            window = coords[:, np.arange(start, stop) % n]
        # squared distances, (dx^2 + dy^2) + dz^2: coordinate rows make each operation one
        # contiguous sweep (an (m, 3) layout costs twice as much)
        d = window - position_m[:, None]
        d *= d
        d2 = d[0] + d[1] + d[2]
        return (start + int(d2.argmin())) % n

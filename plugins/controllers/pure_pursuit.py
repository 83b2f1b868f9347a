"""Pure pursuit on a 3D polyline: the reference all controllers share.

The tracker keeps the index of the closest path point (searched in a window
ahead of the last one, so a path that passes near itself is followed in
order) and returns the point a look-ahead distance further along the path:
``L = lookahead_m + gain_s * |v|`` (the paper's Table V: 9 mm, 0.001).
"""

from __future__ import annotations

import numpy as np

from cosim.paths import Path

WINDOW_BACK, WINDOW_AHEAD = 20, 200


class PurePursuit:
    def __init__(self, path: Path, lookahead_m: float = 9e-3, gain_s: float = 0.001):
        self.path, self.lookahead_m, self.gain_s = path, lookahead_m, gain_s
        self.index: int | None = None

    def reference(self, position_m: np.ndarray, velocity_m_s: np.ndarray, t_s: float):
        """``(target (3,), closest (3,), at_end)`` for the swimmer at ``position_m``."""
        pts = self.path.points(t_s)
        n = len(pts)
        if self.index is None:
            idx = np.arange(n)
        elif self.path.closed:
            idx = (self.index + np.arange(-WINDOW_BACK, WINDOW_AHEAD)) % n
        else:
            idx = np.arange(max(self.index - WINDOW_BACK, 0), min(self.index + WINDOW_AHEAD, n))
        d2 = ((pts[idx] - position_m) ** 2).sum(axis=1)
        self.index = int(idx[np.argmin(d2)])
        spacing = np.linalg.norm(pts[1] - pts[0])
        ahead = int(round((self.lookahead_m + self.gain_s * np.linalg.norm(velocity_m_s)) / spacing))
        target_idx = self.index + ahead
        at_end = False
        if self.path.closed:
            target_idx %= n
        elif target_idx >= n - 1:
            target_idx, at_end = n - 1, True
        return pts[target_idx], pts[self.index], at_end

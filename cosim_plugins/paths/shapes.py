"""Path shapes. Parameters in mm, degrees and Hz; points in m."""

from __future__ import annotations

import numpy as np

from cosim.contract.paths import ReferencePath, resample

_MM = 1e-3
#: Spacing of the dense polyline every shape here returns [m].
SPACING_M = 0.5e-3


def rotation_y(angle_rad: float) -> np.ndarray:
    """Rotation matrix about +y by ``angle_rad`` [rad], shape (3, 3)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


class Path(ReferencePath):
    """A shape of this package: its polyline resampled every :data:`SPACING_M`."""

    spacing_m = SPACING_M


def _racetrack_xy(straight_mm: float, radius_mm: float, n: int = 2000) -> tuple[np.ndarray, np.ndarray]:
    """Stadium curve in the xy plane centred at the origin, counter-clockwise.

    Returns ``(xy (n, 2) [m], phase (n,))`` where phase in [0, 4) marks the
    sections: [0,1) bottom straight, [1,2) right curve, [2,3) top straight,
    [3,4) left curve.
    """
    a, r = straight_mm / 2 * _MM, radius_mm * _MM
    u = np.linspace(0.0, 4.0, n, endpoint=False)
    sec, f = np.floor(u).astype(int), u - np.floor(u)
    x = np.select([sec == 0, sec == 1, sec == 2, sec == 3],
                  [-a + 2 * a * f, a + r * np.sin(np.pi * f), a - 2 * a * f, -a - r * np.sin(np.pi * f)])
    y = np.select([sec == 0, sec == 1, sec == 2, sec == 3],
                  [-r + 0 * f, -r * np.cos(np.pi * f), r + 0 * f, r * np.cos(np.pi * f)])
    return np.stack([x, y], axis=1), u


class Racetrack(Path):
    """Racetrack (stadium) in a horizontal plane: two straights joined by half circles."""

    def __init__(self, straight_mm: float = 30.0, radius_mm: float = 40.0, z_mm: float = 0.0,
                 angle_deg: float = 0.0):
        if straight_mm < 0 or radius_mm <= 0:
            raise ValueError("straight_mm must be >= 0 and radius_mm > 0")
        self.straight_mm, self.radius_mm, self.z_mm, self.angle_deg = straight_mm, radius_mm, z_mm, angle_deg

    def base_points(self):
        xy, _ = _racetrack_xy(self.straight_mm, self.radius_mm)
        pts = np.column_stack([xy, np.full(len(xy), self.z_mm * _MM)])
        return pts @ rotation_y(np.radians(self.angle_deg)).T


class Circle(Path):
    """Circle of radius ``radius_mm`` in the xy plane, rotated about y by ``angle_deg``."""

    def __init__(self, radius_mm: float = 35.0, angle_deg: float = 0.0, center_mm=(0.0, 0.0, 0.0)):
        if radius_mm <= 0:
            raise ValueError("radius_mm must be > 0")
        self.radius_mm, self.angle_deg = radius_mm, angle_deg
        self.center = np.asarray(center_mm, dtype=float) * _MM

    def base_points(self):
        th = np.linspace(0.0, 2 * np.pi, 2000, endpoint=False)
        pts = self.radius_mm * _MM * np.column_stack([np.cos(th), np.sin(th), np.zeros_like(th)])
        return pts @ rotation_y(np.radians(self.angle_deg)).T + self.center


class RotatingCircle(Circle):
    """The paper's validation path: a circle whose plane rotates continuously about y.

    At time t the circle is rotated about y by ``angle_deg + 360 * rate_hz * t``
    (the paper: radius 35 mm, 0.5 Hz).
    """

    time_varying = True

    def __init__(self, radius_mm: float = 35.0, rate_hz: float = 0.5, angle_deg: float = 0.0):
        super().__init__(radius_mm=radius_mm, angle_deg=0.0)
        self.rate_hz, self.angle0_deg = rate_hz, angle_deg
        self._flat = resample(super().base_points(), SPACING_M, True)

    def points(self, t_s: float = 0.0):
        angle = np.radians(self.angle0_deg) + 2 * np.pi * self.rate_hz * t_s
        return self._flat @ rotation_y(angle).T

    def motion(self, t_s: float):
        """Rigid: ``points(t) = points(0) @ R.T``, R the rotation about y by ``360 * rate_hz * t``."""
        return rotation_y(2 * np.pi * self.rate_hz * t_s), np.zeros(3)


class Helix(Path):
    """Helix about z: ``turns`` turns of radius ``radius_mm`` climbing ``height_mm`` centred at z = 0.

    Open path: the reference stops at its end.
    """

    closed = False

    def __init__(self, radius_mm: float = 30.0, height_mm: float = 60.0, turns: float = 3.0):
        if radius_mm <= 0 or turns <= 0:
            raise ValueError("radius_mm and turns must be > 0")
        self.radius_mm, self.height_mm, self.turns = radius_mm, height_mm, turns

    def base_points(self):
        th = np.linspace(0.0, 2 * np.pi * self.turns, int(2000 * self.turns))
        z = (th / th[-1] - 0.5) * self.height_mm
        return _MM * np.column_stack([self.radius_mm * np.cos(th), self.radius_mm * np.sin(th), z])


class HelixRacetrack(Path):
    """Racetrack whose curves are half helix turns: level straights at two heights.

    Bottom straight at ``-height_mm/2``, climb on the right curve, top straight
    at ``+height_mm/2``, descent on the left curve: a closed 3D loop.
    """

    def __init__(self, straight_mm: float = 30.0, radius_mm: float = 40.0, height_mm: float = 30.0):
        if straight_mm < 0 or radius_mm <= 0:
            raise ValueError("straight_mm must be >= 0 and radius_mm > 0")
        self.straight_mm, self.radius_mm, self.height_mm = straight_mm, radius_mm, height_mm

    def base_points(self):
        xy, u = _racetrack_xy(self.straight_mm, self.radius_mm)
        sec, f = np.floor(u), u - np.floor(u)
        h = self.height_mm / 2 * _MM
        z = np.select([sec == 0, sec == 1, sec == 2, sec == 3], [-h + 0 * f, -h + 2 * h * f, h + 0 * f, h - 2 * h * f])
        return np.column_stack([xy, z])

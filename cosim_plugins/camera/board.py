"""The calibration target: a checkerboard, and where it lies in the tank when the cameras' pose is taken.

Its file (YAML)::

    inner_corners: [11, 8]       # corners along the board's x (a row) and y; one even, one odd
    square_mm: 10.0
    origin_mm: [-50, -35, 0]     # the first inner corner in the tank frame [mm]
    x_axis: [1, 0, 0]            # the board's x direction in the tank frame
    y_axis: [0, 1, 0]            # its y direction (perpendicular to x); x_axis x y_axis points out
                                 # of the printed face, towards the camera
    origin_square: dark          # the square between the first corner and the one diagonally inward

With one even and one odd count, the colour of that square tells the first
corner from the last, so the corners found in an image are numbered as in
the file whichever way up the board is seen.

:func:`render_board` draws the board as a pinhole camera (no distortion)
sees it, for tests and demonstrations of ``cosim camera calibrate``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml

from cosim.contract.errors import UserError
from cosim_plugins.camera.calibration import CameraModel

WHITE_DN, DARK_DN, SURROUND_DN = 220, 30, 120
SUPERSAMPLE = 4


@dataclass(frozen=True)
class Target:
    """A checkerboard of ``cols`` x ``rows`` inner corners, ``square_m`` apart, placed with its first
    corner at ``origin_m`` (3,) and its axes along ``x_axis``, ``y_axis`` (3,) of the tank frame."""

    cols: int
    rows: int
    square_m: float
    origin_m: np.ndarray
    x_axis: np.ndarray
    y_axis: np.ndarray
    origin_dark: bool = True

    @property
    def pattern(self) -> tuple[int, int]:
        return self.cols, self.rows

    def board_points(self) -> np.ndarray:
        """(cols * rows, 3) corners in the board's own frame [m], row by row as OpenCV finds them."""
        j, i = np.divmod(np.arange(self.cols * self.rows), self.cols)
        return np.stack([i * self.square_m, j * self.square_m, np.zeros(len(i))], axis=1)

    def tank_points(self) -> np.ndarray:
        """(cols * rows, 3) the same corners in the tank frame [m] at the target's pose."""
        b = self.board_points()
        return self.origin_m + b[:, :1] * self.x_axis + b[:, 1:2] * self.y_axis

    def pose_in(self, camera: CameraModel) -> tuple[np.ndarray, np.ndarray]:
        """(R (3, 3), t (3,) [m]): board frame -> ``camera``'s frame at the target's pose."""
        board_to_tank = np.stack([self.x_axis, self.y_axis, np.cross(self.x_axis, self.y_axis)], axis=1)
        return camera.R @ board_to_tank, camera.R @ self.origin_m + camera.t_m


def load_target(path: str | Path) -> Target:
    """Read a target file (see the module docstring); errors name the file and the field."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"target file {path} does not exist")
    try:
        data = yaml.safe_load(path.read_text())
        cols, rows = (int(v) for v in data["inner_corners"])
        square_m = float(data["square_mm"]) * 1e-3
        origin = np.asarray(data["origin_mm"], dtype=float) * 1e-3
        x_axis, y_axis = (np.asarray(data[k], dtype=float) for k in ("x_axis", "y_axis"))
        dark = str(data.get("origin_square", "dark"))
    except (yaml.YAMLError, TypeError, ValueError) as exc:
        raise UserError(f"target file {path}: {exc}") from None
    except KeyError as exc:
        raise UserError(f"target file {path}: missing {exc.args[0]}") from None
    if origin.shape != (3,) or x_axis.shape != (3,) or y_axis.shape != (3,):
        raise UserError(f"target file {path}: origin_mm, x_axis and y_axis need 3 numbers each")
    if (cols + rows) % 2 == 0 or min(cols, rows) < 2:
        raise UserError(f"target file {path}: inner_corners {cols}x{rows}: give one even and one odd count "
                        "(at least 2), so the board's first corner can be told from its last")
    x_axis, y_axis = x_axis / np.linalg.norm(x_axis), y_axis / np.linalg.norm(y_axis)
    if abs(x_axis @ y_axis) > 1e-3:
        raise UserError(f"target file {path}: x_axis and y_axis are not perpendicular")
    if dark not in ("dark", "light"):
        raise UserError(f"target file {path}: origin_square must be dark or light, got {dark!r}")
    return Target(cols, rows, square_m, origin, x_axis, y_axis, dark == "dark")


def render_board(camera: CameraModel, target: Target, R: np.ndarray, t_m: np.ndarray,
                 rng: np.random.Generator, noise_dn: float = 2.0, blur_px: float = 0.7,
                 texture_px_per_m: float = 20000.0) -> np.ndarray:
    """What ``camera`` (pinhole, its distortion ignored) sees of the board placed at ``R`` (3, 3),
    ``t_m`` (3,) (board frame -> camera frame): a (height, width) uint8 image, ``SUPERSAMPLE`` x
    ``SUPERSAMPLE`` samples a pixel."""
    sq, res = target.square_m, texture_px_per_m
    lo = -2 * sq  # a row of squares around the inner corners, and a white margin of one square
    n_x, n_y = int(round((target.cols + 3) * sq * res)), int(round((target.rows + 3) * sq * res))
    a = np.floor((lo + (np.arange(n_x) + 0.5) / res) / sq).astype(int)
    b = np.floor((lo + (np.arange(n_y) + 0.5) / res) / sq).astype(int)
    dark = ((a[None, :] + b[:, None]) % 2 == 0) == target.origin_dark
    inside = (a[None, :] >= -1) & (a[None, :] <= target.cols - 1) & (b[:, None] >= -1) & (b[:, None] <= target.rows - 1)
    texture = np.where(inside & dark, DARK_DN, WHITE_DN).astype(np.uint8)
    to_board = np.array([[1 / res, 0, lo + 0.5 / res], [0, 1 / res, lo + 0.5 / res], [0, 0, 1]])
    H = camera.K @ np.column_stack([R[:, 0], R[:, 1], t_m])
    n = SUPERSAMPLE  # full pixel x spans sub-pixels n x .. n x + n - 1, centred at n x + (n - 1) / 2
    finer = np.array([[n, 0, (n - 1) / 2], [0, n, (n - 1) / 2], [0, 0, 1.0]])
    w, h = camera.size
    big = cv2.warpPerspective(texture, finer @ H @ to_board, (n * w, n * h), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=SURROUND_DN)
    image = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)
    if blur_px > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur_px)
    image += rng.normal(0.0, noise_dn, image.shape).astype(np.float32)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)

"""Calibrating one camera from checkerboard images: intrinsics, distortion, and its pose in the tank.

OpenCV's procedure (https://docs.opencv.org/5.x/dc/dbb/tutorial_py_calibration.html):
``findChessboardCorners`` and ``cornerSubPix`` in every image, then
``calibrateCamera`` over all of them for the camera matrix and distortion
(k3 fixed at 0: the lab's lenses are not wide-angle, and a free k3 fits the
noise), then ``solvePnP`` of the pose image's corners against the target's
corners in the tank frame (:mod:`~cosim_plugins.camera.board`) for the
camera's rotation and translation. Errors name the image.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from cosim.contract.errors import UserError
from cosim_plugins.camera.board import Target
from cosim_plugins.camera.calibration import CameraModel

MIN_VIEWS = 3
_SUBPIX = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4)
_FIND = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE


@dataclass
class CalibrationReport:
    """What a calibration used and how well it fits: ``used`` and ``skipped`` images,
    ``pose_rms_px``: the target's reprojection RMS in the pose image."""

    camera: CameraModel
    used: list[Path]
    skipped: list[Path]
    pose_rms_px: float


def read_grey(path: Path) -> np.ndarray:
    """An image file as 8-bit grey levels (h, w); a missing or unreadable file raises :class:`UserError`."""
    if not Path(path).is_file():
        raise UserError(f"image {path} does not exist")
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise UserError(f"image {path}: cannot be read (corrupted or not an image)")
    return image


def find_corners(image: np.ndarray, target: Target) -> np.ndarray | None:
    """The inner corners (cols * rows, 2) [px], numbered as in the target file, or None.

    A board's corner grid looks the same numbered from any of its four corners, two of those
    numberings mirror it. Seen from its printed face, the board's x and y axes turn clockwise in
    the image (x right, y down), which fixes the handedness; the first square's colour then tells
    the first corner from the last.
    """
    found, corners = cv2.findChessboardCorners(image, target.pattern, flags=_FIND)
    if not found:
        return None
    grid = cv2.cornerSubPix(image, corners, (5, 5), (-1, -1), _SUBPIX).reshape(target.rows, target.cols, 2)
    along_x, along_y = grid[0, 1] - grid[0, 0], grid[1, 0] - grid[0, 0]
    if along_x[0] * along_y[1] - along_x[1] * along_y[0] > 0:
        grid = grid[:, ::-1]  # numbered as the board's mirror image: its face turns the board's x x y away
    corners = grid.reshape(-1, 2)
    if _first_square_dark(image, corners, target.cols) != target.origin_dark:
        corners = corners[::-1]  # the board seen the other way up
    return np.ascontiguousarray(corners)


def _first_square_dark(image: np.ndarray, corners: np.ndarray, cols: int) -> bool:
    """Whether the square between corners 0 and cols + 1 is darker than its neighbour along the row."""
    first = (corners[0] + corners[cols + 1]) / 2
    beside = (corners[1] + corners[cols + 2]) / 2
    (x0, y0), (x1, y1) = np.rint(first).astype(int), np.rint(beside).astype(int)
    return int(image[y0, x0]) < int(image[y1, x1])


def calibrate(images: list[Path], target: Target, pose_image: Path) -> CalibrationReport:
    """One camera from ``images`` of the board at varied poses and ``pose_image`` of it at the target's pose."""
    paths = list(dict.fromkeys([Path(pose_image), *map(Path, images)]))
    size = None
    board, pixels, used, skipped = [], [], [], []
    pose_corners = None
    for path in paths:
        image = read_grey(path)
        if size is None:
            size = (image.shape[1], image.shape[0])
        elif (image.shape[1], image.shape[0]) != size:
            raise UserError(f"image {path}: {image.shape[1]}x{image.shape[0]} px, {paths[0]} is "
                            f"{size[0]}x{size[1]} px (one camera's images share a size)")
        corners = find_corners(image, target)
        if path == Path(pose_image):
            if corners is None:
                raise UserError(f"pose image {path}: no {target.cols}x{target.rows} checkerboard found")
            pose_corners = corners
        if corners is None:
            skipped.append(path)
            continue
        board.append(target.board_points().astype(np.float32))
        pixels.append(corners.astype(np.float32))
        used.append(path)
    if len(used) < MIN_VIEWS:
        raise UserError(f"the board was found in {len(used)} of {len(paths)} images; at least {MIN_VIEWS} "
                        "are needed (10-20 at varied tilts and places calibrate well)")
    rms, K, dist, _, _ = cv2.calibrateCamera(board, pixels, size, None, None, flags=cv2.CALIB_FIX_K3)
    ok, rvec, tvec = cv2.solvePnP(target.tank_points(), pose_corners.astype(np.float64), K, dist,
                                  flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise UserError(f"pose image {pose_image}: solvePnP found no pose for the target")
    camera = CameraModel(size, K, dist.reshape(-1), cv2.Rodrigues(rvec)[0], tvec.reshape(3), float(rms))
    residual = camera.project(target.tank_points()) - pose_corners
    return CalibrationReport(camera, used, skipped, float(np.sqrt((residual**2).sum(axis=1).mean())))

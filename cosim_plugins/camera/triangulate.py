"""Two-view triangulation of pixel pairs, with each pair's reprojection error.

The general two-view case: both pixels are undistorted to normalised image
coordinates, ``cv2.triangulatePoints`` solves the linear (DLT) system with
the cameras' normalised projections ``[R | t]``, and the point found is
projected back into both views; the reprojection error measures how well
the two detections agree (an epipolar check: a blob in one view that is not
the swimmer seen in the other leaves a large error).
"""

from __future__ import annotations

import cv2
import numpy as np

from cosim_plugins.camera.calibration import CameraModel


def triangulate(cam_a: CameraModel, cam_b: CameraModel, px_a: np.ndarray, px_b: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """Tank points (n, 3) [m] of pixel pairs ``px_a``, ``px_b`` (n, 2) and their RMS reprojection
    error over the two views (n,) [px]. Vectorised over the n pairs."""
    na, nb = cam_a.normalise(px_a), cam_b.normalise(px_b)
    homogeneous = cv2.triangulatePoints(cam_a.pose, cam_b.pose, na.T.copy(), nb.T.copy())  # (4, n)
    points = (homogeneous[:3] / homogeneous[3]).T
    err_a = _normalised_residual(cam_a, points, na) * cam_a.focal_px
    err_b = _normalised_residual(cam_b, points, nb) * cam_b.focal_px
    return points, np.sqrt((err_a**2 + err_b**2) / 2.0)


def _normalised_residual(cam: CameraModel, points_m: np.ndarray, normalised: np.ndarray) -> np.ndarray:
    """Distance (n,) between the points' normalised projections and the detections (n, 2)."""
    x_c = points_m @ cam.R.T + cam.t_m
    return np.hypot(x_c[:, 0] / x_c[:, 2] - normalised[:, 0], x_c[:, 1] / x_c[:, 2] - normalised[:, 1])

"""Calibrated cameras: intrinsics, distortion and pose in the tank frame, and their YAML file.

A camera maps a point ``X`` of the tank frame [m] (origin at the manipulator
centre, z up) to pixels in two steps: ``x_c = R X + t`` (``R``: rotation
tank -> camera, ``t`` [m]), then OpenCV's pinhole model with the distortion
coefficients ``(k1, k2, p1, p2, k3)`` and the camera matrix ``K`` [px]
(https://docs.opencv.org/5.x/d9/d0c/group__calib3d.html). The file, written
by ``cosim camera calibrate`` and by the renderer, is plain YAML::

    cameras:
      top:
        image_size: [800, 600]                                  # width, height [px]
        camera_matrix: [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]    # [px]
        dist_coeffs: [k1, k2, p1, p2, k3]
        rvec: [rx, ry, rz]        # rotation tank -> camera, Rodrigues vector [rad]
        tvec_m: [tx, ty, tz]      # translation tank -> camera [m]
        rms_px: 0.2               # calibrateCamera's RMS reprojection error (optional)
      side: {...}

Errors name the file and the camera.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import yaml

from cosim.contract.errors import UserError

#: The views, in the order of every pair: the lab's top and side cameras (paper, Sec. III-A).
VIEWS = ("top", "side")


class CalibrationError(UserError):
    """A calibration file is missing, malformed or does not fit the cameras."""


@dataclass
class CameraModel:
    """One calibrated camera.

    ``size``: (width, height) [px]; ``K``: (3, 3) camera matrix [px]; ``dist``:
    (5,) distortion coefficients; ``R``: (3, 3) rotation tank -> camera;
    ``t_m``: (3,) translation tank -> camera [m]; ``rms_px``: the calibration's
    RMS reprojection error, None for an exact (rendered) camera.
    """

    size: tuple[int, int]
    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    t_m: np.ndarray
    rms_px: float | None = None
    pose: np.ndarray = field(init=False, repr=False)  # (3, 4) [R | t], the normalised projection
    rvec: np.ndarray = field(init=False, repr=False)  # (3,) R as a Rodrigues vector [rad]

    def __post_init__(self) -> None:
        self.K = np.asarray(self.K, dtype=float).reshape(3, 3)
        self.dist = np.asarray(self.dist, dtype=float).reshape(-1)
        self.R = np.asarray(self.R, dtype=float).reshape(3, 3)
        self.t_m = np.asarray(self.t_m, dtype=float).reshape(3)
        self.size = (int(self.size[0]), int(self.size[1]))
        self.pose = np.hstack([self.R, self.t_m[:, None]])
        self.rvec = cv2.Rodrigues(self.R)[0].reshape(3)

    @property
    def centre_m(self) -> np.ndarray:
        """(3,) the camera's optical centre in the tank frame [m]."""
        return -self.R.T @ self.t_m

    @property
    def focal_px(self) -> float:
        return float((self.K[0, 0] + self.K[1, 1]) / 2)

    def project(self, points_m: np.ndarray) -> np.ndarray:
        """Pixels (n, 2) of tank points (n, 3) [m], with distortion."""
        pts = np.asarray(points_m, dtype=float).reshape(-1, 1, 3)
        px, _ = cv2.projectPoints(pts, self.rvec, self.t_m, self.K, self.dist)
        return px.reshape(-1, 2)

    def normalise(self, pixels: np.ndarray) -> np.ndarray:
        """Undistorted normalised image coordinates (n, 2) of pixels (n, 2)."""
        pts = np.asarray(pixels, dtype=float).reshape(-1, 1, 2)
        return cv2.undistortPoints(pts, self.K, self.dist).reshape(-1, 2)

    def to_dict(self) -> dict:
        out = {"image_size": list(self.size), "camera_matrix": self.K.tolist(),
               "dist_coeffs": self.dist.tolist(), "rvec": self.rvec.tolist(), "tvec_m": self.t_m.tolist()}
        if self.rms_px is not None:
            out["rms_px"] = float(self.rms_px)
        return out

    @classmethod
    def from_dict(cls, data: dict, where: str) -> "CameraModel":
        try:
            size = [int(v) for v in data["image_size"]]
            K = np.asarray(data["camera_matrix"], dtype=float)
            dist = np.asarray(data["dist_coeffs"], dtype=float)
            rvec = np.asarray(data["rvec"], dtype=float)
            t = np.asarray(data["tvec_m"], dtype=float)
        except KeyError as exc:
            raise CalibrationError(f"{where}: missing {exc.args[0]}") from None
        except (TypeError, ValueError) as exc:
            raise CalibrationError(f"{where}: not numbers: {exc}") from None
        if len(size) != 2 or K.shape != (3, 3) or dist.size not in (4, 5, 8, 12, 14) or rvec.shape != (3,) \
                or t.shape != (3,) or min(size) <= 0:
            raise CalibrationError(f"{where}: expected image_size [w, h], a 3x3 camera_matrix, 4-14 "
                                   "dist_coeffs, rvec and tvec_m of 3 numbers")
        return cls(tuple(size), K, dist, cv2.Rodrigues(rvec)[0], t, data.get("rms_px"))


@dataclass
class Calibration:
    """The two cameras (``VIEWS`` order) and the file they came from."""

    cameras: dict[str, CameraModel]
    source: str = "<memory>"

    def __getitem__(self, view: str) -> CameraModel:
        return self.cameras[view]

    def check_size(self, view: str, size: tuple[int, int], device: str) -> None:
        """Raise if ``device``'s frames (width, height) do not have the calibrated size."""
        want = self.cameras[view].size
        if tuple(size) != want:
            raise CalibrationError(f"calibration {self.source}: camera {view} is calibrated for "
                                   f"{want[0]}x{want[1]} px but {device} gives {size[0]}x{size[1]} px")

    def _ordered(self) -> list[str]:
        return sorted(self.cameras, key=lambda v: VIEWS.index(v) if v in VIEWS else len(VIEWS))

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        text = ("# camera calibration: pixels of tank points [m] (see cosim_plugins.camera.calibration)\n"
                + yaml.safe_dump({"cameras": {v: self.cameras[v].to_dict() for v in self._ordered()}},
                                 sort_keys=False, default_flow_style=None, width=120))
        path.write_text(text)
        return path


def load_calibration(path: str | Path, views: tuple[str, ...] = VIEWS) -> Calibration:
    """Read a calibration file holding (at least) ``views``."""
    path = Path(path)
    if not path.is_file():
        raise CalibrationError(f"calibration file {path} does not exist")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise CalibrationError(f"calibration {path}: not valid YAML: {getattr(exc, 'problem', exc)}") from None
    cams = data.get("cameras") if isinstance(data, dict) else None
    if not isinstance(cams, dict):
        raise CalibrationError(f"calibration {path}: expected a mapping 'cameras: {{top: ..., side: ...}}'")
    missing = [v for v in views if v not in cams]
    if missing:
        raise CalibrationError(f"calibration {path}: no camera {', '.join(missing)} (has: {', '.join(cams)})")
    return Calibration({v: CameraModel.from_dict(cams[v], f"calibration {path}, camera {v}") for v in cams},
                       str(path))


def update_calibration(path: str | Path, view: str, camera: CameraModel) -> Calibration:
    """Put ``camera`` as ``view`` into the file at ``path`` (created if missing), keeping the others."""
    path = Path(path)
    cal = load_calibration(path, views=()) if path.is_file() else Calibration({}, str(path))
    cal.cameras[view] = camera
    cal.save(path)
    return cal

"""The renderer: frame pairs drawn from the plant's true position and axis.

What the lab's two Basler acA800 cameras (paper, Sec. III-A: top and side)
would see of the 2.5 mm x 6 mm swimmer: a dark body on the lit tank, at the
camera's default 800 x 600 px of 4.8 um (docs.baslerweb.com/aca800-510uc),
behind an 8 mm lens 500 mm from the tank centre, so the whole 150 mm tank
fits the 600 px (its near face spans 589) and a pixel spans 0.29 mm at the
centre. Each frame has:

* the lit background: ``background_dn`` with vignetting, the tank's edges
  drawn faintly (``wall_dn`` darker);
* the body: the silhouette of a capsule (the swimmer's length and diameter)
  about the true axis, anti-aliased, ``body_dn`` dark, blurred by the optics
  (Gaussian, ``blur_px``);
* wall reflections: each camera sees the swimmer mirrored in the two tank
  walls across its image's vertical (top: the y walls; side: the floor and
  the water surface) while it is within ``reflection_mm`` of one, at
  ``reflection_contrast`` of its darkness, outside the tank;
* glints: with probability ``glint_prob`` a pair has a swimmer-like dark
  blob at a random place in one view only (the paper's Fig. 5 spikes);
* sensor noise: Gaussian, ``noise_dn``, drawn once per camera into a bank a
  little larger than the frame, each frame reading it at a random offset
  (a fresh draw per frame costs ~10 ms at this size);
* drops: each frame is lost with probability ``drop_prob``.

The cameras are the :func:`acA800_pair` geometry unless a calibration is
given, and the renderer draws exactly what that calibration says, so its
own calibration file is exact. All draws come from the component's RNG, the
same number every grab.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import cv2
import numpy as np

from cosim_plugins.camera.calibration import VIEWS, Calibration, CameraModel
from cosim_plugins.camera.sources.base import FramePair, FrameSource

SIZE_PX = (800, 600)  # acA800 default width, height
PIXEL_M = 4.8e-6
LENS_M = 0.008
DISTANCE_M = 0.5  # camera to tank centre
SWIMMER_LENGTH_M = 0.006
SWIMMER_DIAMETER_M = 0.0025
TANK_HALF_M = 0.075
NOISE_PAD_PX = 64  # the noise bank's margin: the offsets a frame may read it at


def acA800_pair() -> Calibration:
    """The renderer's exact cameras: top looking down (image right = +x, down = -y), side on the
    -y side looking along +y (right = +x, down = -z), no distortion."""
    f = LENS_M / PIXEL_M
    K = np.array([[f, 0.0, (SIZE_PX[0] - 1) / 2], [0.0, f, (SIZE_PX[1] - 1) / 2], [0.0, 0.0, 1.0]])
    top_R = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    side_R = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    cams = {}
    for view, R, centre in (("top", top_R, [0.0, 0.0, DISTANCE_M]), ("side", side_R, [0.0, -DISTANCE_M, 0.0])):
        cams[view] = CameraModel(SIZE_PX, K, np.zeros(5), R, -R @ np.array(centre))
    return Calibration(cams, "the renderer's acA800 pair")


@dataclass(frozen=True)
class Look:
    """How the rendered frames look (grey levels in DN of 8 bits)."""

    background_dn: float = 200.0
    vignetting: float = 0.2  # fraction of the background lost in the image corners
    wall_dn: float = 15.0
    body_dn: float = 40.0
    blur_px: float = 0.8
    noise_dn: float = 2.0
    drop_prob: float = 0.0
    glint_prob: float = 0.0
    reflection_mm: float = 15.0
    reflection_contrast: float = 0.6


class Renderer(FrameSource):
    """Draws a frame pair of the true swimmer each grab (see the module docstring)."""

    def __init__(self, calibration: Calibration, look: Look, rng: np.random.Generator):
        self.cal, self.look, self.rng = calibration, look, rng
        self.cams = [calibration[v] for v in VIEWS]
        self.devices = tuple(f"renderer ({v})" for v in VIEWS)
        self.sizes = tuple(c.size for c in self.cams)
        self.backgrounds = [self._background(c) for c in self.cams]
        self.noise = [self._noise_bank(c) for c in self.cams]
        # the tank walls each view sees reflections in: the axis closest to its image's vertical
        self.mirror_axes = [int(np.argmax(np.abs(c.R[1]))) for c in self.cams]

    # ------------------------------------------------------------------ set-up
    def _background(self, cam: CameraModel) -> np.ndarray:
        """The lit tank (height, width) uint8: vignetting and the tank's edges."""
        w, h = cam.size
        y, x = np.mgrid[0:h, 0:w].astype(np.float32)
        r2 = ((x - w / 2) ** 2 + (y - h / 2) ** 2) / ((w / 2) ** 2 + (h / 2) ** 2)
        bg = self.look.background_dn * (1.0 - self.look.vignetting * r2)
        edges = np.zeros((h, w), np.float32)
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * TANK_HALF_M
        px = cam.project(corners)
        for i in range(8):
            for j in range(i + 1, 8):
                if np.sum(corners[i] != corners[j]) == 1:  # an edge of the cube
                    a, b = np.round(px[i] * 16).astype(int), np.round(px[j] * 16).astype(int)
                    cv2.line(edges, tuple(a), tuple(b), 1.0, 2, cv2.LINE_AA, shift=4)
        return np.clip(bg - self.look.wall_dn * edges, 0, 255).round().astype(np.uint8)

    def _noise_bank(self, cam: CameraModel) -> tuple[np.ndarray, np.ndarray]:
        """Positive and negative parts (uint8) of a Gaussian noise field a little larger than the frame."""
        w, h = cam.size
        noise = np.rint(self.rng.normal(0.0, self.look.noise_dn, (h + NOISE_PAD_PX, w + NOISE_PAD_PX)))
        noise = np.clip(noise, -255, 255)
        return np.maximum(noise, 0).astype(np.uint8), np.maximum(-noise, 0).astype(np.uint8)

    # ------------------------------------------------------------------ frames
    def grab(self, t_s: float, scene: Mapping[str, np.ndarray]) -> FramePair:
        look, rng = self.look, self.rng
        u = rng.random(4)  # drop top, drop side, glint, glint's view: always four draws
        glint = rng.uniform(-1.0, 1.0, 6)  # the glint's place in the tank and its axis
        offsets = rng.integers(0, NOISE_PAD_PX, 4)
        position = np.asarray(scene["position"], dtype=float)
        axis = np.asarray(scene["axis"], dtype=float)
        images = []
        for i in range(len(VIEWS)):
            if u[i] < look.drop_prob:
                images.append(None)
                continue
            blobs = self.bodies(i, position, axis)
            if u[2] < look.glint_prob and int(u[3] * len(VIEWS)) == i:
                blobs.append((glint[:3] * TANK_HALF_M * 0.8, glint[3:], 1.0))
            images.append(self.draw(i, blobs, offsets[2 * i: 2 * i + 2]))
        return FramePair((images[0], images[1]), float(t_s))

    def bodies(self, view: int, position_m: np.ndarray, axis: np.ndarray) -> list[tuple]:
        """What ``view`` sees of the swimmer: (centre [m], axis, contrast) of the body and of
        its reflections in the walls it is near."""
        if not np.all(np.isfinite(position_m)):
            return []
        out = [(position_m, axis, 1.0)]
        k = self.mirror_axes[view]
        for wall in (-TANK_HALF_M, TANK_HALF_M):
            if abs(wall - position_m[k]) < self.look.reflection_mm * 1e-3:
                mirrored, flipped = position_m.copy(), axis.copy()
                mirrored[k], flipped[k] = 2 * wall - position_m[k], -axis[k]
                out.append((mirrored, flipped, self.look.reflection_contrast))
        return out

    def draw(self, view: int, blobs: list[tuple], noise_offset=(0, 0)) -> np.ndarray:
        """One frame (height, width) uint8 of ``view`` with ``blobs`` ((centre [m], axis, contrast), ...)
        on the background, then the noise bank read at ``noise_offset`` (x, y) [px]."""
        cam, img = self.cams[view], self.backgrounds[view].copy()
        for centre, axis, contrast in blobs:
            self._composite(img, cam, np.asarray(centre, float), np.asarray(axis, float), contrast)
        w, h = cam.size
        ox, oy = int(noise_offset[0]), int(noise_offset[1])
        plus, minus = self.noise[view]
        cv2.add(img, plus[oy: oy + h, ox: ox + w], dst=img)
        cv2.subtract(img, minus[oy: oy + h, ox: ox + w], dst=img)
        return img

    def _composite(self, img: np.ndarray, cam: CameraModel, centre: np.ndarray, axis: np.ndarray,
                   contrast: float) -> None:
        """Darken ``img`` in place by the blurred silhouette of a capsule body at ``centre`` [m]."""
        norm = np.linalg.norm(axis)
        axis = axis / norm if norm > 0 else np.array([1.0, 0.0, 0.0])
        depth = (cam.R @ centre + cam.t_m)[2]
        if depth <= 0:
            return
        radius_m = SWIMMER_DIAMETER_M / 2
        half = (SWIMMER_LENGTH_M / 2 - radius_m) * axis
        a, b = cam.project(np.array([centre - half, centre + half]))
        r_px = cam.focal_px * radius_m / depth
        pad = r_px + 4.0 * self.look.blur_px + 2.0
        h, w = img.shape
        x0, y0 = np.floor(np.minimum(a, b) - pad).astype(int)
        x1, y1 = np.ceil(np.maximum(a, b) + pad).astype(int) + 1
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        if x0 >= x1 or y0 >= y1:
            return
        x = np.arange(x0, x1, dtype=np.float32)[None, :] - np.float32(a[0])  # relative to the end a
        y = np.arange(y0, y1, dtype=np.float32)[:, None] - np.float32(a[1])
        ab = (b - a).astype(np.float32)
        s = np.clip((x * ab[0] + y * ab[1]) / np.float32(max(ab @ ab, 1e-12)), 0.0, 1.0)
        d = np.hypot(x - s * ab[0], y - s * ab[1])
        coverage = np.clip(np.float32(r_px + 0.5) - d, 0.0, 1.0)
        if self.look.blur_px > 0:
            coverage = cv2.GaussianBlur(coverage, (0, 0), self.look.blur_px)
        roi = img[y0:y1, x0:x1].astype(np.float32)
        roi -= coverage * contrast * np.maximum(roi - self.look.body_dn, 0.0)
        img[y0:y1, x0:x1] = np.clip(np.rint(roi), 0, 255).astype(np.uint8)

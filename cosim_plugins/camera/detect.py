"""Dark blobs in one camera frame: where the swimmer (or a reflection) may be.

The swimmer is a dark body on a lit background. A blob is a connected set of
pixels (an outer contour) darker than their local background by
``threshold_dn``, of a plausible area and length; its centre is the
darkness-weighted centroid (image moments of ``background - image`` around
the blob, so the blurred edge counts and the centre is sub-pixel).

Two searches, cheapest first:

* tracking: a window of ``search_px`` around where the swimmer is expected
  (the last position projected into the view), at full resolution;
* the whole frame, when nothing is expected or nothing is in the window:
  downscaled ``scale`` times (bilinear; area averaging costs 6x more), the
  local background a 5 x 5 maximum there, each candidate then measured in a
  full-resolution window.

The background of a window is the median of its border.
Pixel coordinates: x right, y down, the centre of pixel (0, 0) at (0, 0),
as ``cv2.projectPoints`` has them.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

_GROW_PX = 3  # margin around a blob's outline that its centre's moments take in (the blurred edge)
_LOCAL_MAX = np.ones((5, 5), np.uint8)


@dataclass(frozen=True)
class BlobParams:
    """Detection settings (pixels of the full-resolution frame, grey levels in DN of 8 bits)."""

    threshold_dn: float = 40.0  # darkness below the local background that counts
    min_area_px: float = 20.0
    max_area_px: float = 2000.0
    max_length_px: float = 80.0  # longest bounding-box side: tank edges and shadows are longer
    search_px: int = 32  # half-size of the tracking window
    scale: int = 4  # downscaling of the whole-frame search
    max_blobs: int = 4  # kept per frame, the strongest first


@dataclass
class Blobs:
    """The blobs of one frame, strongest (darkness x area) first.

    ``centres``: (n, 2) [px]; ``areas``: (n,) [px]; ``darkness``: (n,) mean
    darkness below the background [DN]; ``boxes``: (n, 4) x0, y0, x1, y1 [px].
    """

    centres: np.ndarray
    areas: np.ndarray
    darkness: np.ndarray
    boxes: np.ndarray

    def __len__(self) -> int:
        return len(self.centres)

    @classmethod
    def of(cls, rows: list[tuple], keep: int) -> "Blobs":
        """From rows (u, v, area, darkness, x0, y0, x1, y1), the ``keep`` strongest, far apart."""
        rows = sorted(rows, key=lambda r: -r[2] * r[3])
        kept: list[tuple] = []
        for r in rows:  # one blob found from two candidates is kept once
            if all((r[0] - k[0]) ** 2 + (r[1] - k[1]) ** 2 > 4.0 for k in kept):
                kept.append(r)
        a = np.array(kept[:keep], dtype=float).reshape(-1, 8)
        return cls(a[:, :2], a[:, 2], a[:, 3], a[:, 4:])


def find_blobs(image: np.ndarray, p: BlobParams, expected_px: np.ndarray | None = None) -> Blobs:
    """Blobs of ``image`` (height, width) uint8; ``expected_px`` (2,): where to look first."""
    if expected_px is not None and np.all(np.isfinite(expected_px)):
        rows = _tracked(image, p, expected_px)
        if rows:
            return Blobs.of(rows, p.max_blobs)
    return Blobs.of(_whole_frame(image, p), p.max_blobs)


def _tracked(image: np.ndarray, p: BlobParams, expected_px: np.ndarray) -> list[tuple]:
    """Blobs in the window around ``expected_px``; one cut by the window's edge is measured again
    in a window centred on it."""
    rows = []
    for r in _in_window(image, p, expected_px, p.search_px):
        x0, y0, x1, y1 = _window(image, r[:2], p.search_px)
        if r[4] <= x0 or r[5] <= y0 or r[6] >= x1 - 1 or r[7] >= y1 - 1:
            again = [q for q in _in_window(image, p, np.array(r[:2]), p.search_px)
                     if (q[0] - r[0]) ** 2 + (q[1] - r[1]) ** 2 < p.search_px ** 2]
            rows.extend(again[:1])
        else:
            rows.append(r)
    return rows


def _whole_frame(image: np.ndarray, p: BlobParams) -> list[tuple]:
    """Candidates in the downscaled frame, each measured at full resolution."""
    s = p.scale
    h, w = image.shape
    small = cv2.resize(image, (w // s, h // s), interpolation=cv2.INTER_LINEAR)
    dark = cv2.subtract(cv2.dilate(small, _LOCAL_MAX), small)
    _, mask = cv2.threshold(dark, 0.75 * p.threshold_dn, 255, cv2.THRESH_BINARY)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    candidates = []
    for c in contours:
        x, y, bw, bh = cv2.boundingRect(c)
        if max(bw, bh) * s <= 2 * p.max_length_px:
            patch = dark[y: y + bh, x: x + bw]
            candidates.append((float(patch.sum()), x + bw / 2.0, y + bh / 2.0))
    rows: list[tuple] = []
    half = max(p.search_px, int(p.max_length_px // 2) + 4)
    for _, cx, cy in sorted(candidates, reverse=True)[: 2 * p.max_blobs]:
        centre = np.array([cx * s, cy * s])  # small pixel j spans full pixels s j .. s j + s - 1
        found = _in_window(image, p, centre, half)
        if found:  # the blob nearest the candidate
            rows.append(min(found, key=lambda r: (r[0] - centre[0]) ** 2 + (r[1] - centre[1]) ** 2))
    return rows


def _window(image: np.ndarray, centre: np.ndarray, half: int) -> tuple[int, int, int, int]:
    h, w = image.shape
    cx, cy = int(round(float(centre[0]))), int(round(float(centre[1])))
    return max(cx - half, 0), max(cy - half, 0), min(cx + half + 1, w), min(cy + half + 1, h)


def _in_window(image: np.ndarray, p: BlobParams, centre: np.ndarray, half: int) -> list[tuple]:
    """Blobs (u, v, area, darkness, x0, y0, x1, y1) in the window of half-size ``half`` about ``centre``.

    The background is the median of the window's border; a blob's pixels are those below it by
    ``threshold_dn`` (outer contours); its centre weighs the darkness of its bounding box grown by
    ``_GROW_PX``, counting pixels darker than a quarter of the threshold (the blurred edge, not noise).
    """
    x0, y0, x1, y1 = _window(image, centre, half)
    if x1 - x0 < 3 or y1 - y0 < 3:
        return []
    win = image[y0:y1, x0:x1]
    background = float(np.median(np.concatenate([win[0], win[-1], win[1:-1, 0], win[1:-1, -1]])))
    if background <= p.threshold_dn:
        return []  # a dark frame (a lost one written as black): nothing to see
    _, mask = cv2.threshold(win, background - p.threshold_dn, 255, cv2.THRESH_BINARY_INV)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    rows = []
    floor = p.threshold_dn / 4.0
    for c in contours:
        bx, by, bw, bh = cv2.boundingRect(c)
        area = cv2.contourArea(c) + len(c) / 2.0 + 1.0  # pixel count of the outlined set (Pick's theorem)
        if not p.min_area_px <= area <= p.max_area_px or max(bw, bh) > p.max_length_px:
            continue
        gx0, gy0 = max(bx - _GROW_PX, 0), max(by - _GROW_PX, 0)
        gx1, gy1 = min(bx + bw + _GROW_PX, x1 - x0), min(by + bh + _GROW_PX, y1 - y0)
        dark = background - win[gy0:gy1, gx0:gx1].astype(np.float32)
        m = cv2.moments(np.where(dark > floor, dark, 0.0).astype(np.float32))
        if m["m00"] <= 0:
            continue
        u, v = x0 + gx0 + m["m10"] / m["m00"], y0 + gy0 + m["m01"] / m["m00"]
        rows.append((u, v, area, m["m00"] / area, x0 + bx, y0 + by, x0 + bx + bw - 1, y0 + by + bh - 1))
    return rows

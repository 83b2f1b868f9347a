"""The camera images in the run's recording: each view downscaled, its blobs and the swimmer found.

Logged by the camera component into its own part of the run's recording
(:func:`cosim.api.component_recording`, ``recording.<component>.rrd``),
every ``every`` captures, on the simulated-time timeline:

* ``<component>/<view>/image``: the frame scaled by ``scale``, JPEG-encoded;
* ``<component>/<view>/blobs``: every blob's box, red, the one taken green;
* ``<component>/<view>/found``: the triangulated position projected back, a cross.

:func:`layout_views` gives the layout's 2D view of each camera.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from cosim.api import TIMELINE, component_recording
from cosim_plugins.camera.calibration import VIEWS, Calibration
from cosim_plugins.camera.locate import Fix

JPEG_QUALITY = 80
RED, GREEN = [255, 60, 40], [40, 220, 90]


def layout_views(component: str) -> list:
    """One 2D view per camera, for the run's layout."""
    return [rrb.Spatial2DView(origin=f"{component}/{view}", name=f"{component}: {view}") for view in VIEWS]


class ViewLogger:
    """Writes the camera views of one component as the run goes (see the module docstring)."""

    def __init__(self, run_dir: Path, recording_id: str, component: str, calibration: Calibration,
                 scale: float, every: int):
        self.rec = component_recording(run_dir, recording_id, component)
        self.component, self.cams, self.scale, self.every = component, [calibration[v] for v in VIEWS], scale, every
        self.count = 0

    def log(self, t_s: float, images, fix: Fix) -> None:
        """One pair (when its turn comes): the frames, their blobs and the fix."""
        self.count += 1
        if (self.count - 1) % self.every:
            return
        self.rec.set_time(TIMELINE, duration=float(t_s))
        found_m = fix.position_m if np.all(np.isfinite(fix.position_m)) else None
        for i, (view, image, blobs) in enumerate(zip(VIEWS, images, fix.blobs)):
            base = f"{self.component}/{view}"
            if image is None:
                continue
            small = cv2.resize(image, None, fx=self.scale, fy=self.scale, interpolation=cv2.INTER_AREA)
            ok, jpeg = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            if ok:
                self.rec.log(f"{base}/image", rr.EncodedImage(contents=jpeg.tobytes(), media_type="image/jpeg"))
            if blobs is not None and len(blobs):
                chosen = fix.chosen[i] if fix.chosen else -1
                boxes = blobs.boxes * self.scale
                colors = [GREEN if k == chosen else RED for k in range(len(blobs))]
                self.rec.log(f"{base}/blobs", rr.Boxes2D(mins=boxes[:, :2], sizes=boxes[:, 2:] - boxes[:, :2]
                                                        + self.scale, colors=colors))
            else:
                self.rec.log(f"{base}/blobs", rr.Clear(recursive=False))
            if found_m is not None:
                px = (self.cams[i].project(found_m[None]) + 0.5) * self.scale
                self.rec.log(f"{base}/found", rr.Points2D(px, colors=[GREEN], radii=[2.0]))
            else:
                self.rec.log(f"{base}/found", rr.Clear(recursive=False))

    def close(self) -> None:
        self.rec.flush()
        self.rec.disconnect()

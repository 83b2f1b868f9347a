"""``record_frames``: the raw frames of each camera as a video in the run folder, written as they come.

One file per view, ``frames_<component>_<view>.mkv``: FFV1, lossless, grey,
at the capture rate, so the video source replays a run's frames bit for bit
(``source: video``). A lost frame is written black (nothing is detected in
it), keeping every later frame at its capture index. OpenCV's FFmpeg
backend writes it (https://docs.opencv.org/5.x/dd/d9e/classcv_1_1VideoWriter.html).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from cosim import ComponentError
from cosim_plugins.camera.calibration import VIEWS

FOURCC = "FFV1"


class FrameVideos:
    """One lossless video per view; ``write`` appends a pair's frames."""

    def __init__(self, run_dir: Path, component: str, sizes, fps: float):
        self.paths = [Path(run_dir) / f"frames_{component}_{view}.mkv" for view in VIEWS]
        self.sizes = [tuple(s) for s in sizes]
        self.writers = []
        for path, size in zip(self.paths, self.sizes):
            writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*FOURCC), fps, size, isColor=False)
            if not writer.isOpened():
                self.close()
                raise ComponentError(f"record_frames: cannot write the video {path} ({FOURCC} through OpenCV)")
            self.writers.append(writer)

    def write(self, images) -> None:
        """Append one frame per view ((height, width) uint8, or None for a lost one)."""
        for writer, image, (w, h) in zip(self.writers, images, self.sizes):
            writer.write(np.zeros((h, w), np.uint8) if image is None else image)

    def close(self) -> None:
        for writer in self.writers:
            writer.release()
        self.writers = []

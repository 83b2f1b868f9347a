"""Frames from OpenCV ``VideoCapture``: a USB camera (by index) or a video file per view.

A view given as a whole number is a camera device (``0`` is ``/dev/video0``
on Linux), asked to keep one buffered frame so a grab returns the latest; any
other value is a video file, read one frame per grab (a run's own
``record_frames`` videos replay it exactly). The first frame of each is read
when the source opens, so a device that cannot be opened, a file that is not
a video or cannot be decoded, fails then, naming it. The capture time is the
run's time of the grab. See https://docs.opencv.org/5.x/d8/dfe/classcv_1_1VideoCapture.html.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Mapping

# FFmpeg's own log lines (a broken file's parse errors) are not printed: the errors below say it in one line
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")

import cv2  # noqa: E402  (after the FFmpeg log level, which OpenCV reads when it first opens a video)
import numpy as np  # noqa: E402

from cosim.contract.component import InputEnded
from cosim_plugins.camera.calibration import VIEWS
from cosim_plugins.camera.sources.base import FramePair, FrameSource, FrameSourceError, size_of, to_grey


@contextlib.contextmanager
def _quiet_opencv():
    """OpenCV's warnings (a device it cannot open) left out while a capture opens."""
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    try:
        yield
    finally:
        cv2.utils.logging.setLogLevel(level)


class _Capture:
    """One view's ``VideoCapture``, opened and checked."""

    def __init__(self, view: str, spec: str):
        with _quiet_opencv():
            self._open(view, spec)

    def _open(self, view: str, spec: str) -> None:
        self.view, self.spec = view, spec
        self.is_device = spec.isdigit()
        if self.is_device:
            self.name = f"camera {view} (video device {spec})"
            self.cap = cv2.VideoCapture(int(spec))
            if not self.cap.isOpened():
                raise FrameSourceError(f"{self.name}: not found or busy (cv2.VideoCapture({spec}) failed)")
            self.cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)
        else:
            self.name = f"video file {spec}"
            if not Path(spec).is_file():
                raise FrameSourceError(f"{self.name} ({view}): does not exist")
            self.cap = cv2.VideoCapture(spec)
            if not self.cap.isOpened():
                raise FrameSourceError(f"{self.name} ({view}): cannot be opened (corrupted or not a video)")
        self.frames = 0
        self.pending: np.ndarray | None = self._read()
        if self.pending is None:
            self.cap.release()
            raise FrameSourceError(f"{self.name} ({view}): no frame can be read"
                                   + ("" if self.is_device else " (corrupted or empty)"))
        self.size = size_of(self.pending)

    def _read(self) -> np.ndarray | None:
        ok, frame = self.cap.read()
        return to_grey(frame) if ok and frame is not None else None

    def next(self) -> np.ndarray:
        frame, self.pending = (self.pending, None) if self.pending is not None else (self._read(), None)
        if frame is None:
            total = int(self.cap.get(cv2.CAP_PROP_FRAME_COUNT))
            if self.is_device:
                raise FrameSourceError(f"{self.name}: stopped delivering frames (after {self.frames})")
            if self.frames < total:
                raise FrameSourceError(f"{self.name} ({self.view}): frame {self.frames} of {total} cannot be "
                                       "decoded (corrupted)")
            # the recording replayed has run out: the run ends here (see cosim.contract.component.InputEnded)
            raise InputEnded(f"{self.name} ({self.view}): ended after {self.frames} frames")
        if size_of(frame) != self.size:
            raise FrameSourceError(f"{self.name}: frame {self.frames} is {size_of(frame)}, the first was {self.size}")
        self.frames += 1
        return frame


class VideoSource(FrameSource):
    """Two ``VideoCapture`` views (see the module docstring); ``specs``: top, side."""

    def __init__(self, specs: tuple[str, str]):
        self.caps: list[_Capture] = []
        try:
            for view, spec in zip(VIEWS, specs):
                if not spec:
                    raise FrameSourceError(f"source video: give the {view} camera (a device index or a video file)")
                self.caps.append(_Capture(view, str(spec)))
        except FrameSourceError:
            self.close()
            raise
        self._describe(self.caps)

    def grab(self, t_s: float, scene: Mapping[str, np.ndarray]) -> FramePair:
        return FramePair((self.caps[0].next(), self.caps[1].next()), float(t_s))

    def close(self) -> None:
        for c in self.caps:
            c.cap.release()

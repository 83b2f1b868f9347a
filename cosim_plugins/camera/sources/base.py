"""The frame-source interface: time-stamped frame pairs (top, side), whatever delivers them.

A source is opened with what it needs (devices, files, the calibration for
the renderer), knows each view's frame size, and on ``grab(t_s, scene)``
returns one :class:`FramePair`: the two images, 8-bit grey (height, width),
either of them None when its frame was lost, and the capture time on the
run's clock [s]. ``scene`` holds the camera component's inputs (the true
position and axis for the renderer, nothing for hardware); a source that
does not draw ignores it. Errors name the device or file.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import cv2
import numpy as np

from cosim import ComponentError


class FrameSourceError(ComponentError):
    """A camera, video or folder cannot deliver frames; the message names it."""


@dataclass
class FramePair:
    """``images``: (height, width) uint8 per view, in ``VIEWS`` order, None where the frame was lost;
    ``capture_time_s``: when the pair was exposed, on the run's clock [s]."""

    images: tuple[np.ndarray | None, np.ndarray | None]
    capture_time_s: float


class FrameSource:
    """Base of every frame source (see the module docstring)."""

    #: what each view reads, for messages: e.g. "Basler 0815-0000", "video file top.mkv"
    devices: tuple[str, str] = ("", "")
    #: (width, height) [px] of each view's frames
    sizes: tuple[tuple[int, int], tuple[int, int]] = ((0, 0), (0, 0))

    def grab(self, t_s: float, scene: Mapping[str, np.ndarray]) -> FramePair:
        raise NotImplementedError

    def _describe(self, views: list) -> None:
        """``devices`` and ``sizes`` from the opened views' handles (each with ``name`` and ``size``)."""
        self.devices = tuple(v.name for v in views)
        self.sizes = tuple(v.size for v in views)

    def close(self) -> None:
        """Release the devices or files."""


def to_grey(frame: np.ndarray) -> np.ndarray:
    """An 8-bit grey image (height, width) of a grey or BGR frame."""
    if frame.ndim == 3:
        frame = cv2.cvtColor(frame, cv2.COLOR_BGRA2GRAY if frame.shape[2] == 4 else cv2.COLOR_BGR2GRAY)
    if frame.dtype != np.uint8:
        raise FrameSourceError(f"frames of {frame.dtype} are not supported: give 8-bit images")
    return frame


def size_of(image: np.ndarray) -> tuple[int, int]:
    """(width, height) [px]."""
    return int(image.shape[1]), int(image.shape[0])

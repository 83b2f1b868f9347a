"""Frames from two folders of images (top, side), one image of each per grab, in name order.

Images are read as 8-bit grey (PNG, BMP, TIFF, JPEG, PGM). A missing or
empty folder, an unreadable image, or a folder that runs out fails naming
the folder or file. The capture time is the run's time of the grab.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import cv2
import numpy as np

from cosim_plugins.camera.calibration import VIEWS
from cosim_plugins.camera.sources.base import FramePair, FrameSource, FrameSourceError, size_of

SUFFIXES = (".png", ".bmp", ".tif", ".tiff", ".jpg", ".jpeg", ".pgm")


class FolderSource(FrameSource):
    """Images of ``folders`` (top, side), sorted by name."""

    def __init__(self, folders: tuple[str, str]):
        self.files: list[list[Path]] = []
        for view, folder in zip(VIEWS, folders):
            path = Path(folder)
            if not folder or not path.is_dir():
                raise FrameSourceError(f"image folder {folder or '(none given)'} ({view}): not a folder")
            files = sorted(f for f in path.iterdir() if f.suffix.lower() in SUFFIXES)
            if not files:
                raise FrameSourceError(f"image folder {folder} ({view}): no images ({', '.join(SUFFIXES)})")
            self.files.append(files)
        self.devices = tuple(f"image folder {f}" for f in folders)
        self.sizes = tuple(size_of(self._read(files[0])) for files in self.files)
        self.index = 0

    @staticmethod
    def _read(file: Path) -> np.ndarray:
        image = cv2.imread(str(file), cv2.IMREAD_GRAYSCALE)
        if image is None:
            raise FrameSourceError(f"image {file}: cannot be read (corrupted or not an image)")
        return image

    def grab(self, t_s: float, scene: Mapping[str, np.ndarray]) -> FramePair:
        images = []
        for view, files, size in zip(VIEWS, self.files, self.sizes):
            if self.index >= len(files):
                raise FrameSourceError(f"image folder {files[0].parent} ({view}): ran out after {len(files)} images")
            image = self._read(files[self.index])
            if size_of(image) != size:
                raise FrameSourceError(f"image {files[self.index]}: {size_of(image)} px, the folder's first is {size}")
            images.append(image)
        self.index += 1
        return FramePair((images[0], images[1]), float(t_s))

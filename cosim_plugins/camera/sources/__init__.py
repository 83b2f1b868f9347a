"""Frame sources behind one interface (:mod:`.base`): Basler cameras, OpenCV video, image folders, the renderer.

:func:`open_source` opens a hardware or file source by name; the renderer
(:mod:`.render`) is opened by ``camera.rendered``, which feeds it the truth.
"""

from __future__ import annotations

from typing import Any, Mapping

from cosim_plugins.camera.sources.base import FramePair, FrameSource, FrameSourceError

SOURCES = ("basler", "video", "folder")


def open_source(kind: str, top: str, side: str, options: Mapping[str, Any]) -> FrameSource:
    """A ``kind`` source (one of ``SOURCES``) reading the ``top`` and ``side`` cameras; ``options``:
    ``trigger``, ``features`` and ``grab_timeout_s`` for Basler cameras."""
    if kind == "basler":
        from cosim_plugins.camera.sources.basler import BaslerSource

        return BaslerSource((top, side), options.get("features"), options.get("trigger", ""),
                            options.get("grab_timeout_s", 0.1))
    if kind == "video":
        from cosim_plugins.camera.sources.video import VideoSource

        return VideoSource((top, side))
    if kind == "folder":
        from cosim_plugins.camera.sources.folder import FolderSource

        return FolderSource((top, side))
    raise FrameSourceError(f"source {kind!r}: unknown; known: {', '.join(SOURCES)}")


__all__ = ["SOURCES", "FramePair", "FrameSource", "FrameSourceError", "open_source"]

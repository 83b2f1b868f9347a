"""Frames from the lab's two Basler cameras through pypylon (``pip install '.[lab]'``).

Each view is a camera named by its serial number. On opening, each camera is
set to 8-bit grey (``Mono8``) where it offers it, takes the ``features``
given for it (GenICam names, e.g. ``ExposureTime``, ``Gain``) and starts
grabbing with pylon's latest-image strategy: a grab returns the newest frame
and never a stale queued one (https://docs.baslerweb.com/pylonapi/). With a
``trigger`` (``Line1``, ...), both cameras expose on that hardware line's
edge (one pulse per control period from the rig's controller makes the pair
simultaneous); ``Software`` triggers both from the grab itself (the camera
emulator, a rig without trigger wiring).

Capture time: each camera's frame time stamp (its own clock, ``tick_hz``,
1 GHz on USB3 ace cameras) measured from its first frame, which is placed at
the run time of the first grab; a camera that stamps nothing (the emulator)
is taken to expose at the grab. A frame that does not arrive within
``timeout_s`` is lost. pylon's camera emulator (``PYLON_CAMEMU=2``: serials
``0815-0000``, ``0815-0001``) stands in for the cameras in tests.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from cosim_plugins.camera.calibration import VIEWS
from cosim_plugins.camera.sources.base import FramePair, FrameSource, FrameSourceError

USB_TICK_HZ = 1e9


def _pylon():
    try:
        from pypylon import genicam, pylon
    except ImportError as exc:
        raise FrameSourceError(f"source basler needs pypylon (pip install '.[lab]'): {exc}") from None
    return pylon, genicam


class _Camera:
    """One opened, configured and grabbing camera."""

    def __init__(self, pylon, genicam, device, view: str, serial: str, features: Mapping[str, Any],
                 trigger: str):
        self.view, self.serial, self.pylon = view, serial, pylon
        self.name = f"Basler camera {view} ({device.GetModelName()} {serial})"
        self.cam = pylon.InstantCamera(pylon.TlFactory.GetInstance().CreateDevice(device))
        self.cam.Open()
        if "Mono8" in self.cam.PixelFormat.Symbolics:
            self.cam.PixelFormat.Value = "Mono8"
        for feature, value in features.items():
            try:
                getattr(self.cam, feature).Value = value
            except (AttributeError, genicam.GenericException) as exc:
                raise FrameSourceError(f"{self.name}: cannot set {feature} = {value!r}: "
                                       f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}") from None
        if trigger:
            if trigger not in self.cam.TriggerSource.Symbolics:
                raise FrameSourceError(f"{self.name}: no trigger source {trigger!r} "
                                       f"(has: {', '.join(self.cam.TriggerSource.Symbolics)})")
            self.cam.TriggerSelector.Value = "FrameStart"
            self.cam.TriggerMode.Value = "On"
            self.cam.TriggerSource.Value = trigger
        else:
            self.cam.TriggerMode.Value = "Off"
        self.size = (int(self.cam.Width.Value), int(self.cam.Height.Value))
        tick = getattr(self.cam, "GevTimestampTickFrequency", None)  # GigE cameras say theirs
        self.tick_hz = float(tick.Value) if tick is not None and genicam.IsReadable(tick) else USB_TICK_HZ
        self.first_stamp: tuple[int, float] | None = None  # (camera ticks, run time [s]) of the first frame
        self.cam.StartGrabbing(pylon.GrabStrategy_LatestImageOnly)

    def fire(self, timeout_ms: int) -> None:
        self.cam.WaitForFrameTriggerReady(timeout_ms, self.pylon.TimeoutHandling_ThrowException)
        self.cam.ExecuteSoftwareTrigger()

    def retrieve(self, t_s: float, timeout_ms: int) -> tuple[np.ndarray | None, float]:
        """The newest frame (None if none came in time) and its capture time [s]."""
        result = self.cam.RetrieveResult(timeout_ms, self.pylon.TimeoutHandling_Return)
        if result is None or not result.IsValid():
            return None, t_s
        try:
            if not result.GrabSucceeded():
                return None, t_s
            image = np.array(result.Array, dtype=np.uint8, copy=True)
            stamp = int(result.TimeStamp)
        finally:
            result.Release()
        if stamp <= 0:
            return image, t_s
        if self.first_stamp is None:
            self.first_stamp = (stamp, t_s)
        return image, self.first_stamp[1] + (stamp - self.first_stamp[0]) / self.tick_hz

    def close(self) -> None:
        if self.cam.IsGrabbing():
            self.cam.StopGrabbing()
        self.cam.Close()


class BaslerSource(FrameSource):
    """The top and side Basler cameras (see the module docstring)."""

    def __init__(self, serials: tuple[str, str], features: Mapping[str, Mapping[str, Any]] | None = None,
                 trigger: str = "", timeout_s: float = 0.1):
        pylon, self.genicam = _pylon()
        self.software = trigger == "Software"
        self.timeout_ms = max(int(round(timeout_s * 1e3)), 1)
        try:
            found = {d.GetSerialNumber(): d for d in pylon.TlFactory.GetInstance().EnumerateDevices()}
        except self.genicam.GenericException as exc:
            raise FrameSourceError(f"source basler: cannot list the cameras: {exc}") from None
        listing = ", ".join(f"{s} ({d.GetModelName()})" for s, d in sorted(found.items())) or "none"
        self.cams: list[_Camera] = []
        try:
            for view, serial in zip(VIEWS, serials):
                serial = str(serial)
                if not serial:
                    raise FrameSourceError(f"source basler: give the {view} camera's serial number; "
                                           f"connected: {listing}")
                if serial not in found:
                    raise FrameSourceError(f"Basler camera {view} (serial {serial}): not connected; "
                                           f"connected: {listing}")
                try:
                    self.cams.append(_Camera(pylon, self.genicam, found[serial], view, serial,
                                             dict((features or {}).get(view, {})), trigger))
                except self.genicam.GenericException as exc:
                    raise FrameSourceError(f"Basler camera {view} (serial {serial}): cannot open: "
                                           f"{str(exc).splitlines()[0]}") from None
        except FrameSourceError:
            self.close()
            raise
        self._describe(self.cams)

    def grab(self, t_s: float, scene: Mapping[str, np.ndarray]) -> FramePair:
        images, times = [], []
        for cam in self.cams:
            try:
                if self.software:
                    cam.fire(self.timeout_ms)
            except self.genicam.GenericException as exc:
                raise FrameSourceError(f"{cam.name}: trigger failed: {str(exc).splitlines()[0]}") from None
        for cam in self.cams:
            try:
                image, at = cam.retrieve(t_s, self.timeout_ms)
            except self.genicam.GenericException as exc:
                raise FrameSourceError(f"{cam.name}: {str(exc).splitlines()[0]} (removed?)") from None
            images.append(image)
            if image is not None:
                times.append(at)
        return FramePair((images[0], images[1]), float(np.mean(times)) if times else float(t_s))

    def close(self) -> None:
        for cam in self.cams:
            try:
                cam.close()
            except self.genicam.GenericException:
                pass  # closing a camera that is gone: nothing left to release
        self.cams = []

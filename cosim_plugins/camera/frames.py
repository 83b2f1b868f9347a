"""``camera.frames`` and ``camera.rendered``: the swimmer's position from two camera frames.

Every ``interval_s`` the component takes a frame pair (top, side) from its
source, finds the swimmer in each frame and triangulates it
(:mod:`~cosim_plugins.camera.locate`) with the cameras of a calibration file
(:mod:`~cosim_plugins.camera.calibration`). It never knows what the source
is; the two registered names differ only in the source and its inputs:

* ``camera.frames``: the lab's cameras or recorded frames, no inputs
  (``source: basler | video | folder``; see :mod:`.sources`);
* ``camera.rendered``: the renderer (:mod:`.sources.render`), fed the true
  position and axis from the plant, so the whole image pipeline runs in
  closed loop. It draws the cameras of ``calibration`` (default: its acA800
  pair) and writes the calibration it drew with into the run folder.

Outputs, as ``camera.emulator``'s where they overlap: ``position`` [m], NaN
between frames and when the swimmer is not found; ``capture_time`` [s];
``reprojection_error`` [px], the detection quality; ``detection``, the
status code (0 found, 1 lost, 2 rejected; NaN between frames), which
``summary.json`` counts as ``detections: {frames, lost, rejected}``.

The recording gets both camera images with the detections drawn (every
``view_every_s``, scaled by ``view_scale``; :mod:`.views`); ``record_frames``
saves the raw frames as a lossless video per camera (:mod:`.frame_video`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from cosim import Component, ComponentError, Port
from cosim.contract.params import Param, read_params
from cosim_plugins.camera.calibration import VIEWS, Calibration, load_calibration
from cosim_plugins.camera.detect import BlobParams
from cosim_plugins.camera.frame_video import FrameVideos
from cosim_plugins.camera.locate import LOST, REJECTED, PairLocator, PairParams
from cosim_plugins.camera.sources import SOURCES, FrameSource, open_source
from cosim_plugins.camera.sources.render import Look, Renderer, acA800_pair

COMMON = {
    "interval_s": Param(0.02, "time between frame pairs [s], a multiple of dt", 0.0, 60.0),
    "threshold_dn": Param(40.0, "darkness below the local background that counts as the swimmer [DN]", 1.0, 255.0),
    "min_area_px": Param(20.0, "smallest blob [px]", 1.0, 1e6),
    "max_area_px": Param(2000.0, "largest blob [px]", 1.0, 1e7),
    "max_length_px": Param(80.0, "longest side of a blob's box [px]", 2.0, 1e4),
    "search_px": Param(32, "half-size of the window around the expected position [px]", 4, 1000),
    "scale": Param(4, "downscaling of the whole-frame search", 1, 16),
    "max_blobs": Param(4, "blobs kept per frame", 1, 32),
    "gate_px": Param(2.0, "largest reprojection error of a consistent pair [px]", 0.01, 1e3),
    "tank_mm": Param(75.0, "half-width of the tank; points beyond are reflections [mm]", 1.0, 1e4),
    "jump_mm": Param(2.0, "reach from the last position at no time elapsed [mm]", 0.0, 1e4),
    "max_speed_mm_s": Param(200.0, "fastest the swimmer moves, for the reach from the last position [mm/s]",
                            0.0, 1e5),
    "max_rejects": Param(5, "rejected pairs in a row before the last position is forgotten", 1, 10000),
    "view_every_s": Param(0.1, "time between camera images in the recording [s] (0: none)", 0.0, 3600.0),
    "view_scale": Param(0.25, "scale of the camera images in the recording", 0.05, 1.0),
    "record_frames": Param(False, "save the raw frames as a lossless video per camera in the run folder"),
}
FRAMES_PARAMS = {
    **COMMON,
    "calibration": Param("", "calibration file (YAML) of the top and side cameras, see `cosim camera calibrate`"),
    "source": Param("basler", f"where the frames come from: {' | '.join(SOURCES)}"),
    "top": Param("", "top camera: Basler serial number, video device index or file, or image folder"),
    "side": Param("", "side camera: as top"),
    "trigger": Param("", "basler: trigger source of both cameras (Line1, ..., Software); empty: free run"),
    "features": Param({}, "basler: GenICam features per camera, {top: {ExposureTime: 2000}, side: {...}}"),
    "grab_timeout_s": Param(0.1, "basler: longest wait for a frame before it counts as lost [s]", 0.001, 60.0),
}
RENDERED_PARAMS = {
    **COMMON,
    "calibration": Param("", "calibration file of the cameras to draw (default: the renderer's acA800 pair)"),
    **{name: Param(default, doc, lo, hi) for name, default, doc, lo, hi in (
        ("background_dn", Look.background_dn, "grey level of the lit tank [DN]", 0.0, 255.0),
        ("vignetting", Look.vignetting, "fraction of the background lost in the image corners", 0.0, 1.0),
        ("wall_dn", Look.wall_dn, "darkness of the tank's edges [DN]", 0.0, 255.0),
        ("body_dn", Look.body_dn, "grey level of the swimmer's body [DN]", 0.0, 255.0),
        ("blur_px", Look.blur_px, "optical blur, Gaussian standard deviation [px]", 0.0, 20.0),
        ("noise_dn", Look.noise_dn, "sensor noise, standard deviation [DN]", 0.0, 100.0),
        ("drop_prob", Look.drop_prob, "probability a frame is lost", 0.0, 1.0),
        ("glint_prob", Look.glint_prob, "probability a pair has a glint in one view", 0.0, 1.0),
        ("reflection_mm", Look.reflection_mm, "distance to a wall within which it reflects the swimmer [mm]",
         0.0, 150.0),
        ("reflection_contrast", Look.reflection_contrast, "darkness of a reflection, relative to the body",
         0.0, 1.0))},
}

OUTPUTS = (
    Port("position", (3,), "m", "triangulated position; NaN when no frame this step or the swimmer was not found"),
    Port("capture_time", (), "s", "when this step's frame pair was exposed; NaN when no frame this step"),
    Port("reprojection_error", (), "px",
         "detection quality: RMS reprojection error of the position over both views; NaN unless found"),
    Port("detection", (), "1", "0 found, 1 lost (a frame lost or no blob in a view), 2 rejected (no consistent "
                               "pair); NaN when no frame this step"),
)


class FrameCamera(Component):
    """Frame pairs from the lab's cameras, a video or image folders: detection and triangulation."""

    outputs = OUTPUTS
    uses_run_dir = True
    PARAMS = FRAMES_PARAMS
    needs_calibration = True  # real cameras: only a calibration file says where they are

    @classmethod
    def validate_params(cls, params: Mapping[str, Any]) -> None:
        cls._read(params)

    @classmethod
    def _read(cls, params: Mapping[str, Any]) -> dict[str, Any]:
        p = read_params(params, cls.PARAMS)
        for key in ("search_px", "scale", "max_blobs", "max_rejects"):
            if p[key] != int(p[key]):
                raise ComponentError(f"parameter {key}={p[key]!r}: expected a whole number")
            p[key] = int(p[key])
        if "source" in p and p["source"] not in SOURCES:
            raise ComponentError(f"parameter source={p['source']!r}: expected one of {', '.join(SOURCES)}")
        if "features" in p and not (isinstance(p["features"], dict) and set(p["features"]) <= set(VIEWS)
                                    and all(isinstance(v, dict) for v in p["features"].values())):
            raise ComponentError(f"parameter features: expected {{top: {{Feature: value}}, side: {{...}}}}, "
                                 f"got {p['features']!r}")
        if cls.needs_calibration and not p["calibration"]:
            raise ComponentError("parameter calibration: give the cameras' calibration file "
                                 "(`cosim camera calibrate`)")
        if p["calibration"]:
            load_calibration(p["calibration"])
        return p

    def setup(self, params, rng):
        p = self.p = self._read(params)
        dt = float(params["dt"])
        self.interval = _ticks(p["interval_s"], dt, "interval_s")
        self.name = params.get("name", "camera")
        self.source: FrameSource | None = None
        self.videos = self.views = None
        self.cal = self._calibration(p)
        try:  # a camera opened stays open unless closed here: the run closes only components set up
            self.source = self._open(p, rng)
            for i, view in enumerate(VIEWS):
                self.cal.check_size(view, self.source.sizes[i], self.source.devices[i])
            self._record(p, params.get("run_dir"), params.get("recording_id", self.name), dt)
        except BaseException:
            self.close()
            raise
        blob = BlobParams(p["threshold_dn"], p["min_area_px"], p["max_area_px"], p["max_length_px"],
                          p["search_px"], p["scale"], p["max_blobs"])
        pair = PairParams(p["gate_px"], p["tank_mm"], p["jump_mm"], p["max_speed_mm_s"], p["max_rejects"])
        self.locator = PairLocator(self.cal, blob, pair)
        self.tick = 0
        nan = np.array(np.nan)
        self.idle = {"position": np.full(3, np.nan), "capture_time": nan, "reprojection_error": nan,
                     "detection": nan}

    def _calibration(self, p) -> Calibration:
        return load_calibration(p["calibration"])

    def _open(self, p, rng) -> FrameSource:
        return open_source(p["source"], str(p["top"]), str(p["side"]), p)

    def _record(self, p, run_dir: Path | None, recording_id: str, dt: float) -> None:
        """The video of the frames and the views in the recording, when there is a run folder."""
        if run_dir is None:
            if p["record_frames"]:
                raise ComponentError("record_frames: needs a run folder (run it with `cosim run`)")
            return
        if p["record_frames"]:
            self.videos = FrameVideos(run_dir, self.name, self.source.sizes, 1.0 / (self.interval * dt))
        every = int(round(p["view_every_s"] / (self.interval * dt)))
        if p["view_every_s"] > 0:
            from cosim_plugins.camera.views import ViewLogger

            self.views = ViewLogger(run_dir, recording_id, self.name, self.cal, p["view_scale"], max(every, 1))

    def initial_outputs(self):
        return self.idle

    def step(self, t, inputs):
        due = self.tick % self.interval == 0
        self.tick += 1
        if not due:
            return self.idle
        pair = self.source.grab(t, inputs)
        if self.videos is not None:
            self.videos.write(pair.images)
        fix = self.locator.locate(pair.capture_time_s, pair.images)
        if self.views is not None:
            self.views.log(t, pair.images, fix)
        return {"position": fix.position_m, "capture_time": np.array(pair.capture_time_s),
                "reprojection_error": np.array(fix.reprojection_px), "detection": np.array(float(fix.status))}

    def close(self) -> None:
        for part in (self.videos, self.views, self.source):
            if part is not None:
                part.close()
        self.videos = self.views = self.source = None

    @classmethod
    def recording_views(cls, name: str) -> list:
        from cosim_plugins.camera.views import layout_views

        return layout_views(name)

    @classmethod
    def summary_figures(cls, outputs: Mapping[str, np.ndarray]) -> dict[str, Any]:
        codes = outputs["detection"]
        return {"detections": {"frames": int(np.isfinite(codes).sum()), "lost": int((codes == LOST).sum()),
                               "rejected": int((codes == REJECTED).sum())}}

    @classmethod
    def summary_accumulator(cls) -> DetectionCounts:
        return DetectionCounts()


class DetectionCounts:
    """The ``detections`` figure counted batch by batch (the same counts as ``summary_figures``)."""

    def __init__(self):
        self.counts = {"frames": 0, "lost": 0, "rejected": 0}

    def add(self, outputs: Mapping[str, np.ndarray]) -> None:
        for key, value in FrameCamera.summary_figures(outputs)["detections"].items():
            self.counts[key] += value

    def figures(self) -> dict[str, Any]:
        return {"detections": dict(self.counts)}


class RenderedCamera(FrameCamera):
    """Frames rendered from the plant's true position and axis, then the same detection and triangulation."""

    inputs = (
        Port("position", (3,), "m", "true swimmer position (what the renderer draws)"),
        Port("axis", (3,), "1", "true unit vector of the swimmer's long axis"),
    )
    PARAMS = RENDERED_PARAMS
    needs_calibration = False  # the renderer's own pair by default

    def _calibration(self, p) -> Calibration:
        return load_calibration(p["calibration"]) if p["calibration"] else acA800_pair()

    def _open(self, p, rng) -> FrameSource:
        look = Look(**{k: p[k] for k in Look.__dataclass_fields__})
        return Renderer(self.cal, look, rng)

    def _record(self, p, run_dir, recording_id, dt) -> None:
        super()._record(p, run_dir, recording_id, dt)
        if run_dir is not None:  # what the frames were drawn with: an exact calibration
            self.cal.save(Path(run_dir) / f"calibration_{self.name}.yaml")


def _ticks(value_s: float, dt: float, name: str) -> int:
    n = value_s / dt
    if abs(n - round(n)) > 1e-6 or round(n) < 1:
        raise ComponentError(f"{name}={value_s} s is not a whole number (>= 1) of steps of dt={dt} s")
    return int(round(n))

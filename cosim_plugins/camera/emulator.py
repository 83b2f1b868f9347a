"""Two orthogonal cameras seeing the swimmer, with the lab's imperfections.

The top camera sees (x, y), the side camera (x, z); x is the mean of both.
Each camera quantises to its pixel grid (~0.19 mm) after Gaussian pixel
noise. A frame is captured every ``interval_s`` (a multiple of the step),
delivered ``latency_s`` later, may be dropped, may repeat the previous
detection (lost detection), and may carry a reflection outlier (one camera
jumps by ``outlier_mm``). All draws come from the component's seeded RNG.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from cosim import Component, ComponentError, Port
from cosim.contract.params import Param, read_params, whole_ticks
from cosim_plugins.vec3 import length

PARAMS = {
    "interval_s": Param(0.02, "time between captured frames [s], a multiple of dt", 0.0, 60.0),
    "latency_s": Param(0.0, "delay from capture to delivery [s], a multiple of dt", 0.0, 10.0),
    "pixel_mm": Param(0.19, "pixel size in the tank [mm]", 1e-6, 10.0),
    "noise_px": Param(0.5, "Gaussian detection noise, standard deviation [pixels]", 0.0, 100.0),
    "outlier_prob": Param(0.0, "probability a frame carries a reflection outlier", 0.0, 1.0),
    "outlier_mm": Param(8.0, "size of a reflection outlier [mm]", 0.0, 200.0),
    "drop_prob": Param(0.0, "probability a frame is lost", 0.0, 1.0),
    "lost_prob": Param(0.0, "probability the detection repeats the previous position", 0.0, 1.0),
}


def _rint(x: float) -> float:
    """``np.rint`` of one float: the nearest whole number, halves to even; keeps the sign of a
    zero (-0.3 gives -0.0) and passes NaN and infinities."""
    return math.copysign(round(x), x) if math.isfinite(x) else x


class CameraEmulator(Component):
    """Two-camera position measurement: noise, quantisation, outliers, drops, latency, sparse frames."""

    inputs = (Port("position", (3,), "m", "true swimmer position"),)
    outputs = (Port("position", (3,), "m", "measured position; NaN when no frame arrives this step"),)

    @classmethod
    def validate_params(cls, params):
        cls._read(params)

    @staticmethod
    def _read(params) -> tuple[dict, int, int]:
        """The parameters, the frame interval and the latency in steps; raises :class:`ComponentError`."""
        p = read_params(params, PARAMS)
        interval = whole_ticks(p["interval_s"], params["dt"], "interval_s")
        if interval < 1:
            raise ComponentError("interval_s must be at least one step")
        return p, interval, whole_ticks(p["latency_s"], params["dt"], "latency_s")

    def setup(self, params, rng):
        self.p, self.interval, self.latency = self._read(params)
        self.rng = rng
        self.pixel_m = self.p["pixel_mm"] * 1e-3
        self.noise_sd_m = self.p["noise_px"] * self.pixel_m
        self.queue: deque = deque()
        self.last = None
        self.tick = 0
        self.nan = np.full(3, np.nan)

    def initial_outputs(self):
        return {"position": self.nan}

    def _capture(self, truth: np.ndarray) -> np.ndarray | None:
        p, rng = self.p, self.rng
        drop, lost, outlier = rng.random(3).tolist()  # always all draws keeps streams aligned
        # four pixel noises, then an outlier's direction: one call draws the stream that
        # rng.normal(0, sd, size=4) and rng.normal(size=3) drew, as loc + scale * z each
        normals = rng.standard_normal(7).tolist()
        if drop < p["drop_prob"]:
            return None
        if lost < p["lost_prob"] and self.last is not None:
            return self.last
        # both cameras: (top x, top y, side x, side z), with noise, quantised to the pixel grid
        x_m, y_m, z_m = truth.tolist()
        sd_m, pixel_m = self.noise_sd_m, self.pixel_m
        top_x, top_y, side_x, side_z = [_rint((v + (0.0 + sd_m * dz)) / pixel_m) * pixel_m
                                        for v, dz in zip((x_m, y_m, x_m, z_m), normals)]
        if outlier < p["outlier_prob"]:  # a reflection fools the top camera
            jump = [0.0 + 1.0 * dz for dz in normals[4:]]
            size = length(jump)
            top_x += jump[0] / size * p["outlier_mm"] * 1e-3
            top_y += jump[1] / size * p["outlier_mm"] * 1e-3
        meas = np.array([(top_x + side_x) / 2, top_y, side_z])
        self.last = meas
        return meas

    def step(self, t, inputs):
        if self.tick % self.interval == 0:
            frame = self._capture(np.asarray(inputs["position"]))
            if frame is not None:
                self.queue.append((self.tick + self.latency, frame))
        out = self.nan
        while self.queue and self.queue[0][0] <= self.tick:
            out = self.queue.popleft()[1]
        self.tick += 1
        return {"position": out}

"""Two orthogonal cameras seeing the swimmer, with the lab's imperfections.

The top camera sees (x, y), the side camera (x, z); x is the mean of both.
Each camera quantises to its pixel grid (~0.19 mm) after Gaussian pixel
noise. A frame is captured every ``interval_s`` (a multiple of the step),
delivered ``latency_s`` later, may be dropped, may repeat the previous
detection (lost detection), and may carry a reflection outlier (one camera
jumps by ``outlier_mm``). All draws come from the component's seeded RNG.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from cosim import Component, ComponentError, Port
from cosim.contract.params import Param, read_params, whole_ticks

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

#: The truth's coordinates each camera sees, in the order of the noise draws: top (x, y), side (x, z).
CAMERA_AXES = np.array([0, 1, 0, 2])


class CameraEmulator(Component):
    """Two-camera position measurement: noise, quantisation, outliers, drops, latency, sparse frames."""

    inputs = (Port("position", (3,), "m", "true swimmer position"),)
    outputs = (Port("position", (3,), "m", "measured position; NaN when no frame arrives this step"),)

    def setup(self, params, rng):
        self.p = read_params(params, PARAMS)
        dt = params["dt"]
        self.interval = whole_ticks(self.p["interval_s"], dt, "interval_s")
        if self.interval < 1:
            raise ComponentError("interval_s must be at least one step")
        self.latency = whole_ticks(self.p["latency_s"], dt, "latency_s")
        self.rng = rng
        self.pixel_m = self.p["pixel_mm"] * 1e-3
        self.queue: deque = deque()
        self.last = None
        self.tick = 0
        self.nan = np.full(3, np.nan)

    def initial_outputs(self):
        return {"position": self.nan}

    def _capture(self, truth: np.ndarray) -> np.ndarray | None:
        p, rng = self.p, self.rng
        draws = rng.random(3)  # drop, lost, outlier: always three draws keeps streams aligned
        noise = rng.normal(0.0, p["noise_px"] * self.pixel_m, size=4)
        jump = rng.normal(size=3)
        if draws[0] < p["drop_prob"]:
            return None
        if draws[1] < p["lost_prob"] and self.last is not None:
            return self.last
        # both cameras at once: (top x, top y, side x, side z), quantised to the pixel grid
        pixels = np.rint((truth[CAMERA_AXES] + noise) / self.pixel_m) * self.pixel_m
        if draws[2] < p["outlier_prob"]:
            offset = jump / np.linalg.norm(jump) * p["outlier_mm"] * 1e-3
            pixels[:2] += offset[:2]  # a reflection fools the top camera
        top_x, top_y, side_x, side_z = pixels.tolist()
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

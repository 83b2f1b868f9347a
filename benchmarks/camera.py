"""Frame camera: detection and triangulation of one frame pair at 800 x 600, per pair.

Renders ``--pairs`` frame pairs of the swimmer going round the racetrack at
20 mm/s (the renderer of ``camera.rendered``, its acA800 pair at the
acA800's default 800 x 600 px, glints in 2 % of the pairs), then times
``PairLocator.locate`` on each pair (``time.perf_counter_ns``): blobs in both
frames, pairing, triangulation, the checks against the last position. The
frames are made before timing, so the renderer's cost is not counted. The
pairs are located ``--repeat`` times in the same order (a fresh locator each
pass) and every pair's minimum kept (like ``timeit``: other processes on a
busy machine only add time). Reported, in ms:

* ``pair_ms``: median and p99 over the pairs (the first pair of a pass
  searches the whole frames, the others track the last position);
* ``whole_frame_ms``: median over the pairs of a pass that never tracks
  (every pair searched in the whole frames, as after a loss);

with the frame size, the number of pairs and the detection error against
the truth (median, p99 [mm]). Budget (DESIGN.md): ``pair_ms`` median <= 2.

    .venv/bin/python benchmarks/camera.py [--pairs 500] [--repeat 5]
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import time

import numpy as np

BUDGET_MS = 2.0
SPEED_M_S = 0.02
DT_S = 0.02


def racetrack(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions (n, 3) [m] and unit axes (n, 3) along the racetrack (30 mm straights, 40 mm radius)."""
    from cosim.scenario.paths import make_path

    polyline = make_path("racetrack", {"straight_mm": 30, "radius_mm": 40}).points(0.0)
    closed = np.vstack([polyline, polyline[:1]])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])

    def at(s_m: np.ndarray) -> np.ndarray:
        return np.stack([np.interp(s_m % arc[-1], arc, closed[:, i]) for i in range(3)], axis=1)

    s = np.arange(n) * SPEED_M_S * DT_S
    points = at(s)
    ahead = at(s + 1e-3) - points
    return points, ahead / np.linalg.norm(ahead, axis=1, keepdims=True)


def time_pass(locator_factory, pairs, track: bool) -> tuple[np.ndarray, np.ndarray]:
    """ms per pair of one pass, and the positions found (n, 3) [m]."""
    locator = locator_factory()
    ms, found = np.empty(len(pairs)), np.full((len(pairs), 3), np.nan)
    gc.disable()
    try:
        for k, images in enumerate(pairs):
            if not track:
                locator.last_m = None
            t0 = time.perf_counter_ns()
            fix = locator.locate(k * DT_S, images)
            ms[k] = (time.perf_counter_ns() - t0) / 1e6
            found[k] = fix.position_m
    finally:
        gc.enable()
    return ms, found


def main() -> None:
    from cosim_plugins.camera.detect import BlobParams
    from cosim_plugins.camera.locate import PairLocator, PairParams
    from cosim_plugins.camera.sources.render import Look, Renderer, acA800_pair

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=500, help="frame pairs rendered and located")
    parser.add_argument("--repeat", type=int, default=5, help="passes; each pair's minimum is kept")
    args = parser.parse_args()
    calibration = acA800_pair()
    renderer = Renderer(calibration, Look(glint_prob=0.02), np.random.default_rng(1))
    truth, axes = racetrack(args.pairs)
    pairs = [renderer.grab(k * DT_S, {"position": p, "axis": a}).images for k, (p, a) in enumerate(zip(truth, axes))]

    def factory():
        return PairLocator(calibration, BlobParams(), PairParams())

    tracked = np.min([time_pass(factory, pairs, True)[0] for _ in range(args.repeat)], axis=0)
    whole = np.min([time_pass(factory, pairs, False)[0] for _ in range(args.repeat)], axis=0)
    _, found = time_pass(factory, pairs, True)
    error_mm = np.linalg.norm(found - truth, axis=1) * 1e3
    width, height = calibration["top"].size
    out = {
        "pair_ms": {"median": round(float(np.median(tracked)), 3), "p99": round(float(np.percentile(tracked, 99)), 3)},
        "whole_frame_ms": round(float(np.median(whole)), 3),
        "width": width,
        "height": height,
        "pairs": args.pairs,
        "repeat": args.repeat,
        "detection_error_mm": {"median": round(float(np.nanmedian(error_mm)), 4),
                               "p99": round(float(np.nanpercentile(error_mm, 99)), 4),
                               "missed": int(np.isnan(error_mm).sum())},
        "budget_ms": BUDGET_MS,
        "within_budget": bool(np.median(tracked) <= BUDGET_MS),
        "load_average_1min": round(os.getloadavg()[0], 2),
        "cpus": os.cpu_count(),
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()

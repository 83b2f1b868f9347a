"""Write a run as a rig's own recordings would look, for the docs' "Your lab's logs" walkthrough (docs/lab-logs.md).

A rig's controller logs its command when it sends it (here at 25 Hz, as a
rotation axis and a spin frequency), and its tracker logs detections at the
cameras' frame times (here 50 frames/s, 4 ms after the control ticks, in mm,
about 5 % of the frames lost and missing from the file; ``--fps`` sets
another rate). This script writes both from a run folder
of `cosim run` (the applied commands of its ``log.csv``, the true positions
of its ``trace.npz``), so `cosim convert` has something real to convert; on a rig, export the same two
files from its own logs.

    python examples/lab_recording.py RUN_DIR --out FOLDER [--fps 50]   # FOLDER/commands.csv, detections.csv
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from cosim_plugins.raw_log import read_log

COMMAND_HZ = 25.0
LOST = 0.05
NOISE_MM = 0.1


def write_recording(run_dir: Path, out: Path, fps: float = 50.0, seed: int = 0) -> tuple[Path, Path]:
    """commands.csv (t_s, axis_x..z, freq_hz) and detections.csv (t_ms, x, y, z [mm]) in ``out``."""
    log = read_log(run_dir / "log.csv")  # the command the coils applied, per control tick
    t, omega = log.t_s, 2 * np.pi * log.omega_hz  # (n,) s, (n, 3) rad/s
    trace = np.load(run_dir / "trace.npz")
    truth_mm = np.column_stack([np.interp(t, trace["t_s"], trace["plant.position"][:, a] * 1e3) for a in range(3)])
    rng = np.random.default_rng(seed)
    out.mkdir(parents=True, exist_ok=True)
    cmd_t = np.arange(t[0], t[-1], 1 / COMMAND_HZ)
    held = np.searchsorted(t, cmd_t, side="right") - 1
    w = omega[held]
    f_hz = np.linalg.norm(w, axis=1) / (2 * np.pi)
    axis = np.where(f_hz[:, None] > 0, w / np.maximum(2 * np.pi * f_hz, 1e-12)[:, None], [0.0, 0.0, 1.0])
    commands = out / "commands.csv"
    np.savetxt(commands, np.column_stack([cmd_t, axis, f_hz]), fmt="%.6f", delimiter=",",
               header="t_s,axis_x,axis_y,axis_z,freq_hz", comments="")
    frame_t = np.arange(t[0] + 0.004, t[-1], 1 / fps)
    kept = frame_t[rng.random(len(frame_t)) >= LOST]
    p = np.column_stack([np.interp(kept, t, truth_mm[:, a]) for a in range(3)])
    p += NOISE_MM * rng.normal(size=p.shape)
    detections = out / "detections.csv"
    np.savetxt(detections, np.column_stack([kept * 1e3, p]), fmt="%.3f", delimiter=",", header="t_ms,x,y,z",
               comments="")
    return commands, detections


def main() -> None:
    """The command line: write a run's commands and detections as a rig would record them."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", type=Path, help="a run folder of `cosim run` (holds trace.npz)")
    ap.add_argument("--out", type=Path, required=True, help="folder for commands.csv and detections.csv")
    ap.add_argument("--fps", type=float, default=50.0, help="camera frame rate [1/s] (default 50)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    for path in write_recording(args.run_dir, args.out, args.fps, args.seed):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()

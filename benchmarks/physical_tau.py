"""Why the KF on the physical model is not monotonic near 1 s frames (Fig. 6, docs/estimators.md).

Rolls the cached physical model out open loop from the plant's TRUE state (``trace.npz``:
``plant.position``, ``plant.velocity``) with the commands as applied, over ``T`` s, and
compares the end position with the plant's; the same with every force of the model scaled by
``s`` (same steady-state speed per Hz and sinking speed, the velocity time constant divided by
``s``). On the training runs (PI, 20 ms frames) and on closed loops of the KF on 1 s frames::

    COSIM_CACHE=cache python benchmarks/physical_tau.py 'runs/fb1s/runs/*/trace.npz' [out.png]

(``runs/fb1s``: ``cosim run scenarios/feedback_sweep.yaml --out runs/fb1s --set
sweep.components.camera.params.interval_s=[1.0] --set seed=...`` keeping the physical rows.)
With ``out.png`` it also plots 10 s of the first closed loop: the plant's z and vz against the
model's from each frame's true state. Prints the rms end error per axis [mm].
"""

from __future__ import annotations

import copy
import glob
import sys

import numpy as np

from cosim_plugins.identify.cache import resolve_model


def scaled(model, s: float):
    out = copy.deepcopy(model)
    out.set_params({n: v * s for n, v in model.params().items()})
    return out


def end_error(model, files, T: float, dt: float = 0.02) -> np.ndarray:
    n, errs = int(round(T / dt)), []
    for f in files:
        d = np.load(f)
        P, V = d["plant.position"] * 1e3, d["plant.velocity"] * 1e3
        U = d["controller.omega"] / (2 * np.pi)
        i0 = np.arange(250, len(P) - n - 1, n)
        x = np.concatenate([P[i0], V[i0]], 1)
        for k in range(n):
            x = model.predict(x, U[i0 + k], dt)
        errs.append(x[:, :3] - P[i0 + n])
    return np.sqrt((np.concatenate(errs) ** 2).mean(0))


def plot(model, trace: str, out: str, t0: float = 4.0, t1: float = 14.0, T: float = 1.0) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = np.load(trace)
    t, P, V = d["t_s"], d["plant.position"] * 1e3, d["plant.velocity"] * 1e3
    U = d["controller.omega"] / (2 * np.pi)
    n, sel = int(round(T / 0.02)), (t >= t0) & (t <= t1)
    fig, axs = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    axs[0].plot(t[sel], P[sel, 2], "k", label="plant z [mm]")
    axs[1].plot(t[sel], V[sel, 2], "k", label="plant vz [mm/s]")
    for s, style in ((1, "r"), (4, "b--")):
        m = scaled(model, s)
        for i0 in range(0, len(t) - n - 1, n):
            if not t0 <= t[i0] <= t1:
                continue
            x, traj = np.concatenate([P[i0], V[i0]]), []
            for k in range(n):
                x = m.predict(x, U[i0 + k], 0.02)
                traj.append(x.copy())
            traj = np.array(traj)
            axs[0].plot(t[i0 + 1:i0 + n + 1], traj[:, 2], style)
            axs[1].plot(t[i0 + 1:i0 + n + 1], traj[:, 5], style)
        axs[0].plot([], [], style, label=f"model x{s} from the plant's state at each frame"
                    + (" (as fitted)" if s == 1 else " (time constant / 4)"))
    axs[2].plot(t[sel], U[sel, 2], "g", label="command omega_z [Hz]")
    axs[2].plot(t[sel], d["estimator.position"][sel, 2] * 1e3, "m", label="KF estimate z [mm]")
    for a in axs:
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    axs[2].set_xlabel("t [s]")
    fig.suptitle("KF on the physical model, PI, racetrack, frames every 1 s (ideal profile)", fontsize=10)
    plt.tight_layout()
    plt.savefig(out, dpi=80)


def main() -> None:
    model = resolve_model("physical")
    p = model.params()
    tau = model.options["mass_mg"] / (1000.0 * p["Cd1"])
    print(f"physical model: velocity time constant along the axis m / Cd1 = {tau:.2f} s")
    train = sorted(glob.glob("cache/paper_dataset/runs/training/runs/*/trace.npz"))
    loop = sorted(glob.glob(sys.argv[1])) if len(sys.argv) > 1 else []
    for name, files in (("training runs (PI, 20 ms frames)", train), ("closed loop, KF physical, 1 s frames", loop)):
        if not files:
            continue
        for T in (0.4, 1.0):
            for s in (1, 2, 4, 8):
                e = end_error(scaled(model, s), files, T)
                print(f"{name:38s} T={T:.1f} s  forces x{s} (tau {tau / s:.2f} s): end error rms x/y/z "
                      f"{e[0]:5.2f} {e[1]:5.2f} {e[2]:5.2f} mm")
    if loop and len(sys.argv) > 2:
        plot(model, loop[0], sys.argv[2])


if __name__ == "__main__":
    main()

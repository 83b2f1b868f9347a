"""Plots of predicted versus measured positions: PNG (matplotlib Agg) and a rerun overlay.

Files written into the plot directory:

* ``one_step_<model>.png``: x, y, z over time for the first log's first
  ``seconds``: measured and one-step predicted.
* ``rollouts_<model>.png``: x-y view of the measured path with 0.42 s
  open-loop rollouts started every 0.5 s.
* ``errors.png``: one-step and rollout error norms per model.
* ``compare.rrd``: measured path and each model's one-step prediction over
  time, and the rollouts as line strips.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cosim_plugins.identify.dataset import log_label

ROLLOUT_S = 0.42
ROLLOUT_EVERY_S = 0.5


def write_plots(models: dict, dataset, result: dict, out_dir, seconds: float = 20.0) -> list[Path]:
    """Write all plots for a compare run; returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    n_first = dataset.logs[0].n  # rows of the first log (index 0..n-1 in the stacked timeline)
    rows = min(n_first, int(round(seconds / dataset.dt_s)))
    t = np.arange(len(dataset.p)) * dataset.dt_s
    strips = {}
    first = log_label(str(dataset.logs[0].path))
    split = f", {result['split']} split" if result.get("split") else ""
    for name, model in models.items():
        idx = dataset.pair_index()
        idx = idx[idx + 1 < rows]
        pred = model.predict(dataset.x[idx], dataset.u[idx], dataset.dt_s)[:, :3]
        fig, axes = plt.subplots(3, 1, sharex=True, figsize=(9, 6))
        for a, ax in enumerate(axes):
            ax.plot(t[:rows], dataset.p[:rows, a], "k.", ms=2, label="measured")
            ax.plot(t[idx + 1], pred[:, a], "-", lw=0.8, label=f"{name} one-step")
            ax.set_ylabel(f"{'xyz'[a]} [mm]")
        axes[0].legend(loc="upper right", fontsize=8)
        axes[-1].set_xlabel("time in the log [s]")
        fig.suptitle(f"{name}: one-step prediction vs measurement, first {rows * dataset.dt_s:g} s of {first}{split}",
                     fontsize=9)
        files.append(_save(fig, out / f"one_step_{name}.png", plt))
        strips[name] = _rollouts(model, dataset, n_first)
        fig, ax = plt.subplots(figsize=(6, 6))
        ax.plot(dataset.p[:n_first, 0], dataset.p[:n_first, 1], "k.", ms=1, label="measured")
        for k, s in enumerate(strips[name]):
            ax.plot(s[:, 0], s[:, 1], "r-", lw=0.8, label=f"{ROLLOUT_S:g} s rollouts" if k == 0 else None)
        ax.set_aspect("equal")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.legend(fontsize=8)
        ax.set_title(f"{name}: {ROLLOUT_S:g} s open-loop rollouts every {ROLLOUT_EVERY_S:g} s, top view of "
                     f"{first}{split}", fontsize=9)
        files.append(_save(fig, out / f"rollouts_{name}.png", plt))
    files.append(_error_bars(result, out / "errors.png", plt))
    files.append(_rerun(models, dataset, strips, rows, out / "compare.rrd"))
    return files


def _save(fig, path, plt):
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _rollouts(model, dataset, n_rows: int) -> list[np.ndarray]:
    """0.42 s rollouts (each (k + 1, 3) positions) started every 0.5 s in the first log."""
    k = int(round(ROLLOUT_S / dataset.dt_s))
    idx = dataset.window_index(k)
    idx = idx[idx + k < n_rows]
    every = max(1, int(round(ROLLOUT_EVERY_S / dataset.dt_s)))
    idx = idx[np.unique(idx // every, return_index=True)[1]] if len(idx) else idx
    if len(idx) == 0:
        return []
    j = idx[:, None] + np.arange(k)[None, :]
    states = model.rollout(dataset.x[idx], dataset.u[j], dataset.dt_s)
    return list(states[:, :, :3])


def _error_bars(result: dict, path, plt):
    models = result["models"]
    names = list(models)
    keys = ["one-step"] + [f"{k} s" for k in next(iter(models.values()))["rollout_mm"]] if names else []
    vals = np.array([[models[n]["one_step_mm"]["norm"] or np.nan]
                     + [v if v is not None else np.nan for v in models[n]["rollout_mm"].values()] for n in names])
    fig, ax = plt.subplots(figsize=(8, 4))
    width = 0.8 / max(1, len(names))
    for i, n in enumerate(names):
        ax.bar(np.arange(len(keys)) + i * width, vals[i], width, label=n)
    ax.set_xticks(np.arange(len(keys)) + 0.4 - width / 2, keys)
    ax.set_yscale("log")
    ax.set_xlabel("prediction: one step, or open-loop rollout of the given horizon")
    ax.set_ylabel("mean error norm [mm]")
    split = f" ({result['split']} split)" if result.get("split") else ""
    ax.set_title(f"prediction error per model on {len(result.get('logs', [])) or 'the'} logs{split}", fontsize=9)
    ax.legend(fontsize=8)
    return _save(fig, path, plt)


def _rerun(models: dict, dataset, strips: dict, rows: int, path) -> Path:
    """Measured and predicted positions on a ``time`` timeline, rollouts as static strips."""
    import rerun as rr

    rec = rr.RecordingStream("cosim_compare")
    rec.save(str(path))
    ok = np.flatnonzero(dataset.pos_ok[:rows])
    times = ok * dataset.dt_s
    rec.send_columns("measured", indexes=[rr.TimeColumn("time", duration=times)],
                     columns=rr.Points3D.columns(positions=dataset.p[ok], radii=np.full(len(ok), 0.4)))
    for name, model in models.items():
        idx = dataset.pair_index()
        idx = idx[idx + 1 < rows]
        if len(idx):
            pred = model.predict(dataset.x[idx], dataset.u[idx], dataset.dt_s)[:, :3]
            rec.send_columns(f"models/{name}/one_step",
                             indexes=[rr.TimeColumn("time", duration=(idx + 1) * dataset.dt_s)],
                             columns=rr.Points3D.columns(positions=pred, radii=np.full(len(idx), 0.4)))
        if strips.get(name):
            rec.log(f"models/{name}/rollouts", rr.LineStrips3D(strips[name]), static=True)
    rec.flush()
    rec.disconnect()
    return Path(path)

"""Model accuracy against measurements (paper Table III and Sec. III-C).

One-step: from each valid measured state x_i and command u_i predict
P_{i+1}; report the per-axis mean absolute error and the norm (mean of the
per-sample Euclidean errors) in mm. Open-loop rollouts over 0.1 s, 0.42 s and
1.0 s: from the measured state feed the recorded commands and compare the
final position with the measurement; windows with any gap are skipped, and
windows where the model's prediction blows up (non-finite) are counted as
``diverged`` and left out of the error.

JSON::

    {"models": {NAME: {"one_step_mm": {"x", "y", "z", "norm"},
                       "rollout_mm": {"0.1": norm, "0.42": norm, "1.0": norm},
                       "rollout_detail": {"0.1": {"x", "y", "z", "norm", "steps", "windows",
                                                  "diverged"}, ...},
                       "n_pairs": N}},
     "split": label or null, "logs": [...]}
"""

from __future__ import annotations

import numpy as np

from cosim.contract.errors import UserError

#: Rollout horizons: JSON key -> seconds.
HORIZONS_S = {"0.1": 0.1, "0.42": 0.42, "1.0": 1.0}
#: Windows per batch in rollouts (bounds memory: chunk x steps x 3 floats).
CHUNK = 20000


def _errors(pred, meas) -> dict:
    """Per-axis MAE and mean Euclidean norm [mm] of (n, 3) predictions against (n, 3) measurements."""
    if len(pred) == 0:
        return {"x": None, "y": None, "z": None, "norm": None}
    d = pred - meas
    mae = np.mean(np.abs(d), axis=0)
    return {"x": float(mae[0]), "y": float(mae[1]), "z": float(mae[2]),
            "norm": float(np.mean(np.linalg.norm(d, axis=1)))}


def one_step(model, dataset) -> tuple[dict, np.ndarray, np.ndarray]:
    """(errors dict, predicted (N, 3), index (N,)) for one-step prediction of positions."""
    idx = dataset.pair_index()
    X, U, Xn = dataset.pairs(idx)
    pred = model.predict(X, U, dataset.dt_s)[:, :3] if len(idx) else np.zeros((0, 3))
    return _errors(pred, Xn[:, :3]), pred, idx


def rollout_end(model, dataset, steps: int) -> tuple[dict, np.ndarray, np.ndarray]:
    """(errors dict, predicted end positions (W, 3), window starts (W,)) for ``steps``-step rollouts."""
    idx = dataset.window_index(steps)
    ends = np.empty((len(idx), 3))
    for s in range(0, len(idx), CHUNK):
        part = idx[s : s + CHUNK]
        x = dataset.x[part]
        for j in range(steps):
            x = model.predict(x, dataset.u[part + j], dataset.dt_s)
        ends[s : s + CHUNK] = x[:, :3]
    meas = dataset.p[idx + steps]
    finite = np.all(np.isfinite(ends), axis=1)
    err = _errors(ends[finite], meas[finite])
    err.update(steps=int(steps), windows=int(len(idx)), diverged=int((~finite).sum()))
    return err, ends, idx


def compare(models: dict, dataset, horizons_s=HORIZONS_S, progress=None) -> dict:
    """Errors of each model on ``dataset``; the JSON shape in the module docstring."""
    out = {}
    for name, model in models.items():
        if progress:
            progress(f"comparing {name} ...")
        try:
            model.predict(np.zeros(6), np.zeros(3), dataset.dt_s)
        except ValueError as exc:
            raise UserError(f"model {name!r} cannot step these logs: {exc}") from exc
        os_err, _, idx = one_step(model, dataset)
        res = {"one_step_mm": os_err, "n_pairs": int(len(idx)), "rollout_mm": {}, "rollout_detail": {}}
        for key, h in horizons_s.items():
            steps = max(1, int(round(h / dataset.dt_s)))
            err, _, _ = rollout_end(model, dataset, steps)
            res["rollout_mm"][key] = err["norm"]
            res["rollout_detail"][key] = err
        out[name] = res
    return {"models": out}


def format_table(result: dict) -> str:
    """Printable table of a :func:`compare` result."""
    models = result["models"]
    if not models:
        return "(no models)"
    keys = list(next(iter(models.values()))["rollout_mm"])
    head = f"{'model':<16} {'x':>6} {'y':>6} {'z':>6} {'norm':>6} | " + " ".join(f"{k + ' s':>7}" for k in keys)
    lines = [f"{'':<16} {'one-step error [mm]':^27} | {'rollout end error [mm]':^{8 * len(keys)}}", head,
             "-" * len(head)]
    for name, r in models.items():
        o = r["one_step_mm"]
        cells = [_f(o[a]) for a in ("x", "y", "z", "norm")]
        roll = [f"{_f(r['rollout_mm'][k]):>7}" for k in keys]
        lines.append(f"{name:<16} " + " ".join(f"{c:>6}" for c in cells) + " | " + " ".join(roll))
    return "\n".join(lines)


def _f(v) -> str:
    return "-" if v is None or not np.isfinite(v) else f"{v:.3f}"

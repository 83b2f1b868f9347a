"""Where, when and under which conditions a model's open-loop error concentrates.

Each evaluation window (a lead-in, then an open-loop prediction of K steps;
see :mod:`cosim_plugins.identify.joint`) gets one error vector (predicted minus
measured position at the reference horizon [mm]) and features describing
the prediction span (the K steps after the lead-in), from the measured
positions, their smoothed velocities and the commands:

=================  ======  =====================================================
feature            unit    meaning
=================  ======  =====================================================
x, y, z            mm      mean position (workspace region)
wall_distance      mm      smallest distance to the nearest wall of the 150 mm tank
centre_distance    mm      mean distance from the manipulator centre
log                1       the log (experiment) the window is in, in the order recorded
time               s       time in the log when the prediction starts
path_phase         deg     angle around the log's path (principal plane)
speed              mm/s    mean speed
spin               Hz      mean commanded spin frequency |omega|
angle_of_attack    deg     mean angle between the command and the velocity
command_rate       Hz/s    mean |d omega / dt| (how fast the command changes)
heading_z          1       mean vertical component of the command's direction
=================  ======  =====================================================

For each feature the windows are cut into quantile bins; a feature that
separates large from small errors has a large correlation ratio eta^2
(between-bin variance of the error norm over its total variance). Clues
are the strongest features in words, plus whether the errors share a
direction (a steady push) and how the error grows with the horizon.
"""

from __future__ import annotations

import warnings

import numpy as np

TANK_HALF_MM = 75.0
N_BINS = 6
MIN_PER_BIN = 15

FEATURES = {  # name: (unit, words)
    "x": ("mm", "x position"),
    "y": ("mm", "y position"),
    "z": ("mm", "z position"),
    "wall_distance": ("mm", "distance to the nearest wall"),
    "centre_distance": ("mm", "distance from the centre"),
    "log": ("", "log (in the order recorded)"),
    "time": ("s", "time in the log"),
    "path_phase": ("deg", "path phase"),
    "speed": ("mm/s", "speed"),
    "spin": ("Hz", "spin frequency"),
    "angle_of_attack": ("deg", "angle of attack"),
    "command_rate": ("Hz/s", "rate of change of the command"),
    "heading_z": ("", "vertical component of the swimming direction"),
}
GROUPS = {"where": ("x", "y", "z", "wall_distance", "centre_distance"), "when": ("log", "time", "path_phase"),
          "conditions": ("speed", "spin", "angle_of_attack", "command_rate", "heading_z")}


def window_features(tl, starts: np.ndarray, lead: int, steps: int) -> dict[str, np.ndarray]:
    """{feature: (w,) values} for the prediction span rows start+lead .. start+lead+steps."""
    rows = starts[:, None] + lead + np.arange(steps + 1)[None, :]
    rows = np.minimum(rows, tl.n - 1)
    p = tl.p[rows]  # (w, K+1, 3)
    v = np.where(np.isfinite(tl.x_lin[rows, 3:]), tl.x_lin[rows, 3:], np.nan)
    u = tl.u[rows[:, :-1]]
    with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN spans give NaN features, skipped later
        pm = np.nanmean(p, axis=1)
        wall = np.nanmin(TANK_HALF_MM - np.max(np.abs(p), axis=2), axis=1)
        un = np.linalg.norm(u, axis=2)
        vn = np.linalg.norm(v, axis=2)
        cos = np.einsum("wka,wka->wk", u, v[:, :-1]) / (un * vn[:, :-1])
        du = np.linalg.norm(np.diff(tl.u[rows], axis=1), axis=2) / tl.dt_s
        out = {
            "x": pm[:, 0], "y": pm[:, 1], "z": pm[:, 2],
            "wall_distance": wall,
            "centre_distance": np.nanmean(np.linalg.norm(p, axis=2), axis=1),
            "log": tl.log[starts + lead].astype(float),
            "time": tl.t_s[starts + lead],
            "path_phase": _path_phase(tl, pm, tl.log[starts + lead]),
            "speed": np.nanmean(vn, axis=1),
            "spin": np.nanmean(un, axis=1),
            "angle_of_attack": np.degrees(np.arccos(np.clip(np.nanmean(cos, axis=1), -1, 1))),
            "command_rate": np.nanmean(du, axis=1),
            "heading_z": np.nanmean(u[..., 2] / np.where(un > 1e-9, un, np.nan), axis=1),
        }
    return out


def _path_phase(tl, pm: np.ndarray, log: np.ndarray) -> np.ndarray:
    """Angle [deg] of each window's mean position around its log's path, in the path's principal plane."""
    phase = np.full(len(pm), np.nan)
    for k in np.unique(log[log >= 0]):
        mine = tl.log == k
        pts = tl.p[mine][np.all(np.isfinite(tl.p[mine]), axis=1)]
        if len(pts) < 10:
            continue
        c = pts.mean(axis=0)
        _, _, vt = np.linalg.svd(pts - c, full_matrices=False)
        sel = log == k
        d = pm[sel] - c
        phase[sel] = np.degrees(np.arctan2(d @ vt[1], d @ vt[0]))
    return phase


def bin_errors(values: np.ndarray, err_norm: np.ndarray, n_bins: int = N_BINS) -> dict | None:
    """Quantile bins of one feature: edges, mean error and count per bin, and eta^2; None if too few windows."""
    ok = np.isfinite(values) & np.isfinite(err_norm)
    x, e = values[ok], err_norm[ok]
    if len(x) < n_bins * MIN_PER_BIN or np.ptp(x) <= 0:
        return None
    edges = np.unique(np.quantile(x, np.linspace(0, 1, n_bins + 1)))
    if len(edges) < 3:
        return None
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    counts = np.bincount(idx, minlength=len(edges) - 1)
    sums = np.bincount(idx, weights=e, minlength=len(edges) - 1)
    means = np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)
    total = float(np.var(e)) * len(e)
    between = float(np.nansum(counts * (means - e.mean()) ** 2))
    return {"edges": edges.tolist(), "mean_mm": means.tolist(), "count": counts.tolist(),
            "eta2": between / total if total > 0 else 0.0, "overall_mm": float(e.mean())}


def localise(features: dict, err: np.ndarray, horizon_means: dict | None = None, max_clues: int = 4) -> dict:
    """Binned error per feature, the direction of the errors, and clues in words.

    Args:
        features: {name: (w,) values} from :func:`window_features`.
        err: (w, 3) error vectors [mm] (NaN rows ignored).
        horizon_means: optional {horizon_s: mean error norm} to describe the growth with the horizon.
    """
    ok = np.all(np.isfinite(err), axis=1)
    norm = np.where(ok, np.linalg.norm(np.nan_to_num(err), axis=1), np.nan)
    bins = {name: bin_errors(values, norm) for name, values in features.items()}
    bins = {k: b for k, b in bins.items() if b is not None}
    mean_vec = err[ok].mean(axis=0) if ok.any() else np.full(3, np.nan)
    mean_norm = float(norm[ok].mean()) if ok.any() else float("nan")
    coherence = float(np.linalg.norm(mean_vec) / mean_norm) if ok.any() and mean_norm > 0 else 0.0
    ranked = sorted(bins, key=lambda k: bins[k]["eta2"], reverse=True)
    clues = [_clue(name, bins[name]) for name in ranked[:max_clues] if bins[name]["eta2"] >= 0.02]
    if coherence >= 0.3:  # a strong common direction is the first clue
        text = (f"the errors share a direction: the mean error vector (predicted minus measured, "
                f"{_vec(mean_vec)} mm) is {coherence:.0%} of the mean error size, a steady push (a drift of the "
                "water or a constant force) rather than noise; the model falls behind it, so the push is along "
                f"({_vec(-mean_vec / max(np.linalg.norm(mean_vec), 1e-12))})")
        clues.insert(0 if coherence >= 0.5 else len(clues), text)
    growth = _growth(horizon_means) if horizon_means else None
    if growth is not None:
        clues.append(growth)
    return {"windows": int(ok.sum()), "mean_mm": mean_norm, "mean_error_vector_mm": mean_vec.tolist(),
            "direction_coherence": coherence, "bins": bins, "ranked_features": ranked, "clues": clues,
            "groups": {g: [f for f in ranked if f in names] for g, names in GROUPS.items()}}


def _clue(name: str, b: dict) -> str:
    unit, words = FEATURES.get(name, ("", name))
    means = np.asarray(b["mean_mm"], dtype=float)
    j = int(np.nanargmax(means))
    lo, hi = b["edges"][j], b["edges"][j + 1]
    where = "lowest" if j == 0 else "highest" if j == len(means) - 1 else "middle"
    ratio = means[j] / b["overall_mm"] if b["overall_mm"] > 0 else float("nan")
    return (f"{words}: the error is {ratio:.1f}x the average ({means[j]:.2f} vs {b['overall_mm']:.2f} mm) "
            f"in the {where} range, {lo:.3g} to {hi:.3g} {unit}".rstrip() + f" (eta^2 = {b['eta2']:.2f})")


def _growth(horizon_means: dict) -> str | None:
    keys = sorted((float(h), m) for h, m in horizon_means.items() if m is not None and np.isfinite(m))
    if len(keys) < 2 or keys[0][1] <= 0 or keys[-1][1] <= 0:
        return None
    (h0, e0), (h1, e1) = keys[0], keys[-1]
    slope = np.log(e1 / e0) / np.log(h1 / h0)
    kind = ("grows faster than the horizon: an unmodelled force integrates over time" if slope >= 0.9 else
            "grows roughly in proportion to the horizon" if slope >= 0.6 else
            "grows slowly with the horizon: mostly noise or a short transient (timing) error")
    return f"the error {kind} ({e0:.2f} mm at {h0:g} s, {e1:.2f} mm at {h1:g} s; log-log slope {slope:.2f})"


def _vec(v) -> str:
    return ", ".join(f"{x:+.2f}" for x in v)

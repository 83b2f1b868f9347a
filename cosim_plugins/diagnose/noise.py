"""Measurement noise estimated from the positions themselves.

The third difference d3_i = p_{i+2} - 3 p_{i+1} + 3 p_i - p_{i-1} removes
any motion up to a constant acceleration; what is left of a smooth swimmer
path (jerk x dt^3, ~0.01 mm at 20 ms) is far below camera noise. For white
noise of standard deviation sigma, var(d3) = 20 sigma^2. The standard
deviation is taken after dropping values beyond 5 robust scales (the few
outliers the cleaning left); a plain median-based scale would snap to the
camera's pixel grid. Only runs of four measured positions at regular steps
are used.

The noise floor (:func:`noise_floor`) is the open-loop error a perfect model
would show: each window's initial state is fitted on the lead-in's noisy
positions and the error of that fit carries to the horizon. How far an
initial-velocity error carries depends only on the swimmer's velocity time
constant tau, so the floor uses first-order dynamics with that tau, not the
sensitivities of whatever model was fitted: a degenerate fit (no drag, an
initial-velocity error carried forever) cannot inflate it.
"""

from __future__ import annotations

import numpy as np

from cosim_plugins.identify.joint import RIDGE, floor_draws

D3_GAIN = np.sqrt(20.0)  # |(-1, 3, -3, 1)|
IQR_TO_SIGMA = 1 / 1.349
TRIM = 5.0


def noise_sigma_mm(tl, max_stride: int = 2) -> np.ndarray:
    """(3,) per-axis measurement noise standard deviation [mm] of a :class:`~cosim_plugins.identify.timeline.Timeline`.

    Uses consecutive rows; when too few runs of four measured rows exist (a
    camera slower than the control rate), every second row, and so on up to
    ``max_stride``. Returns NaN per axis when nothing works.
    """
    for stride in range(1, max_stride + 1):
        d3 = _third_differences(tl, stride)
        if len(d3) >= 30:
            return np.array([_trimmed_std(d3[:, a]) for a in range(3)]) / D3_GAIN
    return np.full(3, np.nan)


def _third_differences(tl, s: int) -> np.ndarray:
    """(m, 3) p_{i+2s} - 3 p_{i+s} + 3 p_i - p_{i-s} where all four are measured and the steps regular."""
    p = tl.p
    n = len(p)
    if n < 3 * s + 1:
        return np.zeros((0, 3))
    i = np.arange(s, n - 2 * s)
    fin = np.all(np.isfinite(p), axis=1)
    ok = (tl.run[i - s] >= 3 * s) & fin[i - s] & fin[i] & fin[i + s] & fin[i + 2 * s]
    i = i[ok]
    return p[i + 2 * s] - 3 * p[i + s] + 3 * p[i] - p[i - s]


def _trimmed_std(x: np.ndarray) -> float:
    x = x - np.median(x)
    q1, q3 = np.percentile(x, [25, 75])
    scale = max((q3 - q1) * IQR_TO_SIGMA, np.mean(np.abs(x)) * 1.25, 1e-9)
    x = x[np.abs(x) <= TRIM * scale]
    return float(np.sqrt(np.mean(x * x)))


def noise_floor(tl, starts: np.ndarray, lead: int, steps: dict, sigma_mm, tau_s: float, draws: int = 8,
                seed: int = 0) -> dict:
    """{horizon key: (w,) expected error norm [mm] of a perfect model} for windows at ``starts``.

    Position sensitivity to the initial state along a window, first-order velocity response:
    p_k = p_0 + v_0 tau (1 - exp(-k dt / tau)); the initial state is fitted on rows 0..lead
    (those measured), white noise ``sigma_mm`` (3,) on every measurement.
    """
    length = lead + max(steps.values())
    rows = starts[:, None] + np.arange(length + 1)[None, :]
    measured = tl.measured[np.minimum(rows, tl.n - 1)] & (rows < tl.n)
    use = np.zeros_like(measured)
    use[:, : lead + 1] = measured[:, : lead + 1]
    g = tau_s * -np.expm1(-np.arange(length + 1) * tl.dt_s / tau_s)  # (L + 1,)
    S = np.zeros((len(starts), length + 1, 3, 6))
    S[..., :3] = np.eye(3)
    S[..., 3:] = g[None, :, None, None] * np.eye(3)
    Su = S * use[..., None, None]
    G = np.einsum("wkai,wkaj->wij", Su, Su) + RIDGE
    return floor_draws(S, G, use, lead, steps, sigma_mm, draws, seed)

"""Noise models of the Kalman estimator: R from the camera, Q from a model's multi-step residuals.

Units are the models' (mm, mm/s, Hz); variances in mm^2 and (mm/s)^2.

Measurement noise R (:func:`camera_variance`): each camera adds Gaussian
pixel noise (``noise_px`` pixels of ``pixel_mm``) and rounds to its pixel grid
(uniform error, variance pixel^2 / 12). x is the mean of the top and side
cameras (half the variance), y comes from the top camera, z from the side one.

Process noise Q (:func:`fit_process_noise`): the model is rolled out open
loop from measured states over windows of the raw logs (``horizon`` steps,
commands as logged). The k-step residuals of position ``P_meas - P_model``
and of velocity (backward differences, like the model's state) give robust
per-axis second moments ``V[k]`` (points beyond 6 MAD dropped: outliers,
lost detections). The filter's own linearised error model predicts them as

    V[k] = diag(F^k P0 F^k') + R_k + sum_{i<k} diag(F^i Q F^i')

for the position and velocity rows, with F the filter's transition Jacobian
(the model's, averaged over 64 logged states, plus the drift state), P0 the
covariance of a state built from two noisy frames and R_k the measurement
noise of a logged position or velocity (both known from R). The unknowns,
per axis: white position noise q_p, velocity noise q_v and, with a drift
state, the drift's stationary variance s_d (a first-order Gauss-Markov
velocity offset with correlation time tau: it starts each window with
variance s_d and is driven by s_d (1 - phi^2) per step, phi = exp(-dt/tau)).
They are the non-negative least-squares fit, in relative terms, of that
line to the measured V over all horizons. So Q is what the model needs to
explain how its own predictions go wrong over the horizons the filter
bridges; the rms residuals measured and fitted are kept for reports.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def camera_variance(noise_px: float, pixel_mm: float) -> np.ndarray:
    """Measurement noise variance per axis [mm^2], (3,), of the two-camera emulator/rig."""
    one = (noise_px * pixel_mm) ** 2 + pixel_mm**2 / 12.0
    return np.array([one / 2.0, one, one])


def drift_decay(dt_s: float, tau_s: float) -> float:
    """Per-step factor phi = exp(-dt / tau) of the drift's first-order Gauss-Markov process."""
    return float(np.exp(-dt_s / tau_s))


def transition_jacobian(A: np.ndarray, dt_s: float, phi: float | None) -> np.ndarray:
    """The filter's state transition Jacobian: (6, 6), or (9, 9) with a drift state (``phi`` given).

    With drift the state is [p, v, d] and p' = f_p(x, u) + dt d, v' = f_v(x, u), d' = phi d.
    """
    if phi is None:
        return A
    F = np.zeros((9, 9))
    F[:6, :6] = A
    F[:3, 6:] = dt_s * np.eye(3)
    F[6:, 6:] = phi * np.eye(3)
    return F


def frame_state_covariance(r_mm2: np.ndarray, dt_s: float) -> np.ndarray:
    """(6, 6) covariance of x = [p_i, (p_i - p_{i-1}) / dt] built from two frames with noise ``r_mm2``."""
    P = np.zeros((6, 6))
    for a in range(3):
        P[a, a] = r_mm2[a]
        P[a, 3 + a] = P[3 + a, a] = r_mm2[a] / dt_s
        P[3 + a, 3 + a] = 2.0 * r_mm2[a] / dt_s**2
    return P


def mean_jacobian(model, X: np.ndarray, U: np.ndarray, dt_s: float) -> np.ndarray:
    """(6, 6) state Jacobian of one step: exact for linear models, else averaged over the states X, U."""
    try:
        return np.asarray(model.linear_matrices()[0], dtype=float)
    except NotImplementedError:
        pass
    As = [model.jacobians(x, u, dt_s)[0] for x, u in zip(X, U)]
    A = np.mean(As, axis=0)
    if not np.all(np.isfinite(A)):
        raise ValueError("the model's Jacobian is not finite on the logged states")
    return A


def robust_second_moment(r: np.ndarray) -> np.ndarray:
    """Per column second moment of ``r`` (n, m) about zero after dropping points beyond 6 MAD (and NaN)."""
    out = np.empty(r.shape[1])
    for j in range(r.shape[1]):
        c = r[:, j][np.isfinite(r[:, j])]
        if len(c) < 10:
            out[j] = np.nan
            continue
        med = np.median(c)
        mad = 1.4826 * np.median(np.abs(c - med))
        keep = c[np.abs(c - med) <= 6.0 * max(mad, 1e-9)]
        out[j] = np.mean(keep**2)
    return out


@dataclass
class ProcessNoise:
    """Fitted noise: per-step Q diagonal, drift prior, and the fit's evidence.

    Attributes:
        q: (n,) per-step process noise variances, n = 6 ([p mm^2, v (mm/s)^2])
            or 9 (+ drift d (mm/s)^2).
        drift0: (3,) stationary (and initial) variance of the drift d [(mm/s)^2] (zeros without drift).
        horizons: (k,) horizons [steps] where measured and fitted residuals are reported.
        measured_mm, fitted_mm: (k, 3) rms k-step position residual, data and fitted model.
        windows: number of data windows used.
    """

    q: np.ndarray
    drift0: np.ndarray
    horizons: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    measured_mm: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    fitted_mm: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    windows: int = 0

    def report(self) -> dict:
        """JSON-able summary (for logs and tests)."""
        return {"q": self.q.tolist(), "drift0": self.drift0.tolist(), "windows": self.windows,
                "horizons": self.horizons.tolist(), "measured_mm": np.round(self.measured_mm, 3).tolist(),
                "fitted_mm": np.round(self.fitted_mm, 3).tolist()}


def measured_residuals(model, dataset, horizon: int, dt_s: float, max_windows: int = 3000, seed: int = 0):
    """k-step residual second moments of position (horizon, 3) [mm^2] and velocity (horizon, 3)
    [(mm/s)^2], and the window starts' states and commands.

    The measured velocity is the logs' backward difference, like the model's state.
    Windows start at valid logged states and never cross a gap (see ``Dataset.windows``).
    """
    idx = dataset.window_index(horizon)
    if len(idx) < 50:
        raise ValueError(f"only {len(idx)} {horizon}-step windows without gaps in the logs; need at least 50")
    if len(idx) > max_windows:
        idx = np.sort(np.random.default_rng(seed).choice(idx, max_windows, replace=False))
    X0, U, P = dataset.windows(horizon, idx)
    with np.errstate(all="ignore"):
        pred = model.rollout(X0, U, dt_s)[:, 1:]
        rp = P - pred[:, :, :3]
        v_meas = np.diff(np.concatenate([X0[:, None, :3], P], axis=1), axis=1) / dt_s
        rv = v_meas - pred[:, :, 3:]
    Vp = np.array([robust_second_moment(rp[:, k]) for k in range(horizon)])
    Vv = np.array([robust_second_moment(rv[:, k]) for k in range(horizon)])
    return Vp, Vv, X0, U[:, 0], len(idx)


def fit_process_noise(model, dataset, r_mm2: np.ndarray, dt_s: float, drift_tau_s: float | None = 2.0,
                      horizon: int = 50, max_windows: int = 3000, seed: int = 0) -> ProcessNoise:
    """Fit Q (and the drift's variance) to ``model``'s measured multi-step residuals on ``dataset``.

    Args:
        model: a :class:`cosim_plugins.identify.model.Model`.
        dataset: a :class:`cosim_plugins.identify.dataset.Dataset` (raw logs) at period ``dt_s`` [s].
        r_mm2: (3,) measurement noise variance of the logs [mm^2].
        drift_tau_s: correlation time of the drift state d [s] (None: no drift, 6 states).
        horizon: longest horizon fitted [steps].
    """
    Vp, Vv, X0, U0, n_windows = measured_residuals(model, dataset, horizon, dt_s, max_windows, seed)
    if np.isfinite(Vp).all(axis=1).sum() < 2:
        raise ValueError("the model's open-loop predictions diverge on the logs; cannot fit its process noise")
    pick = np.linspace(0, len(X0) - 1, min(64, len(X0))).astype(int)
    A = mean_jacobian(model, X0[pick], U0[pick], dt_s)
    drift = drift_tau_s is not None
    phi = drift_decay(dt_s, drift_tau_s) if drift else None
    F = transition_jacobian(A, dt_s, phi)
    P0 = frame_state_covariance(r_mm2, dt_s)
    r_v = 2.0 * r_mm2 / dt_s**2  # noise of a measured (backward-difference) velocity
    n_unknown = 9 if drift else 6  # q_p, q_v (3 each) and the drift's stationary variance s_d
    G_all = np.zeros((horizon, 6, n_unknown))  # variance per unknown, rows p (3) and v (3)
    known = np.zeros((horizon, 6))
    Fi = np.eye(F.shape[0])  # F^i
    acc = np.zeros((6, F.shape[0]))  # sum_{i<k} (F^i)[a, m]^2
    for k in range(1, horizon + 1):
        acc += Fi[:6] ** 2
        Fi = F @ Fi
        known[k - 1] = np.diag(Fi[:6, :6] @ P0 @ Fi[:6, :6].T) + np.concatenate([r_mm2, r_v])
        G_all[k - 1, :, :6] = acc[:, :6]
        if drift:  # d stationary with variance s_d: s_d at the start, s_d (1 - phi^2) added per step
            G_all[k - 1, :, 6:] = Fi[:6, 6:9] ** 2 + (1.0 - phi**2) * acc[:, 6:9]
    V = np.concatenate([Vp, Vv], axis=1)
    use = np.isfinite(V) & (V > 0)
    use[0, 3:] = False  # the 1-step velocity residual shares a frame with the initial state
    from scipy.optimize import nnls  # here: scipy.optimize costs 0.4 s to import, every `cosim` start

    w = 1.0 / V[use]
    theta, _ = nnls(G_all[use] * w[:, None], (V[use] - known[use]) * w)
    q = theta[:6]
    drift0 = theta[6:] if drift else np.zeros(3)
    if drift:
        q = np.concatenate([q, (1.0 - phi**2) * drift0])
    fitted = known + G_all @ theta
    horizons = np.array(sorted({1, 2, 5, 10, 25, 50, horizon} & set(range(1, horizon + 1))))
    return ProcessNoise(q=q, drift0=drift0, horizons=horizons, measured_mm=np.sqrt(Vp[horizons - 1]),
                        fitted_mm=np.sqrt(fitted[horizons - 1, :3]), windows=n_windows)

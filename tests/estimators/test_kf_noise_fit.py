"""The process-noise fit against an independent reference: the filter's covariance propagated step by step.

``fit_process_noise`` builds, per horizon k, the variance the filter's linearised error model predicts
(``V[k] = diag(F^k P0 F^k') + R_k + sum_(i<k) diag(F^i Q F^i')``, the drift's share included) as a
sum over powers of F, and fits the unknowns by non-negative least squares in relative terms. The
reference here is the textbook recursion ``P_k = F P_(k-1) F' + Q`` from the initial covariance, run
once per unknown (the variances are linear in them), then the same weighted problem handed to scipy.
The model's Jacobian depends on the state and the command, so the states it is averaged over (64
window starts, evenly spread) are pinned too.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.optimize import nnls

from cosim_plugins.estimators import noise
from cosim_plugins.estimators.noise import (
    camera_variance,
    drift_decay,
    fit_process_noise,
    frame_state_covariance,
    measured_residuals,
    robust_second_moment,
)

DT = 0.02
R = camera_variance(0.5, 0.19)


class Bent:
    """A model whose one-step Jacobian depends on the state and the command.

    x' = [p + dt v, v + dt (-(1 + x0 / 40) v + 0.3 u0 v_y e_x)]: damping that grows along x and a
    command that couples v_y into v_x. ``rollout`` is never called here (the residuals are given).
    """

    def jacobians(self, x, u, dt_s):
        A = np.eye(6)
        A[:3, 3:] = dt_s * np.eye(3)
        for a in range(3):
            A[3 + a, 3 + a] -= dt_s * (1.0 + x[0] / 40.0)
            A[3 + a, 0] -= dt_s * x[3 + a] / 40.0
        A[3, 4] += dt_s * 0.3 * u[0]
        return A, np.zeros((6, 3)), np.zeros(6)

    def linear_matrices(self):
        raise NotImplementedError


def window_starts(n: int):
    """n window starts along the tank's x axis, moving, with commands that vary: X0 (n, 6), U0 (n, 3)."""
    rng = np.random.default_rng(11)
    X0 = np.column_stack([np.linspace(-60, 60, n), rng.uniform(-5, 5, (n, 2)), rng.uniform(-8, 8, (n, 3))])
    U0 = np.column_stack([np.linspace(0, 12, n) ** 1.5, rng.uniform(-3, 3, (n, 2))])
    return X0, U0


def reference_F(X0, U0, phi):
    """The transition Jacobian: the model's, averaged over 64 evenly spread window starts, plus the drift."""
    pick = np.linspace(0, len(X0) - 1, 64).astype(int)
    A = np.mean([Bent().jacobians(X0[i], U0[i], DT)[0] for i in pick], axis=0)
    if phi is None:
        return A
    F = np.eye(9) * phi
    F[:6, :6] = A
    F[:3, 6:] = DT * np.eye(3)
    return F


def propagated(F, q_diag, drift0, horizon):
    """(horizon, 6) variances of the k-step position and velocity errors, P_k = F P_(k-1) F' + Q, plus R_k."""
    n = F.shape[0]
    P = np.zeros((n, n))
    P[:6, :6] = frame_state_covariance(R, DT)
    if n == 9:
        P[6:, 6:] = np.diag(drift0)
    out = np.empty((horizon, 6))
    for k in range(horizon):
        P = F @ P @ F.T + np.diag(q_diag)
        out[k] = np.diag(P)[:6] + np.concatenate([R, 2 * R / DT**2])
    return out


def reference_fit(F, V, phi):
    """The unknowns (q_p, q_v, and s_d with a drift) fitted to V by the same relative NNLS, columns by recursion."""
    horizon = len(V)
    drift = phi is not None
    n_unknown = 9 if drift else 6

    def model(theta):
        q = np.concatenate([theta[:6], (1 - phi**2) * theta[6:]]) if drift else theta
        return propagated(F, q, theta[6:] if drift else None, horizon)

    base = model(np.zeros(n_unknown))
    G = np.stack([model(np.eye(n_unknown)[j]) - base for j in range(n_unknown)], axis=-1)
    use = np.isfinite(V) & (V > 0)
    use[0, 3:] = False
    w = 1.0 / V[use]
    theta, _ = nnls(G[use] * w[:, None], (V[use] - base[use]) * w)
    return theta


def given_residuals(monkeypatch, V, X0, U0, windows=500):
    """fit_process_noise's measured residuals replaced by V (horizon, 6) and these window starts."""
    def measured(model, dataset, horizon, dt_s, max_windows=3000, seed=0):
        assert horizon == len(V)
        return V[:, :3], V[:, 3:], X0, U0, windows

    monkeypatch.setattr(noise, "measured_residuals", measured)


@pytest.mark.parametrize("tau", [2.0, None], ids=["drift", "no-drift"])
def test_the_fit_matches_the_covariance_recursion(monkeypatch, tau):
    X0, U0 = window_starts(300)
    phi = drift_decay(DT, tau) if tau else None
    F = reference_F(X0, U0, phi)
    truth = np.array([0.004, 0.002, 0.003, 5.0, 3.0, 4.0] + ([0.6, 0.2, 0.4] if tau else []))
    q_true = np.concatenate([truth[:6], (1 - phi**2) * truth[6:]]) if tau else truth
    exact = propagated(F, q_true, truth[6:] if tau else None, 30)
    given_residuals(monkeypatch, exact, X0, U0)
    np.testing.assert_allclose(fit_process_noise(Bent(), object(), R, DT, drift_tau_s=tau, horizon=30).q, q_true,
                               rtol=1e-6)  # the line met exactly: the truth comes back
    V = exact * (1 + 0.05 * np.random.default_rng(3).standard_normal(exact.shape))  # measured: not met exactly
    V[0, 3:] *= 5.0  # the 1-step velocity shares a frame with the state: never used
    V[7, 1] = np.nan  # too few residuals at one horizon
    V[12, 2] = 0.0  # an axis the model predicted exactly: no information
    given_residuals(monkeypatch, V, X0, U0)

    fit = fit_process_noise(Bent(), object(), R, DT, drift_tau_s=tau, horizon=30)
    theta = reference_fit(F, V, phi)
    assert fit.q.shape == ((9,) if tau else (6,)) and fit.drift0.shape == (3,)
    np.testing.assert_allclose(fit.q[:6], theta[:6], rtol=1e-6, atol=1e-12)
    if tau:
        np.testing.assert_allclose(fit.drift0, theta[6:], rtol=1e-6)
        np.testing.assert_allclose(fit.q[6:], (1 - phi**2) * theta[6:], rtol=1e-6)
    else:
        np.testing.assert_array_equal(fit.drift0, np.zeros(3))
    assert fit.windows == 500
    assert fit.horizons.tolist() == [1, 2, 5, 10, 25, 30]
    np.testing.assert_allclose(fit.measured_mm, np.sqrt(V[fit.horizons - 1, :3]))


def test_the_reported_horizons_stop_at_the_longest_fitted(monkeypatch):
    X0, U0 = window_starts(100)
    for horizon, expected in ((49, [1, 2, 5, 10, 25, 49]), (50, [1, 2, 5, 10, 25, 50]), (3, [1, 2, 3]),
                              (60, [1, 2, 5, 10, 25, 50, 60])):
        V = propagated(reference_F(X0, U0, None), np.array([0.01] * 3 + [4.0] * 3), None, horizon)
        given_residuals(monkeypatch, V, X0, U0)
        fit = fit_process_noise(Bent(), object(), R, DT, drift_tau_s=None, horizon=horizon)
        assert fit.horizons.tolist() == expected
        assert fit.fitted_mm.shape == fit.measured_mm.shape == (len(expected), 3)


def test_two_finite_horizons_are_enough_one_is_not(monkeypatch):
    X0, U0 = window_starts(100)
    V = propagated(reference_F(X0, U0, None), np.array([0.01] * 3 + [4.0] * 3), None, 4)
    V[2:, 0] = np.nan  # from the third horizon on, an axis diverged
    given_residuals(monkeypatch, V, X0, U0)
    assert fit_process_noise(Bent(), object(), R, DT, drift_tau_s=None, horizon=4).q.shape == (6,)
    V[1, 0] = np.nan
    with pytest.raises(ValueError) as err:
        fit_process_noise(Bent(), object(), R, DT, drift_tau_s=None, horizon=4)
    assert str(err.value) == "the model's open-loop predictions diverge on the logs; cannot fit its process noise"


class Drifting:
    """Logged windows: window i starts at a state of its own, its positions wander and drift at a speed of its own.

    The commands change every step, so the first one of a window is told from the later ones.
    """

    def __init__(self, n: int, longest: int = 50):
        self.n = n
        rng = np.random.default_rng(7)
        self.start = rng.uniform(-50, 50, (n, 3))
        self.walk = np.cumsum(rng.normal(0, 0.002, (n, longest, 3)), axis=1)
        self.walk += rng.normal(0, 3.0, (n, 1, 3)) * DT * np.arange(1, longest + 1)[:, None]  # a drift: 3 mm/s rms

    def window_index(self, horizon):
        return np.arange(self.n)

    def windows(self, horizon, idx):
        idx = np.asarray(idx)
        X0 = np.zeros((len(idx), 6))
        X0[:, :3] = self.start[idx]
        P = X0[:, None, :3] + self.walk[idx, :horizon]
        U = idx[:, None, None] + np.arange(horizon)[None, :, None] + np.array([0.0, 0.25, 0.5])
        return X0, U, P


class Resting:
    """The constant-velocity model (linear; here at rest, the windows' states having no velocity)."""

    def rollout(self, X0, U, dt_s):
        return np.repeat(X0[:, None, :], U.shape[1] + 1, axis=1)

    def linear_matrices(self):
        A = np.eye(6)
        A[:3, 3:] = DT * np.eye(3)
        return A, np.zeros((6, 3)), np.zeros(6)


def test_the_defaults_3000_windows_seed_0_horizon_50_and_a_2_s_drift():
    data = Drifting(3001)
    r = np.full(3, 1e-6)  # frames far more precise than the wander, which Q and the drift must then explain
    fit = fit_process_noise(Resting(), data, r, DT)
    assert fit.windows == 3000 and fit.horizons[-1] == 50
    assert fit.drift0.min() > 1.0  # the drift is seen: its correlation time matters
    phi = np.exp(-DT / 2.0)
    np.testing.assert_allclose(fit.q[6:], (1 - phi**2) * fit.drift0, rtol=1e-12)
    same = fit_process_noise(Resting(), data, r, DT, drift_tau_s=2.0, horizon=50, max_windows=3000, seed=0)
    np.testing.assert_array_equal(fit.q, same.q)
    np.testing.assert_array_equal(fit.measured_mm, same.measured_mm)


def test_a_thinned_fit_is_the_same_every_time_and_its_seed_decides_the_windows():
    data = Drifting(400)
    fits = [fit_process_noise(Resting(), data, R, DT, None, 10, max_windows=100, seed=s) for s in (0, 0, 1)]
    np.testing.assert_array_equal(fits[0].measured_mm, fits[1].measured_mm)
    assert not np.array_equal(fits[0].measured_mm, fits[2].measured_mm)
    default = fit_process_noise(Resting(), data, R, DT, None, 10, max_windows=100)
    np.testing.assert_array_equal(default.measured_mm, fits[0].measured_mm)


def test_measured_residuals_defaults_and_the_first_command_of_each_window():
    data = Drifting(3001)
    *_, X0, U0, n = measured_residuals(Resting(), data, 3, DT)
    assert n == 3000
    *_, X0_seed0, _, _ = measured_residuals(Resting(), data, 3, DT, max_windows=3000, seed=0)
    np.testing.assert_array_equal(X0, X0_seed0)
    first = int(np.flatnonzero((data.start == X0[0, :3]).all(axis=1))[0])  # the first window kept
    assert U0[0].tolist() == [first, first + 0.25, first + 0.5]  # the command of the window's first step


def test_a_diverging_model_gives_nan_residuals_without_a_warning():
    class Exploding(Resting):
        def rollout(self, X0, U, dt_s):
            out = super().rollout(X0, U, dt_s)
            out[::2, 2:] *= 1e200  # every other window blows up after two steps: an overflow
            out[::2, 2:] *= 1e200
            out[1::4, 3:] = np.nan
            return out

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Vp, Vv, *_ = measured_residuals(Exploding(), Drifting(200), 5, DT)
    assert np.isfinite(Vp[0]).all() and np.isfinite(Vp[4]).all()  # the survivors' residuals, inf beyond 6 MAD


def test_robust_second_moment_fills_every_column_after_a_short_one():
    base = np.array([1.0, -1.0] * 6)
    cols = np.column_stack([np.r_[base[:5], [np.nan] * 7], base, 2 * base])
    out = robust_second_moment(cols)
    assert np.isnan(out[0]) and out[1] == pytest.approx(1.0, rel=1e-15) and out[2] == pytest.approx(4.0, rel=1e-15)


def test_robust_second_moment_drops_outliers_about_a_far_median_and_at_a_small_spread():
    far = 50.0 + np.array([1.0, -1.0] * 6 + [9.5, -9.5])  # median 50, MAD 1: +-9.5 beyond 6 x 1.4826
    assert robust_second_moment(far[:, None])[0] == pytest.approx(2501.0, rel=1e-15)  # mean of 49^2, 51^2
    small = np.array([0.01, -0.01] * 6 + [0.5, -0.5])  # MAD 0.01: +-0.5 far beyond 6 robust sigmas
    assert robust_second_moment(small[:, None])[0] == pytest.approx(1e-4, rel=1e-12)

"""The filter core: textbook equivalence on a linear model, gating, long gaps, latency."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from cosim_plugins.estimators.ekf import MultiStepEKF
from cosim_plugins.estimators.noise import drift_decay, transition_jacobian

_spec = importlib.util.spec_from_file_location("kf_linear_plugin", Path(__file__).with_name("linear_plugin.py"))
linear_plugin = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(linear_plugin)

DT = linear_plugin.DT
R = np.array([0.006, 0.012, 0.012])  # mm^2
Q6 = np.array([1e-3, 1e-3, 1e-3, 4.0, 4.0, 4.0])


def simulate(n, seed=0, frame_every=1):
    """True states (n + 1, 6), commands (n, 3) [Hz] and frames (n + 1, 3) [mm] (NaN between) of the swimmer."""
    rng = np.random.default_rng(seed)
    A, B, c = linear_plugin.damped_swimmer()
    x = np.zeros((n + 1, 6))
    x[0, :3] = [-15.0, -40.0, 0.0]
    t = np.arange(n) * DT
    u = np.column_stack([8 * np.cos(0.5 * t), 8 * np.sin(0.5 * t), 1.0 + np.sin(0.2 * t)])
    for k in range(n):
        x[k + 1] = A @ x[k] + B @ u[k] + c + rng.normal(0, np.sqrt(Q6))
    z = x[:, :3] + rng.normal(0, np.sqrt(R), size=(n + 1, 3))
    z[np.arange(n + 1) % frame_every != 0] = np.nan
    return x, u, z


def textbook(A, B, c, Q, x0, P0, u, z):
    """The Kalman filter as textbooks write it: (estimates (n + 1, n_x), covariances)."""
    H = np.zeros((3, len(x0)))
    H[:, :3] = np.eye(3)
    x, P = x0.copy(), P0.copy()
    xs, Ps = [x.copy()], [P.copy()]
    for k in range(len(u)):
        x = A @ x + B @ u[k] + c
        P = A @ P @ A.T + Q
        if np.all(np.isfinite(z[k + 1])):
            K = P @ H.T @ np.linalg.inv(H @ P @ H.T + np.diag(R))
            x = x + K @ (z[k + 1] - H @ x)
            P = (np.eye(len(x0)) - K @ H) @ P
        xs.append(x.copy())
        Ps.append(P.copy())
    return np.array(xs), np.array(Ps)


@pytest.mark.parametrize("drift", [False, True], ids=["6 states", "9 states with drift"])
def test_linear_model_gives_the_textbook_kalman_filter(drift):
    model = linear_plugin.LinearSwimmer()
    A, B, c = model.linear_matrices()
    phi = drift_decay(DT, 2.0) if drift else None
    q = np.concatenate([Q6, [0.5, 0.5, 0.5]]) if drift else Q6
    p_init = np.concatenate([R, [400.0] * 3, [25.0] * 3 if drift else []])
    ekf = MultiStepEKF(model, DT, q, R, p_init, phi=phi)
    x_true, u, z = simulate(300, frame_every=3)
    ekf.start(z[0])
    xs, Ps = [ekf.x.copy()], [ekf.P.copy()]
    for k in range(len(u)):
        ekf.predict(u[k])
        if np.all(np.isfinite(z[k + 1])):
            ekf.update(z[k + 1])
        xs.append(ekf.x.copy())
        Ps.append(ekf.P.copy())
    F = transition_jacobian(A, DT, phi)
    n = len(q)
    Bn, cn = np.zeros((n, 3)), np.zeros(n)
    Bn[:6], cn[:6] = B, c
    x_ref, P_ref = textbook(F, Bn, cn, np.diag(q), xs[0], Ps[0], u, z)
    np.testing.assert_allclose(np.array(xs), x_ref, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.array(Ps), P_ref, rtol=0, atol=1e-9)
    assert np.abs(x_ref[-50:, :3] - x_true[-50:, :3]).mean() < 0.5  # and it tracks


def _converged_filter(frames=100):
    model = linear_plugin.LinearSwimmer()
    ekf = MultiStepEKF(model, DT, Q6, R, np.concatenate([R, [400.0] * 3]), gate=21.1, max_rejects=3)
    x_true, u, z = simulate(frames + 80, seed=3)
    ekf.start(z[0])
    for k in range(frames):
        ekf.predict(u[k])
        ekf.update(z[k + 1])
    return ekf, x_true, u, z, frames


def test_a_5_mm_outlier_is_rejected_by_the_gate():
    ekf, x_true, u, z, k = _converged_filter()
    ekf.predict(u[k])
    before = ekf.x.copy()
    nu, nis, accepted = ekf.update(z[k + 1] + np.array([3.0, 4.0, 0.0]))  # 5 mm reflection
    assert not accepted and nis > 100
    assert np.linalg.norm(nu - (z[k + 1] + [3.0, 4.0, 0.0] - before[:3])) < 1e-12
    np.testing.assert_array_equal(ekf.x, before)
    ekf.predict(u[k + 1])
    _, nis, accepted = ekf.update(z[k + 2])  # the next good frame is fused as usual
    assert accepted and nis < 16


def test_repeated_rejections_reinitialise_on_the_frame():
    ekf, x_true, u, z, k = _converged_filter()
    jump = np.array([0.0, 0.0, 6.0])  # the swimmer really moved (e.g. a bump): not an outlier
    for i in range(4):
        ekf.predict(u[k + i])
        _, _, accepted = ekf.update(z[k + i + 1] + jump)
    assert accepted and np.linalg.norm(ekf.x[:3] - (z[k + 4] + jump)) < 1e-12


def test_a_long_gap_followed_by_a_frame_converges():
    ekf, x_true, u, z, k = _converged_filter(frames=50)
    gap = 50  # 1 s without frames: predictions only
    for i in range(gap):
        ekf.predict(u[k + i])
    gap_error = np.linalg.norm(ekf.x[:3] - x_true[k + gap, :3])
    sd = np.sqrt(np.diag(ekf.P)[:3])
    assert gap_error > 0.2 and np.all(sd > 5 * np.sqrt(R))  # it drifted, and knows it
    _, nis, accepted = ekf.update(z[k + gap])
    assert accepted and nis < 11.3  # consistent: within the 99 % chi-square bound
    assert np.linalg.norm(ekf.x[:3] - x_true[k + gap, :3]) < 0.4
    for i in range(gap, gap + 10):
        ekf.predict(u[k + i])
        ekf.update(z[k + i + 1])
    assert np.linalg.norm(ekf.x[:3] - x_true[k + gap + 10, :3]) < 0.3
    assert np.linalg.norm(ekf.x[3:] - x_true[k + gap + 10, 3:]) < 10.0  # mm/s, from 4 mm/s noise per step

"""The noise model's parts against hand-computed values: the drift's decay, the covariance of a state
built from two frames, the mean Jacobian, the robust second moment, the residual windows, the report."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim_plugins.estimators.noise import (
    ProcessNoise,
    drift_decay,
    frame_state_covariance,
    mean_jacobian,
    measured_residuals,
    robust_second_moment,
)


def test_drift_decay_is_exp_of_minus_dt_over_tau():
    assert drift_decay(0.02, 2.0) == pytest.approx(math.exp(-0.01), rel=1e-15)
    assert drift_decay(0.5, 0.25) == pytest.approx(math.exp(-2.0), rel=1e-15)


def test_the_covariance_of_a_state_from_two_frames():
    """x = [p_i, (p_i - p_(i-1)) / dt]: var p = r, cov(p, v) = r / dt, var v = 2 r / dt^2, axes apart."""
    P = frame_state_covariance(np.array([1.0, 2.0, 4.0]), 0.5)
    expected = np.zeros((6, 6))
    for a, r in enumerate((1.0, 2.0, 4.0)):
        expected[a, a] = r
        expected[a, 3 + a] = expected[3 + a, a] = r / 0.5
        expected[3 + a, 3 + a] = 2 * r / 0.25
    np.testing.assert_array_equal(P, expected)


class Quadratic:
    """x' = x + dt (x0^2, x1 x2, u0, 0, 0, x3): a Jacobian that depends on the state."""

    name = "quadratic"

    def jacobians(self, x, u, dt_s):
        A = np.eye(6)
        A[0, 0] += dt_s * 2 * x[0]
        A[1, 1] += dt_s * x[2]
        A[1, 2] += dt_s * x[1]
        A[5, 3] += dt_s
        return A, np.zeros((6, 3)), np.zeros(6)

    def linear_matrices(self):
        raise NotImplementedError


def test_mean_jacobian_averages_over_the_states_and_takes_a_linear_models_own():
    X = np.array([[1.0, 2.0, 3.0, 0, 0, 0], [3.0, -2.0, 1.0, 0, 0, 0]])
    U = np.zeros((2, 3))
    A = mean_jacobian(Quadratic(), X, U, 0.1)
    expected = np.eye(6)
    expected[0, 0] += 0.1 * 2 * 2.0  # mean x0 = 2
    expected[1, 1] += 0.1 * 2.0  # mean x2 = 2
    expected[1, 2] += 0.1 * 0.0  # mean x1 = 0
    expected[5, 3] += 0.1
    np.testing.assert_allclose(A, expected, rtol=1e-15)

    class Linear:
        def linear_matrices(self):
            return [[2.0] * 6] * 6, None, None

    np.testing.assert_array_equal(mean_jacobian(Linear(), X, U, 0.1), np.full((6, 6), 2.0))


def test_a_non_finite_mean_jacobian_is_refused():
    X = np.array([[np.nan, 0, 0, 0, 0, 0]])
    with pytest.raises(ValueError) as err:
        mean_jacobian(Quadratic(), X, np.zeros((1, 3)), 0.1)
    assert str(err.value) == "the model's Jacobian is not finite on the logged states"


def test_robust_second_moment_by_hand():
    """Ten points at +-1 and a pair +-e: median 0, MAD 1, so points beyond 6 x 1.4826 = 8.8956 are dropped."""
    base = [1.0, -1.0] * 5
    cols = np.column_stack([
        base + [1.0, -1.0],  # mean square 1
        base + [8.0, -8.0],  # kept: (10 + 2 x 64) / 12
        base + [9.0, -9.0],  # dropped: 1
        base[:9] + [np.nan] * 3,  # nine finite values: too few
    ])
    out = robust_second_moment(cols)
    assert out[0] == pytest.approx(1.0, rel=1e-15)
    assert out[1] == pytest.approx(138.0 / 12, rel=1e-15)
    assert out[2] == pytest.approx(1.0, rel=1e-15)
    assert np.isnan(out[3])
    far = np.array(base + [1.0, -1.0]) + 50.0  # about zero, the outliers judged about the median (50)
    assert robust_second_moment(far[:, None])[0] == pytest.approx(np.mean(far**2), rel=1e-15)
    ten = np.array(base)  # exactly ten finite values are enough
    assert robust_second_moment(ten[:, None])[0] == pytest.approx(1.0, rel=1e-15)


def test_robust_second_moment_keeps_a_point_exactly_at_six_robust_sigmas():
    at = np.array([1.0, -1.0] * 5 + [6 * 1.4826, -6 * 1.4826])
    assert robust_second_moment(at[:, None])[0] == pytest.approx(np.mean(at**2), rel=1e-15)


class Windows:
    """A dataset of ``n`` windows: window i starts at p = (i, 0, 0) at rest and stays there."""

    def __init__(self, n: int):
        self.n = n

    def window_index(self, horizon):
        return np.arange(self.n)

    def windows(self, horizon, idx):
        X0 = np.zeros((len(idx), 6))
        X0[:, 0] = idx
        P = np.repeat(X0[:, None, :3], horizon, axis=1)
        return X0, np.zeros((len(idx), horizon, 3)), P


class Still:
    """A model in which nothing moves."""

    def rollout(self, X0, U, dt_s):
        return np.repeat(X0[:, None, :], U.shape[1] + 1, axis=1)


def test_residual_windows_need_fifty_and_are_thinned_without_repeats():
    with pytest.raises(ValueError) as err:
        measured_residuals(Still(), Windows(49), 4, 0.02)
    assert str(err.value) == "only 49 4-step windows without gaps in the logs; need at least 50"
    Vp, Vv, X0, U0, n = measured_residuals(Still(), Windows(50), 4, 0.02)
    assert n == 50 and Vp.shape == (4, 3) and Vv.shape == (4, 3) and U0.shape == (50, 3)
    np.testing.assert_array_equal(Vp, 0.0)  # a perfect model: no residual at all
    _, _, X0, _, n = measured_residuals(Still(), Windows(500), 4, 0.02, max_windows=120)
    assert n == 120 and len(np.unique(X0[:, 0])) == 120 and np.all(np.diff(X0[:, 0]) > 0)  # distinct, sorted
    _, _, X0_again, _, _ = measured_residuals(Still(), Windows(500), 4, 0.02, max_windows=120)
    np.testing.assert_array_equal(X0, X0_again)  # the same windows every time
    _, _, all_of_them, _, n = measured_residuals(Still(), Windows(120), 4, 0.02, max_windows=120)
    assert n == 120 and np.array_equal(all_of_them[:, 0], np.arange(120))


def test_the_report_names_every_figure_and_rounds_the_residuals_to_the_micrometre():
    noise = ProcessNoise(q=np.array([1.0, 2.0]), drift0=np.array([0.5]), horizons=np.array([1, 5]),
                         measured_mm=np.array([[0.12345, 1.0, 2.0]]), fitted_mm=np.array([[0.98765, 0.0, 1.0]]),
                         windows=42)
    assert noise.report() == {"q": [1.0, 2.0], "drift0": [0.5], "windows": 42, "horizons": [1, 5],
                              "measured_mm": [[0.123, 1.0, 2.0]], "fitted_mm": [[0.988, 0.0, 1.0]]}

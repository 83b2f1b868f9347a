"""Noise models: R from the camera, Q fitted to multi-step residuals, the adaptive Q scale."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from cosim_plugins.estimators.ekf import MultiStepEKF
from cosim_plugins.estimators.noise import camera_variance, fit_process_noise
from cosim_plugins.identify.dataset import Dataset
from cosim_plugins.raw_log import write_log

_spec = importlib.util.spec_from_file_location("kf_linear_plugin_n", Path(__file__).with_name("linear_plugin.py"))
linear_plugin = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(linear_plugin)
DT = linear_plugin.DT


def test_camera_variance_of_two_cameras():
    r = camera_variance(0.5, 0.19)
    one = (0.5 * 0.19) ** 2 + 0.19**2 / 12
    np.testing.assert_allclose(r, [one / 2, one, one])


def swimmer_logs(folder: Path, q_true, r, n=3000, logs=4):
    """Raw logs of the linear test swimmer driven by process noise ``q_true`` (6,), frames with noise ``r``."""
    A, B, c = linear_plugin.damped_swimmer()
    rng = np.random.default_rng(5)
    paths = []
    for j in range(logs):
        t = np.arange(n) * DT
        u = np.column_stack([8 * np.cos(0.3 * t + j), 8 * np.sin(0.3 * t + j), np.sin(0.1 * t)])
        x = np.zeros((n, 6))
        for k in range(n - 1):
            x[k + 1] = A @ x[k] + B @ u[k] + c + rng.normal(0, np.sqrt(q_true))
        z = x[:, :3] + rng.normal(0, np.sqrt(r), (n, 3))
        path = folder / f"log{j}.csv"
        write_log(path, np.round(t * 1e3), u * 2 * np.pi, z * 1e-3)
        paths.append(path)
    return Dataset.from_paths(paths)


def test_q_fitted_on_multi_step_residuals_recovers_the_true_noise(tmp_path):
    q_true = np.array([0.002, 0.002, 0.002, 6.0, 6.0, 6.0])  # mm^2, (mm/s)^2 per step
    r = camera_variance(0.5, 0.19)
    data = swimmer_logs(tmp_path, q_true, r)
    fit = fit_process_noise(linear_plugin.LinearSwimmer(), data, r, DT, drift_tau_s=None, horizon=25)
    np.testing.assert_allclose(fit.q[3:], q_true[3:], rtol=0.3)  # velocity noise: what makes the drift
    assert np.all(fit.q[:3] < 0.02)
    np.testing.assert_allclose(fit.fitted_mm, fit.measured_mm, rtol=0.1)  # the line explains the data
    assert fit.measured_mm[-1].min() > 1.0  # 0.5 s ahead the prediction is mm off


def test_drift_variance_explains_a_persistent_model_error(tmp_path):
    r = camera_variance(0.5, 0.19)
    q_true = np.array([0.0, 0.0, 0.0, 0.5, 0.5, 0.5])
    data = swimmer_logs(tmp_path, q_true, r)
    model = linear_plugin.LinearSwimmer()
    model.c = model.c + np.array([0.08, 0, 0, 0, 0, 0])  # its x position runs away at 4 mm/s
    fit = fit_process_noise(model, data, r, DT, drift_tau_s=2.0, horizon=25)
    assert fit.drift0[0] > 4 * max(fit.drift0[1], 1.0)  # the x drift carries the misfit
    np.testing.assert_allclose(fit.fitted_mm[-1], fit.measured_mm[-1], rtol=0.15)


def test_adaptive_scale_repairs_a_too_small_q():
    A, B, c = linear_plugin.damped_swimmer()
    rng = np.random.default_rng(2)
    q_true = np.array([1e-3] * 3 + [9.0] * 3)
    r = camera_variance(0.5, 0.19)
    ekf = MultiStepEKF(linear_plugin.LinearSwimmer(), DT, q_true / 100, r, np.concatenate([r, [400.0] * 3]),
                       adapt_rate=0.1)
    x = np.zeros(6)
    ekf.start(x[:3] + rng.normal(0, np.sqrt(r)))
    nis = []
    for k in range(3000):
        u = np.array([8 * np.cos(0.01 * k), 8 * np.sin(0.01 * k), 0.0])
        x = A @ x + B @ u + c + rng.normal(0, np.sqrt(q_true))
        ekf.predict(u)
        if k % 5 == 4:  # a frame every 100 ms
            nis.append(ekf.update(x[:3] + rng.normal(0, np.sqrt(r)))[1])
    scale = np.exp(ekf.log_scale)
    assert 30 < scale < 300, scale
    late = np.array(nis[300:])
    assert 0.4 < np.mean(late <= 2.366) < 0.6  # chi-square(3) median
    assert np.mean(late > 7.815) < 0.1  # its 95 % quantile

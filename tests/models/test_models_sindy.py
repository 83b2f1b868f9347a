"""SINDy with control in discrete time: recovery of a known linear system, numpy library."""

from __future__ import annotations

import numpy as np
import pytest

from cosim_plugins.identify.dataset import Dataset
from cosim_plugins.models.sindy import SindyLinear, SindyNonlinear


def _linear_system_dataset(n=4000, noise=0.0, seed=0):
    """A known sparse, stable x' = A x + B u + c (swimmer-like, with a weak pull to the centre)
    driven by random commands, as a one-log Dataset."""
    rng = np.random.default_rng(seed)
    dt = 0.02
    a = np.diag([0.87, 0.85, 0.9])
    a[0, 1] = 0.03  # a cross-coupling
    b = np.diag([1.2, 1.4, 1.5])
    b[2, 0] = 0.1
    A = np.block([[0.98 * np.eye(3), dt * a], [np.zeros((3, 3)), a]])
    B = np.vstack([dt * b, b])
    c = np.array([0, 0, 0, 0, 0, -5.0])
    x = np.zeros((n, 6))
    u = rng.normal(0, 5, (n, 3))
    for i in range(n - 1):
        x[i + 1] = A @ x[i] + B @ u[i] + c
    x_obs = x + noise * rng.standard_normal(x.shape)
    ds = Dataset(dt_s=dt, p=x_obs[:, :3], x=x_obs, u=u, step_ok=np.r_[np.ones(n - 1, bool), False], logs=[])
    return ds, (A, B, c)


def test_linear_sindy_recovers_known_system():
    ds, (A, B, c) = _linear_system_dataset()
    model = SindyLinear().fit(ds)
    A_, B_, c_ = model.linear_matrices()
    np.testing.assert_allclose(A_, A, atol=1e-6)
    np.testing.assert_allclose(B_, B, atol=1e-6)
    np.testing.assert_allclose(c_, c, atol=1e-6)
    assert model.n_params == 60  # paper Table II
    assert model.n_nonzero == np.count_nonzero(A) + np.count_nonzero(B) + np.count_nonzero(c)
    x, u = ds.x[10:20], ds.u[10:20]
    np.testing.assert_allclose(model.predict(x, u, 0.02), x @ A_.T + u @ B_.T + c_, atol=1e-9)


def test_linear_sindy_with_noise_is_close():
    ds, (A, B, c) = _linear_system_dataset(n=20000, noise=1e-3, seed=1)
    A_, B_, c_ = SindyLinear().fit(ds).linear_matrices()
    np.testing.assert_allclose(B_, B, atol=2e-3)
    np.testing.assert_allclose(A_, A, atol=2e-2)


def test_nonlinear_sindy_finds_no_quadratic_terms_in_a_linear_system():
    ds, (A, B, c) = _linear_system_dataset()
    model = SindyNonlinear().fit(ds)
    assert model.n_params == 330  # paper Table II
    quadratic = model.powers_.sum(axis=1) == 2
    assert np.abs(model.coef_[:, quadratic]).max() < 1e-6
    x, u = ds.x[100:110], ds.u[100:110]
    np.testing.assert_allclose(model.predict(x, u, 0.02), ds.x[101:111], atol=1e-6)
    with pytest.raises(NotImplementedError):
        model.linear_matrices()


def test_numpy_library_matches_pysindy():
    import pysindy as ps

    rng = np.random.default_rng(2)
    z = rng.standard_normal((7, 9))
    lib = ps.PolynomialLibrary(degree=2, include_bias=True).fit(z)
    model = SindyNonlinear()
    model.powers_ = np.asarray(lib.powers_)
    model.coef_ = np.zeros((6, len(model.powers_)))
    model._prepare()
    np.testing.assert_allclose(model.library(z[:, :6], z[:, 6:]), np.asarray(lib.transform(z)), rtol=1e-12)


def test_multiple_dt_steps_and_bad_dt():
    ds, _ = _linear_system_dataset(n=500)
    model = SindyLinear().fit(ds)
    x, u = ds.x[5], ds.u[5]
    two = model.predict(model.predict(x, u, 0.02), u, 0.02)
    np.testing.assert_allclose(model.predict(x, u, 0.04), two)
    with pytest.raises(ValueError, match="not a multiple"):
        model.predict(x, u, 0.03)


def test_finite_difference_jacobians_of_a_linear_model_are_its_matrices():
    ds, _ = _linear_system_dataset(n=500)
    model = SindyLinear().fit(ds)
    A, B, c = model.linear_matrices()
    A_, B_, c_ = model.jacobians(ds.x[7], ds.u[7], 0.02)
    np.testing.assert_allclose(A_, A, atol=1e-8)
    np.testing.assert_allclose(B_, B, atol=1e-8)
    np.testing.assert_allclose(c_, c, atol=1e-6)

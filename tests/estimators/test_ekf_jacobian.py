"""The EKF's transition Jacobian against an independent finite-difference reference, for every model kind.

The reference differentiates the model one state at a time with its own
step (1e-5, against the filter's 1e-3), one-row calls of ``predict``, and
lays the derivative of next state ``i`` by state ``j`` at ``[i, j]``; a
transposed or mis-indexed Jacobian disagrees with it wherever the dynamics
are not symmetric (the position rows' ``dt`` on the velocity columns, at least).
Each kind is built with fixed, non-trivial parameters instead of fitted
ones (fitting is tested elsewhere and would take seconds to minutes).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from cosim_plugins.estimators.ekf import MultiStepEKF
from cosim_plugins.estimators.noise import drift_decay
from cosim_plugins.models.mlp import LAYERS, MLPModel
from cosim_plugins.models.physical import PhysicalModel
from cosim_plugins.models.sindy import SindyLinear, SindyNonlinear

DT = 0.02
R = np.array([0.006, 0.012, 0.012])  # mm^2
X0 = np.array([3.0, -12.0, 5.0, 4.0, -2.5, 1.5])  # [mm, mm/s]
U0 = np.array([6.0, -3.0, 2.0])  # [Hz]


def _powers(degree: int) -> np.ndarray:
    """Exponents (n_features, 9) of every monomial of x (6) and u (3) up to ``degree``, bias first."""
    rows = [np.zeros(9, dtype=np.int64)]
    for d in range(1, degree + 1):
        for combo in itertools.combinations_with_replacement(range(9), d):
            row = np.zeros(9, dtype=np.int64)
            for j in combo:
                row[j] += 1
            rows.append(row)
    return np.array(rows)


def _sindy(cls, degree: int, seed: int):
    """A SINDy model of ``degree`` near a stable swimmer: identity plus dt coupling plus small random terms."""
    rng = np.random.default_rng(seed)
    model = cls()
    model.powers_ = _powers(degree)
    coef = rng.normal(0.0, 1e-3, (6, len(model.powers_)))
    for i in range(6):  # x_i' ~ x_i, p' ~ p + dt v
        coef[i, 1 + i] += 1.0
    for i in range(3):
        coef[i, 1 + 3 + i] += DT
    model.coef_ = coef
    model.feature_names_ = [f"f{k}" for k in range(len(coef[0]))]
    model.dt_s = DT
    model._prepare()
    return model


def _mlp(seed: int):
    """A 9-10-10-6 network with random weights and a scaling of the swimmer's ranges."""
    rng = np.random.default_rng(seed)
    model = MLPModel()
    model.weights = [rng.normal(0.0, 0.6, (a, b)) for a, b in zip(LAYERS[:-1], LAYERS[1:])]
    model.biases = [rng.normal(0.0, 0.3, b) for b in LAYERS[1:]]
    model.scaling = {"in_lo": np.array([-50.0] * 3 + [-30.0] * 3 + [-15.0] * 3),
                     "in_hi": np.array([50.0] * 3 + [30.0] * 3 + [15.0] * 3),
                     "out_lo": np.array([-0.5] * 3 + [-5.0] * 3), "out_hi": np.array([0.5] * 3 + [5.0] * 3)}
    model.dt_s = DT
    model._prepare()
    return model


def _physical():
    return PhysicalModel.from_params({}, dt_s=DT)


KINDS = {
    "physical": _physical,
    "sindy-nonlinear": lambda: _sindy(SindyNonlinear, 2, 1),
    "mlp": lambda: _mlp(2),
}


def reference_jacobian(model, x: np.ndarray, u: np.ndarray, h: float = 1e-5) -> np.ndarray:
    """(6, 6) d next state / d state by central differences, one state and one 1-D predict call at a time."""
    J = np.empty((6, 6))
    for j in range(6):
        step = np.zeros(6)
        step[j] = h
        J[:, j] = (model.predict(x + step, u, DT) - model.predict(x - step, u, DT)) / (2 * h)
    return J


def _filter(model, drift: bool) -> MultiStepEKF:
    q = np.array([1e-3] * 3 + [4.0] * 3 + ([0.5] * 3 if drift else []))
    p_init = np.concatenate([R, [400.0] * 3, [25.0] * 3 if drift else []])
    return MultiStepEKF(model, DT, q, R, p_init, phi=drift_decay(DT, 2.0) if drift else None)


@pytest.mark.parametrize("kind", sorted(KINDS))
@pytest.mark.parametrize("drift", [False, True], ids=["6 states", "9 states"])
def test_the_filter_jacobian_of_a_nonlinear_model_matches_finite_differences(kind, drift):
    model = KINDS[kind]()
    ekf = _filter(model, drift)
    ekf.start(X0[:3])
    ekf.x[3:6] = X0[3:]
    ref = reference_jacobian(model, X0, U0)
    assert not np.allclose(ref, ref.T, atol=1e-3)  # asymmetric: a transposed Jacobian would show
    F, mean = ekf.jacobian(U0)
    n = 9 if drift else 6
    assert F.shape == (n, n)
    np.testing.assert_allclose(F[:6, :6], ref, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(mean, model.predict(X0, U0, DT), rtol=1e-12, atol=1e-12)
    if drift:  # p' = f_p + dt d, d' = phi d; the model's states do not depend on d
        np.testing.assert_allclose(F[:3, 6:], DT * np.eye(3), rtol=0, atol=0)
        np.testing.assert_allclose(F[3:6, 6:], 0.0, rtol=0, atol=0)
        np.testing.assert_allclose(F[6:, :6], 0.0, rtol=0, atol=0)
        np.testing.assert_allclose(F[6:, 6:], drift_decay(DT, 2.0) * np.eye(3), rtol=0, atol=0)


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_predict_propagates_the_covariance_through_that_jacobian(kind):
    """One predict: P' = F P F' + Q with the reference F, and the mean through the model itself."""
    model = KINDS[kind]()
    ekf = _filter(model, drift=False)
    ekf.start(X0[:3])
    ekf.x[3:6] = X0[3:]
    P0 = ekf.P.copy()
    ekf.predict(U0)
    F = reference_jacobian(model, X0, U0)
    np.testing.assert_allclose(ekf.P, F @ P0 @ F.T + np.diag(ekf.q), rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(ekf.x, model.predict(X0, U0, DT), rtol=1e-12, atol=1e-12)


def test_a_linear_model_kind_uses_its_exact_matrices_which_match_finite_differences():
    """sindy-linear: the filter holds A from linear_matrices(); differentiating predict gives the same A."""
    model = _sindy(SindyLinear, 1, 3)
    ekf = _filter(model, drift=False)
    ref = reference_jacobian(model, X0, U0)
    assert not np.allclose(ref, ref.T, atol=1e-3)
    np.testing.assert_allclose(ekf._fixed_F, ref, rtol=1e-6, atol=1e-8)
    ekf.start(X0[:3])
    ekf.x[3:6] = X0[3:]
    P0 = ekf.P.copy()
    ekf.predict(U0)
    np.testing.assert_allclose(ekf.P, ref @ P0 @ ref.T + np.diag(ekf.q), rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(ekf.x, model.predict(X0, U0, DT), rtol=1e-12, atol=1e-9)


def test_every_registered_model_kind_is_covered():
    from cosim.contract import plugins

    registered = set(plugins.registry("model"))
    assert registered == set(KINDS) | {"sindy-linear"}, registered

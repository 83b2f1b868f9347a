"""The EKF's parts one by one: the 3 x 3 inverse, a linear model's composed step, the checks of its
arguments, the fallbacks (non-finite Jacobian, a prediction out of the tank, the speed limit), the
gate at its exact threshold, the rejections before a reset, the adaptive noise scale, snapshots."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from cosim_plugins.estimators.ekf import E_LOG_CHI2_3, MultiStepEKF, _inv3, linear_step

_spec = importlib.util.spec_from_file_location("kf_linear_plugin_parts", Path(__file__).with_name("linear_plugin.py"))
linear_plugin = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(linear_plugin)

DT = 0.02
R = np.array([0.006, 0.012, 0.012])  # mm^2
Q6 = np.array([1e-3, 1e-3, 1e-3, 4.0, 4.0, 4.0])
P_INIT = np.concatenate([R, [400.0] * 3])


class Scripted:
    """A nonlinear model whose one-row prediction is set by the test (``next``); batched calls
    (the Jacobian's) answer ``x + dt * 0.5 * x`` per row unless ``nan_batch``. Counts batched calls."""

    name, dt_s = "scripted", None

    def __init__(self):
        self.next = None
        self.nan_batch = False
        self.batches = 0

    def predict(self, x, u, dt_s):
        x = np.asarray(x, dtype=float)
        if x.ndim == 2:
            self.batches += 1
            out = x + dt_s * 0.5 * x
            if self.nan_batch:
                out[1:] = np.nan
            return out
        return np.array(self.next, dtype=float)

    def linear_matrices(self):
        raise NotImplementedError


def _started(model, x0, **kw) -> MultiStepEKF:
    ekf = MultiStepEKF(model, DT, Q6, R, P_INIT, **kw)
    ekf.start(np.asarray(x0[:3], dtype=float))
    ekf.x[3:6] = x0[3:]
    return ekf


def test_inv3_inverts_a_full_symmetric_positive_definite_matrix():
    rng = np.random.default_rng(5)
    for _ in range(5):
        m = rng.normal(size=(3, 3))
        S = m @ m.T + 0.5 * np.eye(3)
        np.testing.assert_allclose(_inv3(S), np.linalg.inv(S), rtol=1e-10, atol=1e-12)


class Halved(linear_plugin.LinearSwimmer):
    """The test swimmer stepping 10 ms at a time."""

    def __init__(self, dt_s):
        super().__init__()
        self.dt_s = dt_s


def test_a_linear_model_with_a_shorter_step_is_composed_over_the_period():
    model = Halved(0.01)
    A, B, c = model.linear_matrices()
    Ak, Bk, ck = linear_step(model, 0.02)
    np.testing.assert_allclose(Ak, A @ A, rtol=1e-15)
    np.testing.assert_allclose(Bk, A @ B + B, rtol=1e-15)
    np.testing.assert_allclose(ck, A @ c + c, rtol=1e-15)
    no_step = Halved(None)  # a model without its own step: one step per period
    np.testing.assert_allclose(linear_step(no_step, 0.02)[0], A, rtol=0)


@pytest.mark.parametrize("step_s, message", [
    (0.015, "the model steps 15 ms; the period 20 ms is not a multiple"),
    (0.03, "the model steps 30 ms; the period 20 ms is not a multiple"),
    (0.0199, "the model steps 19.9 ms; the period 20 ms is not a multiple"),
])
def test_a_period_that_is_not_a_multiple_of_the_models_step_is_refused(step_s, message):
    with pytest.raises(ValueError) as err:
        linear_step(Halved(step_s), 0.02)
    assert str(err.value) == message


@pytest.mark.parametrize("q, phi, message", [
    (np.ones(7), None, "process noise has 7 entries; expected 6 (p, v) or 9 (p, v, drift)"),
    (np.ones(9), None, "a drift state needs its decay phi"),
])
def test_bad_filter_arguments_are_named(q, phi, message):
    with pytest.raises(ValueError) as err:
        MultiStepEKF(linear_plugin.LinearSwimmer(), DT, q, R, np.ones(len(q)), phi=phi)
    assert str(err.value) == message


def test_a_decay_given_without_drift_states_is_ignored():
    ekf = MultiStepEKF(linear_plugin.LinearSwimmer(), DT, Q6, R, P_INIT, phi=0.9)
    assert ekf.phi is None and ekf._F.shape == (6, 6)


def test_a_filter_is_unstarted_until_its_first_frame():
    ekf = MultiStepEKF(linear_plugin.LinearSwimmer(), DT, Q6, R, P_INIT)
    assert ekf.started is False and np.isnan(ekf.x).all() and np.isnan(ekf.P).all()
    assert ekf.rejects == 0 and ekf.log_scale == 0.0
    ekf.start(np.array([1.0, 2.0, 3.0]))
    assert ekf.started is True and ekf.rejects == 0
    np.testing.assert_array_equal(ekf.x, [1.0, 2.0, 3.0, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(ekf.P, np.diag(P_INIT))


def test_a_non_finite_jacobian_falls_back_to_constant_velocity():
    model = Scripted()
    model.nan_batch = True
    ekf = _started(model, [0.0, 0.0, 0.0, 1.0, 2.0, 3.0])
    F, _ = ekf.jacobian(np.zeros(3))
    expected = np.eye(6)
    expected[:3, 3:] = DT * np.eye(3)
    np.testing.assert_array_equal(F, expected)


@pytest.mark.parametrize("every", [1, 3])
def test_the_jacobian_is_refreshed_every_relinearize_steps_predictions(every):
    model = Scripted()
    model.next = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]
    ekf = _started(model, [0.0, 0.0, 0.0, 1.0, 1.0, 1.0], **({} if every == 1 else {"relinearize_steps": every}))
    for _ in range(7):
        ekf.predict(np.zeros(3))
    assert model.batches == math.ceil(7 / every)  # predictions 1, 4, 7 (every 3) or each one


@pytest.mark.parametrize("bad", ["nan_px", "nan_py", "nan_pz", "nan_vx", "nan_vy", "nan_vz",
                                 "out_x", "out_y", "out_z"])
def test_a_prediction_out_of_the_tank_or_not_finite_is_a_constant_velocity_step(bad):
    x0 = np.array([1.0, -2.0, 3.0, 10.0, -20.0, 30.0])
    nxt = [1.5, -2.5, 3.5, 11.0, -21.0, 31.0]
    kind, what = bad.split("_")
    axis = "xyz".index(what[-1]) + (3 if what.startswith("v") else 0)
    nxt[axis] = math.nan if kind == "nan" else 80.0 * (1 if axis != 1 else -1)
    model = Scripted()
    model.next = nxt
    ekf = _started(model, x0, tank=75.0, relinearize_steps=1000)
    ekf._F, ekf._since = np.eye(6), 0  # keep the held Jacobian: the one-row prediction is used
    ekf.predict(np.zeros(3))
    np.testing.assert_allclose(ekf.x, np.concatenate([x0[:3] + DT * x0[3:], x0[3:]]), rtol=1e-15)


def test_a_prediction_inside_the_tank_is_kept_and_the_speed_limited_along_its_direction():
    model = Scripted()
    model.next = [74.0, -74.0, 74.0, 30.0, -40.0, 120.0]  # 130 mm/s
    ekf = _started(model, np.zeros(6), tank=75.0, v_max=65.0, relinearize_steps=1000)
    ekf._F, ekf._since = np.eye(6), 0
    ekf.predict(np.zeros(3))
    np.testing.assert_allclose(ekf.x, [74.0, -74.0, 74.0, 15.0, -20.0, 60.0], rtol=1e-14)
    model.next = [0.0, 0.0, 0.0, 3.0, 4.0, 12.0]  # 13 mm/s: within
    ekf.predict(np.zeros(3))
    np.testing.assert_allclose(ekf.x[3:], [3.0, 4.0, 12.0], rtol=0)


def test_the_gate_accepts_a_frame_exactly_at_its_threshold():
    x0 = np.array([1.0, 2.0, 3.0, 0.0, 0.0, 0.0])
    z = np.array([1.3, 1.8, 3.1])
    probe = _started(linear_plugin.LinearSwimmer(), x0)
    _, _, nis = probe.innovation(z)
    at = _started(linear_plugin.LinearSwimmer(), x0, gate=nis)
    assert at.update(z)[2] is True
    above = _started(linear_plugin.LinearSwimmer(), x0, gate=nis * (1 - 1e-9))
    assert above.update(z)[2] is False


def test_three_rejections_then_a_reset_on_the_frame_by_default():
    x0 = np.array([1.0, 2.0, 3.0, 5.0, 0.0, 0.0])
    ekf = _started(linear_plugin.LinearSwimmer(), x0, gate=11.3)
    far = np.array([30.0, 2.0, 3.0])
    assert [ekf.update(far)[2] for _ in range(3)] == [False, False, False] and ekf.rejects == 3
    ekf.P[:3, :3] += 0.5  # what the covariance said before the reset is forgotten
    assert ekf.update(far)[2] is True  # the fourth: the filter was lost
    np.testing.assert_array_equal(ekf.x[:3], far)
    assert ekf.x[3] == 5.0  # velocity kept
    np.testing.assert_array_equal(ekf.P, np.diag(P_INIT))
    assert ekf.rejects == 0 and ekf._since == ekf.relinearize_steps
    assert [ekf.update(np.array([90.0, 2.0, 3.0]))[2] for _ in range(4)] == [False, False, False, True]


def test_the_adaptive_scale_follows_log_nis_and_stays_in_its_range():
    x0 = np.array([1.0, 2.0, 3.0, 0.0, 0.0, 0.0])
    z = np.array([1.2, 1.9, 3.05])
    ekf = _started(linear_plugin.LinearSwimmer(), x0, adapt_rate=0.1)
    _, _, nis = ekf.innovation(z)
    ekf.update(z)
    assert ekf.log_scale == pytest.approx(0.1 * (math.log(nis) - E_LOG_CHI2_3), rel=1e-12)
    np.testing.assert_allclose(ekf._Qd, math.exp(ekf.log_scale) * np.diag(Q6), rtol=1e-12)
    exact = _started(linear_plugin.LinearSwimmer(), x0, adapt_rate=0.1)
    exact.update(x0[:3].copy())  # NIS 0: log of the floor 1e-6
    assert exact.log_scale == pytest.approx(0.1 * (math.log(1e-6) - E_LOG_CHI2_3), rel=1e-12)  # within 0.1..100
    low = _started(linear_plugin.LinearSwimmer(), x0, adapt_rate=1.0, scale_range=(0.2, 50.0))
    for _ in range(20):
        low.update(low.x[:3].copy())
    assert low.log_scale == pytest.approx(math.log(0.2), rel=1e-12)
    fixed = _started(linear_plugin.LinearSwimmer(), x0)  # adapt_rate 0: Q as given
    fixed.update(z)
    assert fixed.log_scale == 0.0
    np.testing.assert_array_equal(fixed._Qd, np.diag(Q6))


def test_restore_returns_to_the_snapshot_exactly():
    model = Scripted()
    model.next = [0.5, 0.5, 0.5, 1.0, 1.0, 1.0]
    ekf = _started(model, [0.0, 0.0, 0.0, 1.0, 1.0, 1.0], relinearize_steps=3, adapt_rate=0.2)
    ekf.predict(np.zeros(3))
    snap = ekf.snapshot()
    x, P = ekf.x.copy(), ekf.P.copy()
    ekf.update(np.array([0.6, 0.4, 0.5]))
    ekf.predict(np.zeros(3))
    ekf.restore(snap)
    np.testing.assert_array_equal(ekf.x, x)
    np.testing.assert_array_equal(ekf.P, P)
    assert ekf._since == 1 and ekf.log_scale == 0.0 and ekf.rejects == 0
    ekf.x[0] = 99.0  # the snapshot is a copy
    ekf.restore(snap)
    assert ekf.x[0] == x[0]


@pytest.mark.parametrize("drift", [False, True], ids=["6 states", "9 states"])
def test_between_refreshes_the_mean_goes_through_the_model(drift):
    """With the Jacobian held (relinearize_steps 3) each prediction is still the model's own."""
    from cosim_plugins.estimators.noise import drift_decay
    from cosim_plugins.models.physical import PhysicalModel

    model = PhysicalModel.from_params({}, dt_s=DT)
    q = np.concatenate([Q6, [0.5] * 3]) if drift else Q6
    p_init = np.concatenate([P_INIT, [25.0] * 3]) if drift else P_INIT
    phi = drift_decay(DT, 2.0) if drift else None
    ekf = MultiStepEKF(model, DT, q, R, p_init, phi=phi, relinearize_steps=3)
    ekf.start(np.array([3.0, -12.0, 5.0]))
    ekf.x[3:6] = [4.0, -2.5, 1.5]
    u = np.array([6.0, -3.0, 2.0])
    for _ in range(4):
        before = ekf.x.copy()
        ekf.predict(u)
        expected = model.predict(before[:6], u, DT)
        if drift:
            expected[:3] += DT * before[6:]
        np.testing.assert_allclose(ekf.x[:6], expected, rtol=1e-12, atol=1e-12)


def test_the_constant_velocity_fallback_with_a_drift_state():
    model = Scripted()
    model.next = [math.nan] * 6
    x0 = np.array([1.0, -2.0, 3.0, 10.0, -20.0, 30.0, 0.5, 0.25, 0.0])
    ekf = MultiStepEKF(model, DT, np.concatenate([Q6, [0.5] * 3]), R, np.concatenate([P_INIT, [25.0] * 3]),
                       phi=0.9, relinearize_steps=1000)
    ekf.start(x0[:3])
    ekf.x[:] = x0
    ekf._F, ekf._since = np.eye(9), 0
    ekf.predict(np.zeros(3))
    expected = np.concatenate([x0[:3] + DT * x0[3:6] + DT * x0[6:], x0[3:6], 0.9 * x0[6:]])
    np.testing.assert_allclose(ekf.x, expected, rtol=1e-15)


def test_a_prediction_on_the_tank_wall_is_kept():
    model = Scripted()
    model.next = [75.0, -75.0, 0.0, 1.0, 1.0, 1.0]
    ekf = _started(model, np.zeros(6), tank=75.0, relinearize_steps=1000)
    ekf._F, ekf._since = np.eye(6), 0
    ekf.predict(np.zeros(3))
    np.testing.assert_array_equal(ekf.x, model.next)


def test_integer_initial_variances_still_give_the_cameras_variance_on_the_position():
    ekf = MultiStepEKF(linear_plugin.LinearSwimmer(), DT, Q6, R, [1, 1, 1, 400, 400, 400])
    ekf.start(np.zeros(3))
    np.testing.assert_array_equal(np.diag(ekf.P), np.concatenate([R, [400.0] * 3]))


@pytest.mark.parametrize("huge", [(3, 4), (4, 5), (3, 5)], ids=["vx vy", "vy vz", "vx vz"])
def test_a_diverging_prediction_whose_sum_overflows_is_a_constant_velocity_step(huge):
    """Two velocities of 1e308 mm/s, each finite, sum to inf: the model left its domain as surely as with a NaN,
    and the step goes on at constant velocity (not through the speed limit, which would zero the velocity)."""
    x0 = np.array([1.0, -2.0, 3.0, 10.0, -20.0, 30.0])
    nxt = [1.5, -2.5, 3.5, 11.0, -21.0, 31.0]
    for axis in huge:
        nxt[axis] = 1e308
    model = Scripted()
    model.next = nxt
    ekf = _started(model, x0, tank=75.0, v_max=65.0, relinearize_steps=1000)
    ekf._F, ekf._since = np.eye(6), 0
    ekf.predict(np.zeros(3))
    np.testing.assert_allclose(ekf.x, np.concatenate([x0[:3] + DT * x0[3:], x0[3:]]), rtol=1e-15)

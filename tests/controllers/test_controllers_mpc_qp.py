"""The MPC's QP (Eq. 15): fast path vs the cvxpy formulation, bounds, convergence on a known system."""

from __future__ import annotations

import numpy as np
import pytest

from cosim_plugins.controllers.mpc_qp import CondensedMPC, CvxpyMPC, MPCSpec, clip_first

DT = 0.02


def swimmer_like(tau_s=0.15, mm_s_per_hz=2.5, sink_mm_s=0.0):
    """Exact discretisation of dp/dt = v, dv/dt = (b u - v)/tau + w: (A (6, 6), B (6, 3), c (6,))."""
    a = np.exp(-DT / tau_s)
    A = np.eye(6)
    A[:3, 3:] = np.eye(3) * tau_s * (1 - a)
    A[3:, 3:] = np.eye(3) * a
    B = np.zeros((6, 3))
    B[:3] = np.eye(3) * mm_s_per_hz * (DT - tau_s * (1 - a))
    B[3:] = np.eye(3) * mm_s_per_hz * (1 - a)
    w = np.array([0.0, 0.0, -sink_mm_s])  # a constant velocity offset (sinking) [mm/s]
    c = np.concatenate([w * (DT - tau_s * (1 - a)), w * (1 - a)])
    return A, B, c


def random_problem(rng, horizon=5):
    x0 = np.concatenate([rng.normal(0, 20, 3), rng.normal(0, 15, 3)])
    ref = x0[:3] + np.cumsum(rng.normal(0, 3, (horizon, 3)), axis=0) + rng.normal(0, 5, 3)
    return x0, ref, rng.uniform(-1, 1, 3)


def test_cvxpy_formulation_is_dpp():
    assert CvxpyMPC(MPCSpec(*swimmer_like())).is_dpp()


def test_fast_path_agrees_with_cvxpy_formulation():
    import cvxpy as cp

    A, B, c = swimmer_like(sink_mm_s=3.5)
    A[:3, :3] += 1e-3 * np.random.default_rng(0).normal(size=(3, 3))  # not diagonal: couples the axes
    spec = MPCSpec(A, B, c, horizon=5, q=(3, 2, 4), r=(1, 0.5, 2), ru=(1, 1, 0.3), eps=1e-7, max_iter=20000)
    fast, ref = CondensedMPC(spec), CvxpyMPC(spec, solver_opts={"solver": cp.CLARABEL})
    rng = np.random.default_rng(1)
    active = 0
    for _ in range(40):
        x0, r, u_prev = random_problem(rng)
        a, b = fast.solve(x0, r, u_prev), ref.solve(x0, r, u_prev)
        assert a is not None and b is not None
        np.testing.assert_allclose(a[0], b[0], atol=1e-4)  # the applied command
        np.testing.assert_allclose(a, b, atol=3e-3)  # late commands barely move p_N: loosely determined
        active += np.any(np.abs(b) > 1 - 1e-6) or np.any(np.abs(np.diff(np.vstack([u_prev, b]), axis=0)) > 1 - 1e-6)
    assert active >= 5  # the comparison covered saturated plans too


def test_first_command_is_inside_the_bounds_even_from_an_unconverged_solve():
    rng = np.random.default_rng(2)
    spec = MPCSpec(*swimmer_like(), u_max=0.8, du_max=0.3, max_iter=1)  # one OSQP iteration: not converged
    qp = CondensedMPC(spec)
    for _ in range(100):
        x0, r, u_prev = random_problem(rng)
        u_prev = np.clip(u_prev, -0.8, 0.8)
        plan = qp.solve(x0, r * 3, u_prev)
        u0 = clip_first(plan[0] if plan is not None else np.zeros(3), u_prev, 0.8, 0.3)
        assert np.all(np.abs(u0) <= 0.8) and np.all(np.abs(u0 - u_prev) <= 0.3 + 1e-12)


@pytest.mark.parametrize("sink_mm_s, ru", [(0.0, (1.0, 1.0, 1.0)), (3.5, (0.0, 0.0, 0.0))])
def test_drives_a_known_linear_system_to_the_reference(sink_mm_s, ru):
    """Closed loop on the model itself: the position settles on a fixed reference [mm]
    (with a drift the command must hold against it, so Ru = 0 there: no command penalty)."""
    A, B, c = swimmer_like(sink_mm_s=sink_mm_s)
    spec = MPCSpec(A, B, c, horizon=5, ru=ru, f_max_hz=20.0, eps=1e-6, max_iter=4000)
    qp = CondensedMPC(spec)
    target = np.array([10.0, -5.0, 3.0])
    x, u_prev = np.zeros(6), np.zeros(3)
    for _ in range(250):  # 5 s
        plan = qp.solve(x, np.tile(target, (5, 1)), u_prev)
        u_prev = clip_first(plan[0], u_prev, 1.0, 1.0)
        x = A @ x + B @ (20.0 * u_prev) + c
    assert np.linalg.norm(x[:3] - target) < 0.05
    assert np.linalg.norm(x[3:]) < 0.05


@pytest.mark.parametrize("backend", [CondensedMPC, CvxpyMPC])
def test_non_finite_data_gives_no_plan_and_does_not_poison_the_next_solve(backend):
    qp = backend(MPCSpec(*swimmer_like()))
    target = np.tile([1.0, 2.0, 3.0], (5, 1))
    good = qp.solve(np.zeros(6), target, np.zeros(3))
    assert qp.solve(np.full(6, np.nan), target, np.zeros(3)) is None
    np.testing.assert_allclose(qp.solve(np.zeros(6), target, np.zeros(3)), good, atol=1e-3)

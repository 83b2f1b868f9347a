"""The physical model: integration, parameter recovery, extra force terms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.contract.errors import UserError
from cosim_plugins.identify import synthetic as syn
from cosim_plugins.identify.model import load_model
from cosim_plugins.identify.terms import EffectParam, ForceTerm, quadratic_drag
from cosim_plugins.models.physical import PhysicalModel, forces, synthetic_plant


def _random_states(n, seed=0):
    rng = np.random.default_rng(seed)
    x = np.column_stack([rng.uniform(-50, 50, (n, 3)), rng.normal(0, 20, (n, 3))])
    return x, rng.normal(0, 10, (n, 3))


def test_predict_single_matches_batch_and_special_cases():
    model = synthetic_plant(richer=False)
    x, u = _random_states(6)
    u[0] = 0.0  # no command: alpha undefined, no lift
    x[1, 3:] = 0.0  # at rest
    x[2, :3] = 0.0  # at the centre: no centripetal direction
    batch = model.predict(x, u, 0.02)
    single = np.array([model.predict(x[i], u[i], 0.02) for i in range(len(x))])
    np.testing.assert_allclose(single, batch, rtol=1e-12, atol=1e-12)
    assert np.all(np.isfinite(batch))
    # the backward-difference velocity of the model's own step is its new velocity
    np.testing.assert_allclose((batch[:, :3] - x[:, :3]) / 0.02, batch[:, 3:], rtol=1e-10)


def test_acceleration_matches_the_force_equations():
    model = synthetic_plant(richer=False)
    x, u = _random_states(50, seed=1)
    dt = 1e-7
    acc = (model.predict(x, u, dt)[:, 3:] - x[:, 3:]) / dt
    f = forces(x[:, :3], x[:, 3:], u, syn.TRUE_PARAMS)
    np.testing.assert_allclose(acc, 1000.0 * f / 12.4, rtol=1e-4, atol=1e-3)


def test_a_uniform_flow_gives_the_forces_at_the_velocity_relative_to_the_water():
    """The library's background flow w: drag and lift act on v - w, so the model's forces with it are its forces
    at v - w (the centring force and the net weight do not depend on v); with no angle terms it is +Cd1 w."""
    from cosim_plugins.identify.effect import resolve

    (flow,) = resolve(["background_flow"])
    x, u = _random_states(40, seed=2)
    w = np.array([2.5, -1.5, 0.0])
    params = {**syn.TRUE_PARAMS, "background_flow.w_x": w[0], "background_flow.w_y": w[1]}
    assert params["Cd0"] > 0 and params["Cl0"] != 0  # the angle terms matter here
    p, v = x[:, :3], x[:, 3:]
    np.testing.assert_allclose(forces(p, v, u, params, terms=[flow]), forces(p, v - w, u, syn.TRUE_PARAMS),
                               rtol=1e-10, atol=1e-12)
    linear = {**params, "Cd0": 0.0, "Cl0": 0.0}
    extra = forces(p, v, u, linear, terms=[flow]) - forces(p, v, u, linear)
    np.testing.assert_allclose(extra, np.broadcast_to(linear["Cd1"] * w, extra.shape), rtol=1e-12)


def test_beside_a_flow_every_drag_acts_on_the_velocity_relative_to_the_water():
    """A swimmer drifting with the water feels no drag: with a uniform flow w in the model, the wall, anisotropic
    and quadratic drags act on v - w as the host's drag does: in the force law, in the model's step and in a batch
    of parameter groups (a fit's Jacobian columns), where each group's drags follow its own flow."""
    from cosim_plugins.identify.effect import resolve

    effects = resolve(["background_flow", "wall_drag", "anisotropic_drag", "quadratic_drag"])
    x, u = _random_states(40, seed=4)
    p, v = x[:, :3], x[:, 3:]
    w = np.array([3.0, -2.0, 0.0])
    still = {**syn.TRUE_PARAMS, "wall_drag.c": 1.5, "wall_drag.ell": 8.0, "anisotropic_drag.c": 0.4,
             "quadratic_drag.c": 0.01}
    moving = {**still, "background_flow.w_x": w[0], "background_flow.w_y": w[1]}
    np.testing.assert_allclose(forces(p, v, u, moving, terms=effects), forces(p, v - w, u, still, terms=effects[1:]),
                               rtol=1e-10, atol=1e-12)
    model = PhysicalModel.from_params(moving, terms=effects)
    dt = 1e-7
    acc = (model.predict(x, u, dt)[:, 3:] - v) / dt
    np.testing.assert_allclose(acc, 1000.0 * forces(p, v, u, moving, terms=effects) / 12.4, rtol=1e-4, atol=1e-3)
    names = list(model.params())
    theta = np.array([model.params()[n] for n in names])
    calm = theta.copy()
    calm[names.index("background_flow.w_x")] = calm[names.index("background_flow.w_y")] = 0.0
    model.set_groups(np.stack([theta, calm]), len(x))
    try:
        both = model.predict_t(np.concatenate([x, x]).T.copy(), np.concatenate([u, u]).T.copy(), dt)
    finally:
        model.set_groups(None)
    acc_groups = (both[3:].T - np.concatenate([v, v])) / dt
    expected = np.concatenate([forces(p, v, u, moving, terms=effects), forces(p, v, u, still, terms=effects[1:])])
    np.testing.assert_allclose(acc_groups, 1000.0 * expected / 12.4, rtol=1e-4, atol=1e-3)


def test_stiff_drag_is_stable():
    model = PhysicalModel.from_params({"k": 100.0, "Cd1": 100.0, "Cd0": 0.0})  # lambda dt ~ 1.6e5
    x = np.array([[0.0, 0.0, 0.0, 500.0, 0.0, 0.0]])
    u = np.array([[2.0, 0.0, 0.0]])
    traj = model.rollout(x, u[:, None].repeat(10, axis=1), 0.02)
    assert np.all(np.isfinite(traj))
    np.testing.assert_allclose(traj[0, -1, 3:], [2.0, 0.0, 0.0], atol=1e-6)  # terminal velocity k u / Cd1


def test_stiff_quadratic_drag_term_is_stable_and_exact_for_small_steps():
    """A term's drag joins the exact decay: a quadratic drag whose explicit step would overshoot
    (c |v| dt / m ~ 50: the speed would flip sign and grow) slows the swimmer without reversing it and
    settles at its terminal speed; for tiny steps the acceleration is still the force law's."""
    model = PhysicalModel.from_params({"k": 0.1, "Cd1": 0.05, "Cd0": 0.0, "quadratic_drag.c": 0.05},
                                      terms=[quadratic_drag()])
    x = np.array([[0.0, 0.0, 0.0, 600.0, 0.0, 0.0]])
    u = np.array([[10.0, 0.0, 0.0]])
    traj = model.rollout(x, u[:, None].repeat(200, axis=1), 0.02)
    speed = traj[0, :, 3]
    assert np.all(np.isfinite(traj)) and np.all((speed >= 0.0) & (speed <= 600.0))
    # terminal speed: k u = Cd1 v + c v^2
    v_end = (-0.05 + math.sqrt(0.05**2 + 4 * 0.05 * 0.1 * 10.0)) / (2 * 0.05)
    assert speed[-1] == pytest.approx(v_end, rel=1e-6)
    xs, us = _random_states(40, seed=3)
    dt = 1e-7
    acc = (model.predict(xs, us, dt)[:, 3:] - xs[:, 3:]) / dt
    f = forces(xs[:, :3], xs[:, 3:], us, model.params(), terms=model.terms)
    np.testing.assert_allclose(acc, 1000.0 * f / 12.4, rtol=1e-4, atol=1e-3)


def test_fit_recovers_known_parameters(make_dataset, tmp_path):
    """Data made by the physical model itself (camera noise 0.03 mm, gaps, outliers, repeats)."""
    plant = synthetic_plant(richer=False)
    ds = make_dataset(tmp_path, plant.predict, 1500, seed=5, noise_mm=0.03)
    model = PhysicalModel(max_windows=1500).fit(ds)
    for name, true in syn.TRUE_PARAMS.items():
        assert model.params()[name] == pytest.approx(true, rel=0.05), name
    assert model.n_params == 6
    assert model.train_time_s > 0


def test_extra_term_is_fitted_jointly(make_dataset, tmp_path):
    truth = {**syn.TRUE_PARAMS, "quadratic_drag.c": 0.0015}
    plant = PhysicalModel.from_params(truth, terms=[quadratic_drag()])
    ds = make_dataset(tmp_path, plant.predict, 1000, seed=6, noise_mm=0.03)
    model = PhysicalModel(max_windows=1500, terms=[quadratic_drag(init=0.001)]).fit(ds)
    assert model.n_params == 7
    assert model.params()["quadratic_drag.c"] == pytest.approx(0.0015, rel=0.1)
    assert model.params()["Cd1"] == pytest.approx(truth["Cd1"], rel=0.05)


def test_custom_term_and_unregistered_term_on_load(tmp_path):
    push = ForceTerm("push", (EffectParam("fx", 0.2, -1.0, 1.0, "uN"),),
                     lambda p, v, u, prm: np.broadcast_to([prm["fx"], 0.0, 0.0], p.shape))
    model = PhysicalModel.from_params({**syn.TRUE_PARAMS, "push.fx": 0.5}, terms=[push])
    assert "push.fx" in model.params()
    x, u = _random_states(3)
    moved = model.predict(x, u, 0.02)
    model.set_params({"push.fx": 0.0})
    assert np.all(moved[:, 3] > model.predict(x, u, 0.02)[:, 3])
    model.save(tmp_path / "m.npz")
    with pytest.raises(UserError, match="the model uses effect 'push', which is not registered"):
        load_model(tmp_path / "m.npz")
    with pytest.raises(ValueError, match="unknown physical parameters"):
        model.set_params({"nope": 1.0})


def test_the_angle_terms_follow_their_definition():
    """geometry (compiled, column by column) against Eq. 2-6 written out: alpha the angle between v and omega,
    v_perp the unit vector normal to v in their plane towards omega, c_hat = -p / |p|."""
    from cosim_plugins.models.physical import geometry

    x, u = _random_states(200, seed=4)
    p, v = x[:, :3], x[:, 3:]
    sin_a, lift, cent = geometry(p, v, u, 70 * math.sqrt(3))
    vh = v / np.linalg.norm(v, axis=1, keepdims=True)
    wh = u / np.linalg.norm(u, axis=1, keepdims=True)
    alpha = np.arccos(np.clip(np.sum(vh * wh, axis=1), -1, 1))
    normal = wh - np.sum(vh * wh, axis=1, keepdims=True) * vh
    v_perp = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    np.testing.assert_allclose(sin_a, np.sin(alpha), atol=1e-12)
    np.testing.assert_allclose(lift, (np.sin(2 * alpha) * np.linalg.norm(v, axis=1))[:, None] * v_perp,
                               rtol=1e-9, atol=1e-9)
    pn = np.linalg.norm(p, axis=1, keepdims=True)
    np.testing.assert_allclose(cent, np.sin(np.pi * pn / (70 * math.sqrt(3))) * (-p / pn), atol=1e-12)
    # without a command or a velocity there is no angle: no lift, no angle drag
    zero = geometry(p[:2], np.array([[0.0, 0, 0], [1, 2, 3]]), np.array([[1.0, 0, 0], [0, 0, 0]]), 120.0)
    assert np.all(zero[0] == 0) and np.all(zero[1] == 0)


def test_fast_single_step():
    import time

    model = synthetic_plant(richer=False)
    x, u = _random_states(1)
    x, u = x[0], u[0]
    t0 = time.perf_counter()
    for _ in range(2000):
        model.predict(x, u, 0.02)
    per_call = (time.perf_counter() - t0) / 2000
    assert per_call < 200e-6  # budget 50 us; loose here because CI machines are shared
    assert math.isfinite(per_call)


def _held_truth(lam_per_s, acc, dt_s):
    """Exact positions (n + 1, 3) [mm] of v' = -lam v + a_i on [t_i, t_i+1) from rest at 0 (a (n, 3) mm/s^2)."""
    e = math.exp(-lam_per_s * dt_s)
    q = (1.0 - e) / lam_per_s
    r = (dt_s - q) / lam_per_s
    p, v, out = np.zeros(3), np.zeros(3), [np.zeros(3)]
    for a in acc:
        p, v = p + q * v + r * a, e * v + q * a
        out.append(p)
    return np.array(out)


def test_exact_hold_steps_step_mean_velocities_exactly():
    """Linear drag, a command held over each step: hold="exact" reproduces the continuous-time positions;
    the paper's scheme leads them by about half a step wherever the command changes."""
    prm = {"k": 0.6, "Cd1": 0.15}  # lambda = 1000 Cd1 / m = 12.1 /s
    lam, dt = 1000.0 * 0.15 / 12.4, 0.02
    U = np.random.default_rng(3).normal(0.0, 8.0, (300, 3))
    truth = _held_truth(lam, 1000.0 * 0.6 / 12.4 * U, dt)
    errors = {}
    for hold in ("paper", "exact"):
        model = PhysicalModel.from_params(prm, dt_s=dt, hold=hold)
        xt = np.concatenate([truth[1], (truth[1] - truth[0]) / dt])[:, None]  # a state built from data
        path = [truth[1]]
        for i in range(1, len(U)):
            xt = model.predict_t(xt, U[i][:, None], dt, U[i - 1][:, None])
            path.append(xt[:3, 0])
        errors[hold] = np.abs(np.array(path) - truth[1:]).max()
    assert errors["exact"] < 1e-9
    assert errors["paper"] > 1e-3
    with pytest.raises(ValueError, match="hold"):
        PhysicalModel(hold="midpoint")


def test_a_start_whose_rollouts_blow_up_is_passed_over(make_dataset, tmp_path):
    """A start with a negative drag overflows the windows' rollouts: the fit ranks it last (its residuals
    are DIVERGED_MM, not NaN or a singular solve) and refines the other start to the truth."""
    ds = make_dataset(tmp_path, synthetic_plant(richer=False).predict, 800, seed=6, noise_mm=0.03)
    model = PhysicalModel(max_windows=400)
    names = [p.name for p in model.all_params()]
    good = np.array([syn.TRUE_PARAMS[n] for n in names])
    bad = good.copy()
    bad[names.index("Cd1")] = -1e3  # out of bounds, the sure way to make every rollout overflow (e^1600 a step)
    model._refine(ds, [bad, good])
    assert model.fit_info["start"] == 1
    assert model.params()["Cd1"] == pytest.approx(syn.TRUE_PARAMS["Cd1"], rel=0.05)


@pytest.mark.parametrize("name", ["wall_drag", "anisotropic_drag", "quadratic_drag"])
def test_every_drag_dissipates_at_every_parameter_within_its_bounds(name):
    """A drag takes energy out of the motion through the water: F . (v - w) <= 0 for every state and for its
    parameters at their bounds and drawn between them (a fit free to make a drag push would let it stand in for
    a misfitted lift: a negative anisotropic drag was named in logs with nothing hidden)."""
    from cosim_plugins.identify.effect import resolve

    effect = resolve([name])[0]
    x, u = _random_states(200, seed=7)
    p, v = x[:, :3], x[:, 3:]
    rng = np.random.default_rng(3)
    water = {"water_x": 4.0, "water_y": -3.0}
    for draw in range(12):
        prm = {q.name: (q.lo if draw == 0 else min(q.hi, 100 * q.typical()) if draw == 1 else
                        rng.uniform(q.lo, min(q.hi, 100 * q.typical()))) for q in effect.params}
        for w in ({}, water):
            power = np.sum(effect.force(p, v, u, {**prm, **w}) * (v - [w.get("water_x", 0), w.get("water_y", 0), 0]),
                           axis=1)
            assert np.all(power <= 1e-12), (name, prm, w, power.max())

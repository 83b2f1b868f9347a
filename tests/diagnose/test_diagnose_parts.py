"""The parts: the effect library and contract, the noise estimate and floor, the split."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.contract.plugins import lookup
from cosim_plugins.diagnose.noise import noise_floor, noise_sigma_mm
from cosim_plugins.diagnose.pipeline import _floor_time_constant, velocity_time_constant
from cosim_plugins.identify import synthetic as syn
from cosim_plugins.identify.dataset import Dataset
from cosim_plugins.identify.effect import check_effect, known_effects
from cosim_plugins.identify.joint import JointModel
from cosim_plugins.identify.timeline import Timeline

LIBRARY = {"background_flow", "wall_drag", "step_out", "actuation_lag", "gradient_force", "anisotropic_drag",
           "quadratic_drag", "sensor_latency"}


def test_library_is_registered_and_valid():
    known = known_effects()
    assert LIBRARY <= set(known)
    for effect in known.values():
        assert check_effect(effect) is effect
        assert len(effect.doc) > 80  # each documents its physics


def _sample(n=50, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(0, 30, (n, 3)), rng.normal(0, 15, (n, 3)), rng.normal(0, 8, (n, 3))


def test_force_forms():
    known = known_effects()
    p, v, u = _sample()
    base = {"k": 0.2, "Cd0": 0.0, "Cd1": 0.08, "Cl0": 0.0, "Fvs": -0.4, "Fmax": 0.0}
    flow = known["background_flow"].force(p, v, u, {**base, "w_x": 2.0, "w_y": -1.0})
    assert np.allclose(flow, [0.16, -0.08, 0.0])  # +Cd1 w
    quad = known["quadratic_drag"].force(p, v, u, {**base, "c": 0.01})
    assert np.allclose(quad, -0.01 * np.linalg.norm(v, axis=1, keepdims=True) * v)
    wall = known["wall_drag"].force(np.array([[0.0, 0, 0], [70.0, 0, 0]]), np.ones((2, 3)), np.ones((2, 3)),
                                    {**base, "c": 0.1, "ell": 5.0})
    assert np.allclose(wall[:, 0], [-0.1 * 5 / 80, -0.1 * 5 / 10])  # grows as 1/d towards the wall
    so = known["step_out"].force(p, v, np.array([[10.0, 0, 0]] * 50), {**base, "f_so": 6.0})
    assert np.allclose(so[:, 0], -0.2 * 8.0)  # spin 10 - sqrt(100 - 36) = 2 Hz instead of 10
    aniso = known["anisotropic_drag"].force(p, np.array([[1.0, 2.0, 0]] * 50), np.array([[5.0, 0, 0]] * 50),
                                            {**base, "c": 0.1})
    assert np.allclose(aniso, [0.0, -0.2, 0.0])  # only across the spin axis
    g = known["gradient_force"].force(p, v, np.array([[0, 0, 8.0]] * 50), {**base, "b_x": 0.01, "b_y": 0.0,
                                      "b_z": 0.0})
    assert np.allclose(g, 0.01 * np.column_stack([2 * p[:, 0], -p[:, 1], -p[:, 2]]))  # x pair carries the field


def test_transforms():
    known = known_effects()
    u = np.zeros((40, 3))
    u[10:, 0] = 10.0
    lag = known["actuation_lag"].transform(u, 0.02, {"tau": 0.1})
    assert lag[10, 0] < 2.0 and 9.0 < lag[-1, 0] < 10.0 and np.all(np.diff(lag[:, 0]) >= 0)
    assert np.array_equal(known["actuation_lag"].transform(u, 0.02, {"tau": 0.0}), u)
    traj = np.cumsum(np.ones((1, 8, 3)), axis=1)  # moving 1 mm per step
    late = known["sensor_latency"].transform(traj, 0.02, {"delay": 1.5})
    assert np.allclose(late[0, 3:], traj[0, 3:] - 1.5)
    turn = np.radians(np.where(np.arange(30) < 5, 0.0, 150.0))
    head = known["heading_lag"].transform(5.0 * np.column_stack([np.cos(turn), np.sin(turn), np.zeros(30)]), 0.02,
                                          {"tau": 0.05})
    norm = np.linalg.norm(head, axis=1)  # the spin rate is kept: only a turn within a step shortens the mean
    assert np.allclose(norm[:5], 5.0) and np.all(norm <= 5.0 + 1e-12) and np.allclose(norm[-5:], 5.0)
    assert head[5, 0] > 0.0 and head[-1, 0] == pytest.approx(5.0 * np.cos(np.radians(150.0)), abs=0.01)  # lags, turns


def test_heading_lag_is_the_overdamped_magnetic_alignment():
    """The body axis b under a torque m B sin(theta) against a rotational drag: b' = (u_hat - (u_hat . b) b) / tau,
    integrated numerically (scipy, tight tolerances) through turns of 30, 90 and 150 degrees, each step's mean
    of |u| b against the transform; a small turn decays as a first-order lag."""
    from scipy.integrate import solve_ivp

    from cosim_plugins.effects.transforms import first_order_lag, heading_relaxation

    tau, dt = 0.15, 0.02
    rates = [8.0] * 5 + [12.0] * 15 + [10.0] * 15 + [6.0] * 15
    angles = np.radians([0.0] * 5 + [30.0] * 15 + [120.0] * 15 + [-30.0] * 15)  # then 90 and 150 degrees back
    u = np.column_stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)]) * np.array(rates)[:, None]
    u[20:35, 2], u[20:35, :2] = 0.3 * u[20:35, 0], 0.9 * u[20:35, :2]  # out of the plane too
    want, b = [], u[0] / np.linalg.norm(u[0])
    for ui in u:
        target = ui / np.linalg.norm(ui)

        def rhs(t, y, target=target):
            bn = y[:3] / np.linalg.norm(y[:3])
            db = (target - target @ bn * bn) / tau
            return np.concatenate([db, bn])  # the axis and the integral of the axis over the step

        sol = solve_ivp(rhs, (0.0, dt), np.concatenate([b, np.zeros(3)]), rtol=1e-11, atol=1e-13)
        b = sol.y[:3, -1] / np.linalg.norm(sol.y[:3, -1])
        want.append(np.linalg.norm(ui) * sol.y[3:, -1] / dt)
    got = heading_relaxation(u, dt, tau)
    assert np.abs(got - np.array(want)).max() < 1e-6 * 12.0
    small = np.column_stack([np.ones(30), np.r_[np.zeros(5), np.full(25, 1e-3)], np.zeros(30)]) * 10.0
    assert np.allclose(heading_relaxation(small, dt, tau)[:, 1], first_order_lag(small, dt, tau)[:, 1], rtol=1e-5,
                       atol=1e-9)
    idle = np.vstack([np.zeros((4, 3)), u])  # rows without a command first: the axis starts on the first command
    assert np.abs(heading_relaxation(idle, dt, tau)[4:] - got).max() < 1e-12


def test_saved_model_with_a_library_term_loads(tmp_path):
    from cosim_plugins.identify.model import load_model
    from cosim_plugins.models.physical import synthetic_plant

    model = synthetic_plant()
    model.save(tmp_path / "m.npz")
    back = load_model(tmp_path / "m.npz")
    assert back.params()["quadratic_drag.c"] == pytest.approx(0.0015)
    x = np.array([[1.0, 2, 3, 10, -5, 2]])
    u = np.array([[8.0, 1, 0]])
    assert np.allclose(back.predict(x, u, 0.02), model.predict(x, u, 0.02))


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """(dataset, plant): the plain paper model as the plant, camera noise 0.1 mm."""
    physical = lookup("model", "physical")
    plant = physical.from_params(syn.TRUE_PARAMS)
    cases = syn.paper_cases()
    cases = {k: cases[k] for k in ("circle_+0", "racetrack_+45")}
    files = syn.write_cases(tmp_path_factory.mktemp("syn"), plant.predict, 1500, cases, seed=3,
                            bias_hz=(0.0, 0.0, 2.4), defects=syn.Defects(noise_mm=0.1))
    return Dataset.from_paths(files), plant


def test_noise_estimate_and_floor_of_a_perfect_model(synthetic):
    ds, plant = synthetic
    tl = Timeline.from_dataset(ds)
    sigma = noise_sigma_mm(tl)
    assert np.allclose(sigma, 0.1, rtol=0.1)
    jm = JointModel(plant)
    starts = tl.window_starts(10, 0.6, rows=11)[::2]
    steps = {"0.2": 10, "1.0": 50}
    ev = jm.evaluate(tl, starts, 10, steps)
    tau = velocity_time_constant(jm)  # m / Cd1: the floor knows only this of the model
    assert tau == pytest.approx(0.15, rel=0.01)
    floor = noise_floor(tl, starts, 10, steps, sigma, tau)
    for key, r in ev.items():  # the true model's error is the first-order noise floor
        err = np.mean(np.linalg.norm(r["err"][r["valid"]], axis=1))
        assert err == pytest.approx(np.mean(floor[key][r["valid"]]), rel=0.15)
    # a degenerate fit's "no drag" (tau -> infinity) would have doubled the floor at 1.0 s
    far = noise_floor(tl, starts, 10, steps, sigma, 1e3)
    assert np.mean(far["1.0"]) > 1.5 * np.mean(floor["1.0"])
    # fits that took up a missing lag with three times the drag's time constant: their median would put the floor
    # above the true model's error; a candidate that passes with the true time constant sets it
    slow = JointModel(lookup("model", "physical").from_params({**syn.TRUE_PARAMS, "Cd1": syn.TRUE_PARAMS["Cd1"] / 3}))
    inflated = noise_floor(tl, starts, 10, steps, sigma, velocity_time_constant(slow))
    err = np.mean(np.linalg.norm(ev["1.0"]["err"][ev["1.0"]["valid"]], axis=1))
    assert np.mean(inflated["1.0"][ev["1.0"]["valid"]]) > 1.1 * err
    assert _floor_time_constant([slow] * 3, passing=[slow, jm])[0] == pytest.approx(tau)
    assert _floor_time_constant([jm] * 3, passing=[slow])[0] == pytest.approx(tau)  # never longer than the median
    assert _floor_time_constant([slow, slow, jm])[0] == pytest.approx(3 * tau, rel=0.01)


def test_time_block_split_keeps_halves_apart():
    from dataclasses import dataclass

    from cosim_plugins.diagnose.pipeline import BLOCK_S, split_logs

    @dataclass
    class L:
        t_s: np.ndarray
        p_mm: np.ndarray

    t = np.arange(1500) * 0.02
    log = L(t, np.ones((1500, 3)))
    train, test, info = split_logs([log])
    tr, te = np.isfinite(train[0].p_mm[:, 0]), np.isfinite(test[0].p_mm[:, 0])
    assert not np.any(tr & te) and np.all(tr | te)
    assert te.mean() == pytest.approx(1 / 3, abs=0.05) and info.block_s == BLOCK_S


def test_a_latency_reads_the_path_before_each_window(synthetic):
    """Positions seen 2.5 steps late: with the true delay the rollouts start early enough that the model
    reproduces them (no extrapolation before a window's first row)."""
    from cosim_plugins.identify.effect import known_effects

    ds, plant = synthetic
    tl = Timeline.from_dataset(ds)
    a, b = max(tl.segments, key=lambda s: s[1] - s[0])
    true = plant.rollout(tl.x_lin[a], tl.u[a:b], tl.dt_s)[:, :3]  # (b - a + 1, 3), exact, no noise
    seen = known_effects()["sensor_latency"].transform(true[None], tl.dt_s, {"delay": 2.5})[0]
    tl.p = np.full_like(tl.p, np.nan)
    tl.p[a + 3:b] = seen[3:b - a]
    tl.x_lin[a + 1:b + 1] = np.column_stack([true[1:], np.diff(true, axis=0) / tl.dt_s])  # guesses near the path
    jm = JointModel(plant, [known_effects()["sensor_latency"]], base_params={"sensor_latency.delay": 2.5})
    assert jm.lookback() == 3
    starts = np.arange(a + 3, b - 60, 7)
    ev = jm.evaluate(tl, starts, 10, {"1.0": 50})["1.0"]
    err = np.linalg.norm(ev["err"][ev["valid"]], axis=1)
    assert ev["valid"].sum() > 20 and err.max() < 1e-3
    jm.lookback = lambda: 0  # extrapolating the first step backwards instead
    ev = jm.evaluate(tl, starts, 10, {"1.0": 50})["1.0"]
    assert np.mean(np.linalg.norm(ev["err"][ev["valid"]], axis=1)) > 10 * max(err.mean(), 1e-4)


def test_verdict_names_a_look_alike_group_not_a_member():
    """A step the logs cannot tell from its rival is named as the group; the same step alone is named."""
    from hand_made import typed

    from cosim_plugins.diagnose.render import to_json
    from cosim_plugins.diagnose.verdict import verdict

    def result(group):
        rival = {"sensor_latency": {"t_stat": 1.2, "t_horizons": 0.8, "differ_mm": 0.05, "adds": 0.01}}
        step = {"effects": ["actuation_lag", "sensor_latency"] if group else ["actuation_lag"], "group": group,
                "rollout_before_mm": 1.0, "rollout_mm": 0.64, "reduction": 0.36, "t_stat": 6.0,
                "params": {"actuation_lag.tau": {"value": 0.05, "std": 0.01, "unit": "s"}},
                "group_evidence": rival if group else {}}
        entry = {"effect": "actuation_lag", "reduction": 0.36, "t_stat": 6.0, "rollout_mm": {"1.0": 0.64},
                 "params": step["params"]}
        return {"reference": None, "baseline": {"rollout_mm": {"1.0": 1.0}}, "noise": {"floor_mm": {"1.0": 0.3}},
                "ranking": [entry], "localisation": {"clues": []},
                "stepwise": {"steps": [step], "dropped": [], "joint": {"effects": ["actuation_lag"],
                                                                      "rollout_mm": {"1.0": 0.64},
                                                                      "reduction": {"1.0": 0.36}}}}

    tie = to_json(verdict(typed(result(True)), "1.0"))
    assert tie["effect"] is None and tie["effects"] == []
    assert tie["lookalikes"] == [["actuation_lag", "sensor_latency"]]
    assert "None of them is named" in tie["explanation"] and "t = 1.2 at 1.0 s" in tie["explanation"]
    named = to_json(verdict(typed(result(False)), "1.0"))
    assert named["effect"] == "actuation_lag" and named["effects"] == ["actuation_lag"] and not named["lookalikes"]
    assert "actuation_lag explains the error" in named["explanation"]


def test_a_diverging_model_shows_a_huge_error_not_nan(synthetic):
    """A force that feeds the velocity (+c v, c m / dt >> 1) blows the rollouts up: each valid window's error
    is DIVERGED_MM, so means and rankings stay numbers."""
    from cosim_plugins.identify.joint import DIVERGED_MM
    from cosim_plugins.identify.terms import EffectParam, ForceTerm

    ds, plant = synthetic
    tl = Timeline.from_dataset(ds)
    push = ForceTerm("push", (EffectParam("c", 5.0),), lambda p, v, u, prm: prm["c"] * v)
    jm = JointModel(plant, [push])
    starts = np.arange(20, tl.n - 80, 37)
    ev = jm.evaluate(tl, starts, 10, {"1.0": 50})["1.0"]
    err = np.linalg.norm(ev["err"][ev["valid"]], axis=1)
    assert ev["valid"].sum() > 10 and np.all(np.isfinite(err))
    assert np.allclose(err, DIVERGED_MM)


def test_a_search_on_top_of_a_discovered_form_keeps_the_effects_chosen_before_it(monkeypatch):
    """The search given a discovered form takes its own choices out one at a time (the backward check): the
    effects the first search chose stay in those models, or each choice would be judged against a model that
    lacks them and always pass."""
    from cosim_plugins.diagnose.discover import TERMS, library_effect
    from cosim_plugins.diagnose.fitting import Fit, Fitter
    from cosim_plugins.diagnose.pipeline import on_top_of

    known = known_effects()
    flow, wall, lag = known["background_flow"], known["wall_drag"], known["actuation_lag"]
    form = library_effect(TERMS[:2], [1.0, 1.0])
    host = lookup("model", "physical")()
    host.dt_s = 0.02
    found = Fit(JointModel(host, [flow, wall, form]), {}, {})
    fitter = Fitter(None, [flow], None, None, 0, None, None, None, None, 0, {}, 0)
    monkeypatch.setattr(Fitter, "refit", lambda self, jm: jm)
    kept = on_top_of(fitter, found).without(found, [lag])
    assert [e.name for e in kept.effects] == ["background_flow", "wall_drag", "discovered", "actuation_lag"]


@pytest.mark.parametrize("moved_mm, tried", [(2.5, 4), (900.0, 0), (None, 0)])
def test_discovery_retries_only_about_time_constants_where_the_model_does_not_run_off(monkeypatch, moved_mm, tried):
    """A model without drag moved to a short time constant scales its thrust by ~1e11 and runs off the tank:
    discovery is not retried about it (the refit there raised on a non-finite Jacobian)."""
    from cosim_plugins.diagnose.fitting import Fit, Fitter
    from cosim_plugins.diagnose.pipeline import RUNOFF_RATIO, Settings, _other_time_constants

    plant = lookup("model", "physical").from_params({**syn.TRUE_PARAMS, "Cd1": 1e-9})  # tau ~ 1e7 s
    final = Fit(JointModel(plant), {}, {"rollout_mm": {"1.0": 1.0}})
    fitter = Fitter(Settings(), [], None, None, 0, None, None, None, None, 0, {}, 0)
    monkeypatch.setattr(Fitter, "evaluate", lambda self, jm: Fit(jm, {}, {"rollout_mm": {"1.0": moved_mm}}))
    said = []
    moved = list(_other_time_constants(fitter, final, said.append))
    assert len(moved) == tried and (moved_mm is None or moved_mm > RUNOFF_RATIO) == (tried == 0)
    assert all("runs off" in line for line in said) == (tried == 0)
    taus = [velocity_time_constant(f.model) for f in moved]
    assert taus == pytest.approx([0.03, 0.1, 0.3, 1.0][:tried], rel=1e-6)


def test_a_fit_whose_trial_points_run_off_to_huge_finite_positions_ends_where_they_do_not(synthetic, monkeypatch):
    """Rollouts that run off to 1e200 mm are finite, but their squares overflow: the fit's least squares sees
    them capped at 1e6 mm (a diagnosis's refit of a discovered form beside a flow failed in its SVD on one)
    and ends outside the region where they occur, with a finite cost."""
    from cosim_plugins.identify.joint import fit_joint

    ds, _ = synthetic
    tl = Timeline.from_dataset(ds)
    jm = JointModel(lookup("model", "physical").from_params({**syn.TRUE_PARAMS, "k": 0.9 * syn.TRUE_PARAMS["k"]}))
    cd0 = jm.prm["Cd0"]
    real = JointModel.projected

    def projected(self, *args, **kwargs):  # any Cd0 above the start's runs off (its Jacobian column too)
        pred, solve = real(self, *args, **kwargs)
        return (pred + 1e200 if self.prm["Cd0"] > cd0 else pred), solve

    monkeypatch.setattr(JointModel, "projected", projected)
    fit = fit_joint(jm, tl, tl.window_starts(10, 0.6, rows=11)[::4], 25, max_nfev=15)
    assert np.isfinite(fit.rms_mm) and fit.rms_mm < 1.0
    assert jm.prm["Cd0"] <= cd0
    assert fit.rms_mm < fit.rms_start_mm  # the thrust gain still went to where the logs put it

"""A Jacobian's columns rolled out as one batch equal one rollout per column (to rounding)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cosim.contract.plugins import lookup
from cosim_plugins.identify import synthetic as syn
from cosim_plugins.identify.dataset import Dataset
from cosim_plugins.identify.effect import known_effects
from cosim_plugins.identify.joint import HeldJacobian, JointModel, OpenLoop, UnitOffsets, targets
from cosim_plugins.identify.timeline import Timeline

EFFECTS = ("background_flow", "actuation_lag", "sensor_latency")  # a force, an input and a sensor effect
PARAMS = {"background_flow.w_x": 1.5, "background_flow.w_y": -0.7, "actuation_lag.tau": 0.05,
          "sensor_latency.delay": 1.3, "Cd0": 0.01, "Cl0": 0.005, "Fmax": 0.02}


@pytest.fixture(scope="module")
def timeline():
    plant = lookup("model", "physical").from_params(syn.TRUE_PARAMS)
    cases = syn.paper_cases()
    cases = {k: cases[k] for k in ("circle_+0", "racetrack_+45")}
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        files = syn.write_cases(Path(tmp), plant.predict, 500, cases, seed=4, bias_hz=(0.0, 0.0, 2.4),
                                defects=syn.Defects(noise_mm=0.1))
        return Timeline.from_dataset(Dataset.from_paths(files))


def _joint(hold: str, params: dict) -> JointModel:
    host = lookup("model", "physical")(hold=hold)
    host.set_params(dict(syn.TRUE_PARAMS))
    host.dt_s = 0.02
    known = known_effects()
    return JointModel(host, [known[n] for n in EFFECTS], base_params=params)


def _both(jm, fn, cols=None, step=None):
    """(batched, looped) Jacobians of ``fn`` at jm's parameters; the max relative difference."""
    theta = jm.theta.copy()
    hj = HeldJacobian(jm, fn, step=step)
    batched = hj.jac(theta, cols)
    looped = HeldJacobian(jm, fn, step=step).jac(theta, cols, batched=False)
    assert np.array_equal(jm.theta, theta)  # the parameters are restored
    scale = np.maximum(np.abs(looped).max(axis=0), 1e-300)
    return batched, looped, float(np.max(np.abs(batched - looped) / scale))


def _open_loop(jm, tl, starts):
    ol = OpenLoop.upto(starts, 10, 25)

    def errors(held):
        with np.errstate(all="ignore"):
            e, solve = ol.errors(jm, tl, held)
        return np.nan_to_num(e), solve

    return errors


def _windows(jm, tl, starts, length):
    fit_rows = np.ones((len(starts), length + 1), dtype=bool)
    use = np.all(np.isfinite(targets(tl, starts, length)), axis=2)
    target = np.nan_to_num(targets(tl, starts, length))

    def residual(held):
        pred, solve = jm.projected(tl, starts, length, fit_rows, held=held)
        return np.where(use[..., None], pred - target, 0.0).reshape(-1), solve

    return residual


@pytest.mark.parametrize("hold", ["exact", "paper"])
def test_batched_jacobian_equals_the_looped_one(timeline, hold):
    tl = timeline
    jm = _joint(hold, PARAMS)
    starts = tl.window_starts(35, 0.6)[::9]
    assert len(starts) > 40 and jm.lookback() == 2
    for fn in (_open_loop(jm, tl, starts), _windows(jm, tl, starts, 20)):
        batched, looped, diff = _both(jm, fn)
        assert np.abs(looped).max(axis=0).min() > 0  # every parameter moves the predictions
        assert diff < 1e-9
    # a subset of columns with a fixed step (discovery's way), in small batches
    import cosim_plugins.identify.joint as joint

    old, joint.MAX_BATCH_COLUMNS = joint.MAX_BATCH_COLUMNS, 2 * len(starts)
    try:
        assert _both(jm, _open_loop(jm, tl, starts), cols=[0, 2, 6, 7, 8], step=1e-3)[2] < 1e-9
    finally:
        joint.MAX_BATCH_COLUMNS = old


def test_a_column_whose_lookback_changes_falls_back(timeline):
    """A delay just below 2 steps: its perturbed column needs a lookback of 3, the others 2."""
    tl = timeline
    jm = _joint("exact", {**PARAMS, "sensor_latency.delay": 2.0 - 1e-9})
    starts = tl.window_starts(35, 0.6)[::9]
    assert _both(jm, _open_loop(jm, tl, starts))[2] < 1e-9


def test_parameters_per_unit_roll_out_per_column(timeline):
    tl = timeline
    jm = _joint("exact", PARAMS)
    jm.per_unit = UnitOffsets(("Cd1",), np.where(tl.log > 0, 1, 0), np.array([[0.0], [0.004]]))
    assert not jm.batchable()
    starts = tl.window_starts(35, 0.6)[::9]
    batched, looped, diff = _both(jm, _open_loop(jm, tl, starts))
    assert np.array_equal(batched, looped)


def test_groups_step_like_separate_models():
    """set_groups: each group of columns steps exactly as a model with its parameters; terms get scalars."""
    host = lookup("model", "physical")(hold="exact", terms=[known_effects()["background_flow"]])
    names = [q.name for q in host.all_params()]
    rng = np.random.default_rng(1)
    thetas = np.array([[0.1, 0.01, 0.05, 0.004, -0.3, 0.02, 1.0, -0.5]] * 3)
    thetas[1, 2] = 0.06  # another drag
    thetas[2, 6] = 2.0  # another flow
    x, u, up = rng.normal(0, 10, (6, 12)), rng.normal(0, 8, (3, 12)), rng.normal(0, 8, (3, 12))
    seen = []
    force = host.terms[0].force

    def spy(p, v, w, prm):
        seen.append((len(p), {k: type(val) for k, val in prm.items()}))
        return force(p, v, w, prm)

    host.terms[0] = replace(host.terms[0], force=spy)
    host._velocity_terms()  # its probe, once
    seen.clear()
    host.set_groups(thetas, 4)
    batch = host.predict_t(x, u, 0.02, up)
    host.set_groups(None)
    assert [n for n, _ in seen] == [4] * 9  # one call per group in each pass and in the step's zero-velocity probe
    assert all(t is not np.ndarray for _, types in seen for t in types.values())
    for g in range(3):
        host.set_params(dict(zip(names, thetas[g])))
        one = host.predict_t(x[:, 4 * g:4 * g + 4], u[:, 4 * g:4 * g + 4], 0.02, up[:, 4 * g:4 * g + 4])
        assert np.array_equal(batch[:, 4 * g:4 * g + 4], one)
    with pytest.raises(ValueError, match="groups"):
        host.set_groups(thetas[:, :5], 4)


def test_a_term_runs_once_for_the_groups_that_agree_on_what_it_reads():
    """A term reading w_x always and w_y only far from the centre: groups that differ in other parameters share
    its calls, and a call that reads w_y for the first time is redone with the groups split by it."""
    from cosim_plugins.identify.effect import Effect, EffectParam

    def push(p, v, u, prm):
        far = np.abs(p[:, 0]) > 30.0
        f = np.zeros_like(p)
        f[:, 0] = prm["w_x"]
        if far.any():
            f[far, 1] = prm["w_y"] * p[far, 1]
        return f

    term = Effect(name="push", params=(EffectParam("w_x", 0.0), EffectParam("w_y", 0.0)), force=push)
    host = lookup("model", "physical")(hold="exact", terms=[term])
    names = [q.name for q in host.all_params()]
    thetas = np.array([[0.1, 0.0, 0.05, 0.004, -0.3, 0.02, 1.0, -0.5]] * 4)
    thetas[1, 0] = 0.12  # another k: the term does not read it
    thetas[2, 7] = 0.5  # another w_y: read only once the swimmer is far out
    thetas[3, 6] = 2.0  # another w_x
    x = np.zeros((6, 8))
    x[3] = 400.0  # out past x = 30 mm after a few steps
    u = np.tile([[5.0], [0.0], [2.0]], (1, 8))
    calls = []
    host.terms[0] = replace(term, force=lambda p, v, w, prm: calls.append(len(p)) or push(p, v, w, prm))
    host._velocity_terms()
    calls.clear()
    host.set_groups(thetas, 2)
    xb, out = x, []
    for _ in range(12):
        xb = host.predict_t(xb, u, 0.02, u)
        out.append(xb)
    host.set_groups(None)
    # two passes per step (hold="exact"). Step 1's first: every group alone; then groups 0-2 (same w_x) together;
    # once far out, the merged call reads w_y and is redone split by it: 0 and 1 together (another k only), 2 and
    # 3 alone
    near = [6, 2] * 9
    assert calls == [2, 2, 2, 2] + near + [6] + [4, 2, 2] * 14
    for g in range(4):
        host.set_params(dict(zip(names, thetas[g])))
        xs = x[:, 2 * g:2 * g + 2]
        for j in range(12):
            xs = host.predict_t(xs, u[:, :2], 0.02, u[:, :2])
            assert np.array_equal(out[j][:, 2 * g:2 * g + 2], xs)


def test_discovery_sensitivities_split_over_processes_are_the_same(timeline):
    from cosim_plugins.diagnose.discover import _sensitivities

    tl = timeline
    jm = _joint("exact", PARAMS)
    ol = OpenLoop.upto(tl.window_starts(35, 0.6)[::15], 10, 25)
    cols = [jm.names.index(n) for n in ("background_flow.w_x", "actuation_lag.tau", "sensor_latency.delay")]
    host = [jm.names.index(n) for n in ("k", "Cd1")]
    one = _sensitivities(jm, tl, ol, cols, host, jobs=1)
    two = _sensitivities(jm, tl, ol, cols, host, jobs=2)
    assert all(np.array_equal(a, b) for a, b in zip(one, two))
    assert one[1].shape == (len(one[0]), 3) and one[2].shape == (len(one[0]), 2)


@pytest.mark.parametrize("per_unit", [False, True])
def test_a_wide_rollout_stepped_in_pieces_is_the_same(timeline, per_unit, monkeypatch):
    import cosim_plugins.identify.joint as joint

    tl = timeline
    jm = _joint("exact", PARAMS)
    if per_unit:
        jm.per_unit = UnitOffsets(("Cd1",), np.where(tl.log > 0, 1, 0), np.array([[0.0], [0.004]]))
    starts = tl.window_starts(35, 0.6)[::5]
    x0 = np.stack([tl.x_lin[starts - 2] + d for d in (0.0, 0.5, 1.0)])  # (3, w, 6)
    whole = jm.rollouts(tl, starts, 30, x0)[0]
    monkeypatch.setattr(joint, "MAX_BATCH_COLUMNS", 37)  # pieces that split windows and variants
    assert np.array_equal(jm.rollouts(tl, starts, 30, x0)[0], whole)


def test_a_window_whose_rollout_blew_up_gets_no_initial_state_step():
    """A rollout that diverged leaves its window's normal matrix singular (huge sensitivities swamp the ridge):
    that window gets no Gauss-Newton step, the others the step they get alone."""
    from cosim_plugins.identify.joint import _corrected

    rng = np.random.default_rng(0)
    w, rows = 3, 5
    S = rng.normal(size=(w, rows, 3, 6))
    S[1] = 0.0
    S[1, :, :, :2] = 1e120  # two position components move alike, so hugely that the ridge is lost: G is singular
    q0, tz, use = rng.normal(size=(w, rows, 3)), np.zeros((w, rows, 3)), np.ones((w, rows), bool)
    _, d, _, _ = _corrected(q0, S, use, tz)
    assert np.all(d[1] == 0.0)
    _, alone, _, _ = _corrected(q0[[0, 2]], S[[0, 2]], use[[0, 2]], tz[[0, 2]])
    assert np.allclose(d[[0, 2]], alone)


def test_the_open_loop_fits_minimise_the_errors_the_diagnosis_measures(timeline):
    """An open-loop fit's residuals (the polish, discovery, per-log drift fits) at step K are the held-out
    evaluation's errors at that horizon, initial-state solve and all: a fit of one-pass errors against a
    two-pass evaluation settled, on logs with nothing hidden, 25 % above the truth's held-out error."""
    tl = timeline
    jm = _joint("exact", {**PARAMS, "Cl0": 0.02, "Cd0": 0.03})
    jm._set(jm.theta * 1.15)  # off the truth: the initial velocity's effect on the rollout is then nonlinear
    starts = tl.window_starts(60, 0.6)[::7]
    lead, horizon = 10, 50
    fitted, _ = OpenLoop.upto(starts, lead, horizon).errors(jm, tl)
    fitted = fitted.reshape(len(starts), horizon, 3)
    measured = jm.evaluate(tl, starts, lead, {"h": horizon})["h"]
    ok = measured["valid"]
    assert ok.sum() > 20
    np.testing.assert_allclose(fitted[ok, -1], measured["err"][ok], rtol=1e-9, atol=1e-12)
    one_pass = jm.evaluate(tl, starts, lead, {"h": horizon}, passes=1)["h"]["err"][ok]
    assert np.max(np.abs(one_pass - measured["err"][ok])) > 1e-6  # the passes matter on these windows

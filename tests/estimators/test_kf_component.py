"""estimator.kf as a component: ports and units, latency, and bad models refused at validation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cosim import ComponentError
from cosim.cli import main
from cosim.contract.plugins import lookup
from cosim_plugins.identify.model import load_model
from cosim_plugins.resources import SCENARIOS_DIR

SCENARIO = SCENARIOS_DIR / "feedback_sweep.yaml"
Q_DIAG = [1e-3, 1e-3, 1e-3, 4.0, 4.0, 4.0]


@pytest.fixture
def linear_file(linear_kinds, tmp_path):
    return lookup("model", "test-linear")().save(tmp_path / "linear.npz")


def make_kf(model_file, **params):
    kf = lookup("component", "estimator.kf")()
    kf.setup({"dt": 0.02, "model": str(model_file), "q_diag": Q_DIAG, "drift": False, **params},
             np.random.default_rng(0))
    return kf


def swim(model_file, n=120, seed=1):
    """True positions (n, 3) [m], commands (n, 3) [rad/s] (applied over [t_k, t_k+1)), noisy frames [m]."""
    model = load_model(model_file)
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.02
    u_hz = np.column_stack([8 * np.cos(t), 8 * np.sin(t), np.ones(n)])
    x = np.zeros((n, 6))
    x[0, :3] = [-15.0, -40.0, 0.0]
    for k in range(n - 1):
        x[k + 1] = model.predict(x[k], u_hz[k], 0.02)
    frames = (x[:, :3] + rng.normal(0, 0.1, (n, 3))) * 1e-3
    return x[:, :3] * 1e-3, u_hz * 2 * np.pi, frames


def run(kf, omega, frames):
    """Step the component; the omega input at tick k is the command of tick k - 1 (delay: 1)."""
    out = []
    for k in range(len(frames)):
        prev = omega[k - 1] if k else np.zeros(3)
        out.append(kf.step(k * 0.02, {"position": frames[k], "omega": prev}))
    return out


def test_ports_units_and_nan_between_frames(linear_file):
    truth, omega, frames = swim(linear_file)
    frames[:3] = np.nan  # nothing seen yet
    frames[np.arange(len(frames)) % 5 != 3] = np.nan  # a frame every 100 ms
    out = run(make_kf(linear_file), omega, frames)
    assert np.all(np.isnan(out[0]["position"])) and np.all(out[0]["velocity"] == 0)
    pos = np.array([o["position"] for o in out[3:]])
    assert np.all(np.isfinite(pos)) and np.abs(pos - truth[3:]).max() < 1e-3  # metres
    vel = np.array([o["velocity"] for o in out[40:]])
    true_vel = np.diff(truth, axis=0)[39:] / 0.02
    assert np.abs(vel - true_vel).mean() < 3e-3  # m/s
    innov = np.array([o["innovation"] for o in out])
    has = np.all(np.isfinite(innov), axis=1)
    np.testing.assert_array_equal(np.flatnonzero(has), np.arange(8, len(frames), 5))  # not the first frame
    assert np.abs(innov[has]).max() < 1e-3
    assert all(np.isfinite(o["nis"]) == h for o, h in zip(out, has))


def test_latency_gives_the_same_estimate_once_the_frame_is_in(linear_file):
    truth, omega, frames = swim(linear_file)
    frames[np.arange(len(frames)) % 4 != 0] = np.nan
    late = np.full_like(frames, np.nan)
    late[3:] = frames[:-3]  # each frame delivered 60 ms after its capture
    now = run(make_kf(linear_file), omega, frames)
    then = run(make_kf(linear_file, latency_s=0.06), omega, late)
    for k in range(3, len(frames), 4):  # ticks where the delayed frame just arrived
        np.testing.assert_allclose(then[k]["position"], now[k]["position"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(then[k]["velocity"], now[k]["velocity"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(then[7]["innovation"], now[4]["innovation"], rtol=0, atol=1e-12)
    with pytest.raises(ComponentError, match="latency_s=0.05 s is not a multiple"):
        make_kf(linear_file, latency_s=0.05)


# ---------------------------------------------------------------- validation


def _validate(capsys, model):
    code = main(["validate", str(SCENARIO), "--set", f"components.estimator.params.model={model}"])
    return code, capsys.readouterr().err


def test_validate_accepts_kinds_and_good_files_without_training(linear_file, capsys, monkeypatch):
    import cosim_plugins.identify.cache as cache

    monkeypatch.setattr(cache, "ensure_model", lambda *a, **k: pytest.fail("validate must not train"))
    assert _validate(capsys, "sindy-linear")[0] == 0
    assert _validate(capsys, linear_file)[0] == 0


def test_validate_refuses_an_unknown_model_kind(linear_kinds, tmp_path, capsys):
    code, err = _validate(capsys, "kalman-net")
    assert code == 2 and "model 'kalman-net' is neither a model file (.npz) nor a known kind" in err
    path = tmp_path / "alien.npz"
    meta = {"format": "cosim-model", "kind": "alien", "version": 1, "dt_s": 0.02, "options": {}, "meta": {}}
    np.savez(path, __meta__=np.array(json.dumps(meta)))
    code, err = _validate(capsys, path)
    assert code == 2 and f"model file {path} holds a 'alien' model, which is not a known kind" in err
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip")
    code, err = _validate(capsys, junk)
    assert code == 2 and "is not a cosim model file" in err
    code, err = _validate(capsys, tmp_path / "missing.npz")
    assert code == 2 and "does not exist" in err


def test_validate_refuses_a_model_file_of_another_version(linear_file, capsys, monkeypatch):
    monkeypatch.setattr(lookup("model", "test-linear"), "version", 2)
    code, err = _validate(capsys, linear_file)
    assert code == 2
    assert "components.estimator.params (estimator.kf)" in err
    assert "'test-linear' format version 1 is not supported (this code reads version 2); refit" in err


def test_validate_refuses_a_model_of_the_wrong_state_size(linear_kinds, tmp_path, capsys):
    small = lookup("model", "test-small")().save(tmp_path / "small.npz")
    code, err = _validate(capsys, small)
    assert code == 2 and "('test-small') has state size 4; the estimator needs 6 states" in err
    model = lookup("model", "test-linear")()
    model.A, model.B, model.c = model.A[:4, :4], model.B[:4], model.c[:4]  # arrays of a 4-state system
    path = model.save(tmp_path / "four.npz")
    code, err = _validate(capsys, path)
    assert code == 2 and "('test-linear') cannot predict a 6-state [p mm, v mm/s] with 3 inputs" in err


# ---------------------------------------------------------------- what setup hands the filter


def test_setup_hands_the_filter_every_parameter(linear_file):
    """The gate is the chi-square (3 dof) quantile of gate_prob; the initial velocity variance v0^2; the rest as
    given (against the filter's own defaults, which differ: 3 rejections, every step, no limits, no adaptation)."""
    from scipy.stats import chi2

    kf = make_kf(linear_file, gate_prob=0.99, max_rejects=7, relinearize_steps=4, v_max_mm_s=55.0, tank_mm=60.0,
                 adapt_rate=0.25, v0_mm_s=3.0)
    f = kf.filter
    assert f.gate == pytest.approx(chi2.ppf(0.99, 3), rel=1e-12) and f.gate == pytest.approx(11.3449, abs=1e-4)
    assert (f.max_rejects, f.relinearize_steps, f.v_max, f.tank, f.adapt_rate) == (7, 4, 55.0, 60.0, 0.25)
    np.testing.assert_allclose(f.p_init[3:6], 9.0, rtol=0)
    assert make_kf(linear_file, gate_prob=1.0).filter.gate == np.inf


def test_the_history_of_a_late_camera_holds_latency_plus_one_ticks(linear_file):
    """A 60 ms latency keeps the filter's state of the last 4 ticks, however long the run (no growth)."""
    truth, omega, frames = swim(linear_file, n=40)
    kf = make_kf(linear_file, latency_s=0.06)
    run(kf, omega, frames)
    assert len(kf.history) == 4


def test_latency_with_frames_closer_than_the_latency_fuses_each_as_if_on_time(linear_file):
    """A frame every 2 ticks, each 60 ms (3 ticks) late: a frame's capture entry is one the previous frame
    re-predicted, so it must hold that state (not forget it): each frame's innovation is the one it has when
    fused on time, and the NIS too."""
    truth, omega, frames = swim(linear_file)
    frames[np.arange(len(frames)) % 2 != 0] = np.nan
    late = np.full_like(frames, np.nan)
    late[3:] = frames[:-3]
    now = run(make_kf(linear_file), omega, frames)
    then = run(make_kf(linear_file, latency_s=0.06), omega, late)
    for c in range(2, len(frames) - 3, 2):  # each frame after the first, by its capture tick
        np.testing.assert_allclose(then[c + 3]["innovation"], now[c]["innovation"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(then[c + 3]["nis"], now[c]["nis"], rtol=1e-9)


@pytest.mark.parametrize("params, message", [
    ({"q_logs": ["a.csv", 3]}, "parameter q_logs: expected a list of file paths or glob patterns"),
    ({"max_rejects": 2.5}, "max_rejects and relinearize_steps must be whole numbers"),
])
def test_bad_parameters_are_refused_in_full(linear_file, params, message):
    with pytest.raises(ComponentError) as err:
        make_kf(linear_file, **params)
    assert str(err.value) == message

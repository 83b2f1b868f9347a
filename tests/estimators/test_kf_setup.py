"""estimator.kf's set-up: which model and logs it resolves (and on which profile), the noise it takes
(given as q_diag, or fitted on the logs named), the drift state, its first outputs.

The logs are short synthetic ones of the linear test swimmer; training and the paper dataset are
stood in for where the test is about what is asked of them, not how they are made.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

import cosim_plugins.estimators.kalman as kalman
import cosim_plugins.identify.cache as cache
import cosim_plugins.paper.dataset as paper_dataset
from cosim import ComponentError
from cosim.contract.errors import UserError
from cosim.contract.plugins import lookup
from cosim_plugins.estimators.noise import camera_variance, fit_process_noise
from cosim_plugins.identify.dataset import Dataset
from cosim_plugins.raw_log import write_log

Q9 = [1e-3, 1e-3, 1e-3, 4.0, 4.0, 4.0, 0.25, 0.5, 1.0]
KF = lookup("component", "estimator.kf")


@pytest.fixture
def linear_file(linear_kinds, tmp_path):
    return lookup("model", "test-linear")().save(tmp_path / "linear.npz")


def swimmer_log(path: Path, n: int = 400, dt: float = 0.02, seed: int = 0, velocity_sd_mm_s: float = 2.0) -> Path:
    """A raw log of the linear test swimmer (its damped_swimmer matrices at 20 ms) with process noise (0.01 mm on
    positions, ``velocity_sd_mm_s`` on velocities, per step) and 0.05 mm frame noise."""
    from linear_plugin import damped_swimmer

    A, B, c = damped_swimmer()
    rng = np.random.default_rng(seed)
    u = np.column_stack([8 * np.cos(0.3 * np.arange(n) * 0.02), 8 * np.sin(0.3 * np.arange(n) * 0.02), np.zeros(n)])
    x = np.zeros((n, 6))
    for k in range(n - 1):
        x[k + 1] = A @ x[k] + B @ u[k] + c + rng.normal(0, [0.01] * 3 + [velocity_sd_mm_s] * 3)
    write_log(path, np.round(np.arange(n) * dt * 1e3), u * 2 * np.pi, (x[:, :3] + rng.normal(0, 0.05, (n, 3))) * 1e-3)
    return path


def setup_kf(**params):
    kf = KF()
    kf.setup({"dt": 0.02, **params}, np.random.default_rng(0))
    return kf


def test_the_first_outputs_are_nothing_seen_and_at_rest(linear_file):
    out = setup_kf(model=str(linear_file), q_diag=Q9).initial_outputs()
    assert out["position"].shape == (3,) and np.isnan(out["position"]).all()
    np.testing.assert_array_equal(out["velocity"], np.zeros(3))
    assert out["innovation"].shape == (3,) and np.isnan(out["innovation"]).all()
    assert out["nis"].shape == () and math.isnan(out["nis"])
    kf = setup_kf(model=str(linear_file), q_diag=Q9)
    blind = kf.step(0.0, {"position": np.full(3, np.nan), "omega": np.zeros(3)})  # no frame yet
    assert np.isnan(blind["position"]).all()
    np.testing.assert_array_equal(blind["velocity"], np.zeros(3))
    z = np.array([0.061, -0.047, 0.0123])  # far from the centre: a scale error would show
    first = kf.step(0.02, {"position": z, "omega": np.zeros(3)})
    np.testing.assert_allclose(first["position"], z, rtol=0, atol=1e-15)  # the first frame is the estimate


def test_artifacts_are_the_model_file_or_nothing_for_a_kind(tmp_path):
    assert KF.artifacts({"model": str(tmp_path / "m.npz")}) == [tmp_path / "m.npz"]
    assert KF.artifacts({"model": "mlp"}) == [] and KF.artifacts({}) == []


@pytest.fixture
def asked(monkeypatch):
    """What set-up asks for: models resolved (spec, profile) and datasets ensured (quick, profile)."""
    calls = {"models": [], "datasets": []}
    resolve = cache.resolve_model

    def resolve_model(spec, base_dir=None, quick=None, profile="ideal"):
        calls["models"].append((spec, profile))
        return resolve(spec, base_dir, quick, profile) if str(spec).endswith(".npz") else None

    def ensure_dataset(quick=False, profile="ideal", **kw):
        calls["datasets"].append((quick, profile))
        raise UserError("no dataset in this test")

    monkeypatch.setattr(cache, "resolve_model", resolve_model)
    monkeypatch.setattr(paper_dataset, "ensure_dataset", ensure_dataset)
    return calls


def test_prepare_trains_on_the_profile_named_and_makes_the_q_logs_only_when_needed(asked):
    with pytest.raises(UserError, match="no dataset in this test"):
        KF.prepare({"model": "mlp", "dataset": "lab"})
    assert asked == {"models": [("mlp", "lab")], "datasets": [(True, "lab")]}  # quick: COSIM_DATASET=quick here
    KF.prepare({"model": "physical", "q_diag": Q9})
    KF.prepare({"model": "physical", "q_logs": ["runs/*/log.csv"]})
    assert asked["models"][1:] == [("physical", "ideal"), ("physical", "ideal")] and len(asked["datasets"]) == 1


def test_a_model_that_cannot_be_resolved_is_named(monkeypatch):
    def refuse(spec, base_dir=None, quick=None, profile="ideal"):
        raise UserError(f"no {spec} on {profile}")

    monkeypatch.setattr(cache, "resolve_model", refuse)
    with pytest.raises(ComponentError) as err:
        KF.prepare({"model": "mlp", "dataset": "lab", "q_diag": Q9})
    assert str(err.value) == "model 'mlp': no mlp on lab"


def test_the_drift_state_takes_its_stationary_variance_from_q_diag(linear_file, asked):
    kf = setup_kf(model=str(linear_file), dataset="lab", q_diag=Q9, drift_tau_s=0.5)
    assert asked["models"] == [(str(linear_file), "lab")]
    phi = math.exp(-0.02 / 0.5)
    np.testing.assert_allclose(kf.noise.drift0, np.array(Q9[6:]) / (1 - phi**2), rtol=1e-12)
    assert kf.filter.n == 9 and kf.filter.phi == pytest.approx(phi, rel=1e-12)
    kf.step(0.0, {"position": np.array([0.01, -0.02, 0.0]), "omega": np.zeros(3)})  # the first frame starts it
    np.testing.assert_allclose(np.diag(kf.filter.P)[6:], kf.noise.drift0, rtol=1e-12)  # starts stationary
    kf.filter.x[6:] = [1.0, 2.0, 3.0]  # a drift of 1-3 mm/s
    out = kf.step(0.02, {"position": np.full(3, np.nan), "omega": np.zeros(3)})
    np.testing.assert_allclose(out["velocity"], (kf.filter.x[3:6] + kf.filter.x[6:9]) * 1e-3, rtol=1e-12)
    assert np.abs(kf.filter.x[6:] - [1.0, 2.0, 3.0]).max() > 0  # decayed by phi each period
    without = setup_kf(model=str(linear_file), q_diag=Q9[:6], drift=False)
    assert without.filter.n == 6 and np.array_equal(without.noise.drift0, np.zeros(3))


def test_q_is_fitted_on_the_logs_named_over_the_horizon_and_scaled(linear_file, tmp_path):
    # 20 mm/s of velocity noise a step: a Q the fit cannot put at zero (at 2 mm/s the camera explains all)
    logs = [swimmer_log(tmp_path / f"log{i}.csv", seed=i, velocity_sd_mm_s=20.0) for i in range(2)]
    kf = setup_kf(model=str(linear_file), q_logs=[str(tmp_path / "log*.csv")], q_horizon_s=0.3, q_scale=2.0,
                  noise_px=1.0, pixel_mm=0.1, drift_tau_s=4.0)
    model = lookup("model", "test-linear")()
    expected = fit_process_noise(model, Dataset.from_paths([str(p) for p in logs]), camera_variance(1.0, 0.1), 0.02,
                                 4.0, 15)
    assert np.all((expected.q[3:6] > 0.6 * 400.0) & (expected.q[3:6] < 1.4 * 400.0))  # near the 20^2 drawn
    np.testing.assert_allclose(kf.noise.q, 2.0 * expected.q, rtol=1e-12)
    np.testing.assert_allclose(kf.noise.drift0, expected.drift0, rtol=1e-12)
    assert kf.noise.horizons[-1] == 15 and kf.noise.windows == expected.windows


def test_the_shortest_horizon_is_two_periods(linear_file, tmp_path, monkeypatch):
    seen = []
    real = kalman.noise.fit_process_noise
    monkeypatch.setattr(kalman.noise, "fit_process_noise", lambda *a: seen.append(a[5]) or real(*a))
    setup_kf(model=str(linear_file), q_logs=[str(swimmer_log(tmp_path / "a.csv"))], q_horizon_s=0.02, drift=False)
    assert seen == [2]


def test_logs_at_another_period_or_too_short_are_refused_by_name(linear_file, tmp_path):
    slow = swimmer_log(tmp_path / "slow.csv", dt=0.04)
    with pytest.raises(ComponentError) as err:
        setup_kf(model=str(linear_file), q_logs=[str(slow)])
    assert str(err.value) == ("the logs for Q are sampled every 40 ms but the scenario steps 20 ms; give logs at the "
                              "scenario's period or q_diag")
    short = swimmer_log(tmp_path / "short.csv", n=40)
    with pytest.raises(ComponentError) as err:
        setup_kf(model=str(linear_file), q_logs=[str(short)], q_horizon_s=0.2)
    assert str(err.value).startswith(f"model {str(linear_file)!r}: only ") and "need at least 50" in str(err.value)


def test_q_logs_are_globbed_in_order_read_once_and_again_when_rewritten(tmp_path):
    kalman._DATASETS.clear()
    b, a = swimmer_log(tmp_path / "b.csv", 60), swimmer_log(tmp_path / "a.csv", 60, seed=1)
    data = kalman._dataset([str(tmp_path / "*.csv")])
    assert [log.path for log in data.logs] == [str(a), str(b)]
    assert kalman._dataset([str(tmp_path / "?.csv")]) is data  # the same files: not read again
    assert kalman._dataset([str(b), str(a)]) is not data  # another order is another dataset
    swimmer_log(b, 60, seed=2)
    os.utime(b, ns=(1, 10**18))  # rewritten: another modification time
    again = kalman._dataset([str(b), str(a)])
    assert again is not data and kalman._dataset([str(b), str(a)]) is again
    assert [log.path for log in again.logs] == [str(b), str(a)]  # every pattern's files, in the order given
    assert len(kalman._DATASETS) == 1  # only the last read is kept


@pytest.mark.parametrize("pattern, message", [
    ("missing.csv", "q_logs: no log file matches 'missing.csv'"),
    ("nothing*.csv", "q_logs: no log file matches 'nothing*.csv'"),
    ("folder", "q_logs: no log file matches 'folder'"),
    ("bad.csv", "q_logs: log bad.csv: wrong header"),
])
def test_q_logs_that_name_no_log_are_refused(tmp_path, monkeypatch, pattern, message):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "folder").mkdir()
    (tmp_path / "bad.csv").write_text("t,x\n1,2\n")
    kalman._DATASETS.clear()
    with pytest.raises(ComponentError) as err:
        kalman._dataset([pattern])
    assert str(err.value).startswith(message)


def test_set_up_without_q_logs_fits_q_on_the_training_logs_of_the_profile_named(linear_file, asked):
    with pytest.raises(ComponentError) as err:
        setup_kf(model=str(linear_file), dataset="lab")
    assert str(err.value) == "dataset: no dataset in this test"
    assert asked["datasets"] == [(True, "lab")]


def test_without_q_logs_the_paper_training_logs_of_the_profile_are_read(tmp_path, monkeypatch):
    logs = [swimmer_log(tmp_path / "t0.csv", 60), swimmer_log(tmp_path / "t1.csv", 60, seed=1)]
    seen = []

    class Paper:
        training = logs

    def ensure_dataset(quick=False, profile="ideal", **kw):
        seen.append((quick, profile))
        if profile == "nowhere":
            raise UserError("no profile nowhere")
        return Paper()

    monkeypatch.setattr(paper_dataset, "ensure_dataset", ensure_dataset)
    kalman._DATASETS.clear()
    assert [log.path for log in kalman._dataset([], "lab").logs] == [str(p) for p in logs]
    assert seen == [(True, "lab")]
    with pytest.raises(ComponentError) as err:
        kalman._dataset([], "nowhere")
    assert str(err.value) == "dataset: no profile nowhere"

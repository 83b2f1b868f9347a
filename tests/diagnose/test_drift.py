"""Drift between logs and within them: flagged with the identifiable combination that moves, never on logs of
one plant.

The logs come from the project's synthetic closed loop (:mod:`cosim_plugins.identify.synthetic`) with the
plain physical model as the plant, one plant per log: the drag (Cd0, Cd1, Cl0 together, as a change of the
water's viscosity does) grows by :data:`DRAG_STEP` from log to log, or stays put; or the net weight grows
within each log (:data:`WEIGHT_CHANGE`).
"""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from cosim.cli import main
from cosim.contract.plugins import lookup
from cosim_plugins.diagnose.per_unit import PerUnitFit, Units, between_logs, clone, trend_fit, within_logs
from cosim_plugins.diagnose.pipeline import Settings, run
from cosim_plugins.identify import synthetic as syn
from cosim_plugins.identify.joint import JointModel

DRAG_STEP = 0.08  # relative drag increase per log
PATHS = ("circle_+0", "racetrack_+45", "circle_-30", "racetrack_+0")


def _logs(folder, drag_step: float) -> list:
    physical = lookup("model", "physical")
    cases = syn.paper_cases()
    files = []
    for i, name in enumerate(PATHS):
        f = (1.0 + drag_step) ** i
        prm = {**syn.TRUE_PARAMS, **{n: syn.TRUE_PARAMS[n] * f for n in ("Cd0", "Cd1", "Cl0")}}
        plant = physical.from_params(prm, substeps=8)  # near the continuous-time swimmer
        files += syn.write_cases(folder / f"log{i}", plant.predict, 1250, {name: cases[name]}, seed=10 + i,
                                 defects=syn.Defects(noise_mm=0.1))
    return [str(p) for p in files]


@pytest.fixture(scope="module")
def drifting(tmp_path_factory):
    return _logs(tmp_path_factory.mktemp("drift"), DRAG_STEP)


def test_drag_drift_between_logs_is_flagged_as_the_combinations_it_moves(drifting):
    r = run(drifting, settings=Settings(candidates=[])).json
    d = r["drift"]
    # drag up 8 % per log: the speed per Hz k/Cd1 and the sinking speed Fvs/(Cd0 + Cd1) fall by 1 - 1/1.08 = 7.4 %
    # per log (the time constant too, but logs at one spin rate barely determine it)
    assert {"speed_per_hz", "sink_speed_mm_s"} <= set(d["flagged"])
    assert not any(f.startswith("within:") for f in d["flagged"])
    for q in ("speed_per_hz", "sink_speed_mm_s"):
        v = d["between"]["quantities"][q]
        assert v["change_per_step"] == pytest.approx(1 / (1 + DRAG_STEP) - 1, abs=0.025)
        assert abs(v["slope_t"]) > 3.0  # a trend in the order recorded
    speed = np.array(d["between"]["quantities"]["speed_per_hz"]["values"])
    true_speed = syn.TRUE_PARAMS["k"] / syn.TRUE_PARAMS["Cd1"] / (1 + DRAG_STEP) ** np.arange(len(PATHS))
    assert np.allclose(speed, true_speed, rtol=0.05)
    assert d["between"]["reduction"] >= 0.05 and d["between"]["t_stat"] >= 3.0
    assert r["verdict"]["status"] == "drift"
    assert "falls" in r["verdict"]["explanation"] and "from log to log" in r["verdict"]["explanation"]


def test_per_log_refit_ranks_by_its_held_out_drop(drifting, tmp_path):
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        code = main(["diagnose", *drifting, "--effects", "none", "--per-log", "Cd1", "--out", str(tmp_path)])
    assert code == 0
    r = json.loads((tmp_path / "diagnosis.json").read_text())
    entry = next(e for e in r["ranking"] if e["effect"] == "per-log Cd1")
    assert entry["kind"] == "drift" and entry["reduction"] >= 0.05 and entry["t_stat"] >= 3.0
    before = r["baseline"]["rollout_mm"]["1.0"]
    assert entry["rollout_mm"]["1.0"] < before  # the held-out error falls with Cd1 per log
    cd1 = np.array(r["drift"]["per_log"]["Cd1"])
    assert np.all(np.diff(cd1) > 0)  # the drag grows in the order recorded
    assert "drift flagged:" in printed.getvalue()
    assert "## Drift between and within the logs" in (tmp_path / "report.md").read_text()


def test_no_drift_flagged_on_logs_of_one_plant(tmp_path):
    r = run(_logs(tmp_path, 0.0), settings=Settings(candidates=[])).json
    assert r["drift"]["flagged"] == []
    assert r["verdict"]["status"] != "drift"


WEIGHT_CHANGE = 0.2  # the net weight grows by this over each log


def _weight_drifting_logs(folder, rows: int = 4000) -> list:
    """Two 80 s logs whose net weight grows linearly by :data:`WEIGHT_CHANGE` from start to end (the plant is
    stepped once per row, both paths at once)."""
    physical = lookup("model", "physical")
    cases = syn.paper_cases()
    plant = physical.from_params(syn.TRUE_PARAMS)
    row = [0]

    def drifting(x, u, dt_s):
        plant.set_params({"Fvs": syn.TRUE_PARAMS["Fvs"] * (1.0 + WEIGHT_CHANGE * row[0] / rows)})
        row[0] += 1
        return plant.predict(x, u, dt_s)

    files = syn.write_cases(folder, drifting, rows, {n: cases[n] for n in ("circle_+0", "racetrack_+45")}, seed=3,
                            defects=syn.Defects(noise_mm=0.1))
    return [str(p) for p in files]


def test_a_weight_drifting_within_each_log_is_flagged_as_a_trend_of_the_sinking_speed(tmp_path):
    r = run(_weight_drifting_logs(tmp_path), settings=Settings(candidates=[])).json
    d = r["drift"]
    assert d["flagged"] == ["within:sink_speed_mm_s"]
    v = d["within"]["quantities"]["sink_speed_mm_s"]
    # Fvs grows by 20 % over each log's 80 s: the sinking speed by ~15 % a minute (relative to the mean)
    assert v["change_per_min"] == pytest.approx(WEIGHT_CHANGE * 60.0 / 80.0 / (1 + WEIGHT_CHANGE / 2), rel=0.25)
    assert d["within"]["reduction"] >= 0.05 and d["within"]["t_vs_per_log"] >= 2.0
    assert d["explains"]["fit"] == "a trend within the logs"
    assert r["verdict"]["status"] == "drift" and "per minute within the logs" in r["verdict"]["explanation"]


def test_bad_drift_options_name_the_problem(drifting, tmp_path, capsys):
    assert main(["diagnose", *drifting, "--t-start", "0,60", "--out", str(tmp_path)]) == 2
    assert "--t-start gives 2 start times for 4 logs" in capsys.readouterr().err
    assert main(["diagnose", *drifting, "--per-log", "Cd9", "--effects", "none", "--out", str(tmp_path)]) == 2
    assert "--per-log Cd9: not a base parameter" in capsys.readouterr().err


def test_homogeneity_and_trend_tests_on_known_values():
    rng = np.random.default_rng(4)
    sd = np.full(40, 0.1)
    same = between_logs(1.0 + 0.1 * rng.standard_normal(40), sd, np.arange(40.0))
    assert same["p"] > 1e-3 and abs(same["slope_t"]) < 3.0
    trend = between_logs(1.0 - 0.01 * np.arange(40) + 0.1 * rng.standard_normal(40), sd, np.arange(40.0))
    assert trend["p"] < 1e-3 and trend["slope_t"] < -3.0
    assert trend["change_per_step"] == pytest.approx(-0.01 / trend["mean"], rel=0.2)
    # within: each log its own offset, one common slope per second
    log = np.repeat(np.arange(4), 10)
    t = np.tile(np.arange(10) * 20.0 + 10.0, 4)
    x = log * 0.5 + 0.002 * t + 0.01 * rng.standard_normal(40)
    w = within_logs(x, np.full(40, 0.01), log, t)
    assert w["slope"] == pytest.approx(0.002, rel=0.05) and w["p"] < 1e-6
    flat = within_logs(log * 0.5 + 0.01 * rng.standard_normal(40), np.full(40, 0.01), log, t)
    assert flat["p"] > 1e-3
    # blocks scattering 3x beyond their stated uncertainty: the Birge ratio ~9 takes the false trend back
    loose = within_logs(log * 0.5 + 0.03 * rng.standard_normal(40), np.full(40, 0.01), log, t)
    assert loose["scatter"] == pytest.approx(9.0, rel=0.5) and loose["p"] > 1e-3
    # per-log values 1 % apart (std) with 0.1 % uncertainties: the excess spread is the 1 %
    apart = between_logs(1.0 + 0.01 * rng.standard_normal(200), np.full(200, 0.001), np.arange(200.0))
    assert apart["excess_sd"] == pytest.approx(0.01, rel=0.15)
    assert between_logs(1.0 + 0.01 * rng.standard_normal(200), np.full(200, 0.001), np.arange(200.0),
                        scatter=100.0)["p"] > 1e-3  # the same spread, all of it scatter: homogeneous


def test_per_column_parameters_step_each_column_with_its_own_values():
    physical = lookup("model", "physical")
    model = physical.from_params(syn.TRUE_PARAMS, hold="exact")
    rng = np.random.default_rng(1)
    x, u = rng.normal(0, 5, (6, 4)), rng.normal(0, 8, (3, 4))
    cd1 = np.array([0.05, 0.08, 0.12, 0.2])
    model.set_columns({"Cd1": cd1})
    batch = model.predict_t(x, u, 0.02)
    model.set_columns(None)
    for j in range(4):
        one = physical.from_params({**syn.TRUE_PARAMS, "Cd1": cd1[j]}, hold="exact")
        assert np.allclose(batch[:, j], one.predict_t(x[:, j:j + 1], u[:, j:j + 1], 0.02)[:, 0], rtol=1e-12)
    with pytest.raises(ValueError, match="only base parameters"):
        model.set_columns({"quadratic_drag.c": cd1})


def test_trend_fit_puts_per_unit_values_on_lines_weighted_by_their_covariance():
    physical = lookup("model", "physical")
    jm = JointModel(physical.from_params(syn.TRUE_PARAMS))
    names, shared = ("k", "Fvs"), jm.params()
    log = np.repeat(np.arange(3), 8)
    t = np.tile(np.arange(8) * 20.0 + 10.0, 3)
    units = Units(np.arange(24), log, t)
    truth = np.stack([shared["k"] * (1.0 + 0.1 * log - 0.002 * t), shared["Fvs"] * (1.0 + 0.003 * t)], axis=1)
    rng = np.random.default_rng(5)
    sd = np.array([0.02 * shared["k"], 0.05 * abs(shared["Fvs"])])
    cov = np.tile(np.diag(sd ** 2), (24, 1, 1))
    cov[5] = np.nan  # a unit without a fit follows the lines
    noisy = truth + sd * rng.standard_normal((24, 2))
    free = PerUnitFit(names, units, noisy, cov, clone(jm))
    smooth = trend_fit(free, log, t, shared)
    # a level per log and one slope: far closer to the truth than the free values, the unfitted unit included
    err_free = np.abs(np.delete(noisy - truth, 5, axis=0)).mean(0)
    err_smooth = np.abs(smooth.values - truth).mean(0)
    assert np.all(err_smooth < 0.7 * err_free)
    assert np.allclose(smooth.values[5], truth[5], rtol=0.05)
    # exact lines are kept exactly, and the model's offsets are the values less the shared ones
    exact = trend_fit(PerUnitFit(names, units, truth, np.tile(np.diag(sd ** 2), (24, 1, 1)), clone(jm)), log, t,
                      shared)
    assert np.allclose(exact.values, truth, rtol=1e-9)
    assert np.allclose(exact.model.per_unit.offsets, truth - [shared["k"], shared["Fvs"]], rtol=1e-9)
    # one group along the order recorded: a trend from log to log
    order = np.arange(5.0)
    line = np.stack([shared["k"] * (1 - 0.04 * order), np.full(5, shared["Fvs"])], axis=1)
    per_log = PerUnitFit(names, Units(np.arange(5), np.arange(5), np.zeros(5)), line,
                         np.tile(np.diag(sd ** 2), (5, 1, 1)), clone(jm))
    assert np.allclose(trend_fit(per_log, np.zeros(5), order, shared).values, line, rtol=1e-9)

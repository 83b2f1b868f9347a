"""The scenario's ``profile`` field, the seed sweep axis and the pooling of seeds."""

from __future__ import annotations

import pytest

from cosim import api
from cosim.contract.figures import Figure
from cosim.record.sweep_report import largest_below, monotonic_within_spread, pool_replicates
from cosim.scenario.schema import ScenarioError, load_scenario, sweep_overrides
from cosim_plugins.profiles import LAB
from cosim_plugins.resources import SCENARIOS_DIR

SCENARIOS = SCENARIOS_DIR


def test_ideal_is_the_default_and_leaves_params_alone():
    s = load_scenario(SCENARIOS / "feedback_sweep.yaml")
    assert s.profile == "ideal"
    assert s.components["camera"].params == {"interval_s": 0.02, "noise_px": 0.5, "pixel_mm": 0.19,
                                             "outlier_prob": 0.002}


def test_lab_profile_sets_every_component_by_plugin_and_overrides_win():
    s = load_scenario(SCENARIOS / "feedback_sweep.yaml",
                      ["profile=lab", "components.camera.params.interval_s=0.1", "components.camera.params.noise_px=2"])
    cam = s.components["camera"].params
    assert cam["latency_s"] == LAB["camera.emulator"]["latency_s"] and cam["interval_s"] == 0.1
    assert cam["noise_px"] == 2  # an explicit override beats the profile
    assert s.components["estimator"].params["latency_s"] == cam["latency_s"]  # the filter knows its camera
    assert s.components["controller"].params["speed_mm_s"] == LAB["controller.pi"]["speed_mm_s"]
    assert s.components["plant"].params["background_flow_on"] is True


def test_a_sweep_axis_that_swaps_the_plugin_gets_that_plugins_profile_values():
    s = load_scenario(SCENARIOS / "controllers_racetrack.yaml",
                      ["profile=lab", "components.controller.plugin=controller.mpc",
                       'components.controller.params={"model": "sindy-linear"}'])
    assert s.components["controller"].params == {"model": "sindy-linear", **LAB["controller.mpc"]}


def test_unknown_profile_names_the_known_ones():
    with pytest.raises(ScenarioError, match="profile 'lob' unknown; known: ideal, lab"):
        load_scenario(SCENARIOS / "racetrack.yaml", ["profile=lob"])


def test_seed_and_profile_are_plain_sweep_axes():
    s = load_scenario(SCENARIOS / "racetrack.yaml", ["sweep={seed: [1, 2], profile: [ideal, lab]}"])
    combos = sweep_overrides(s)
    assert [labels for labels, _ in combos] == [{"seed": 1, "profile": "ideal"}, {"seed": 1, "profile": "lab"},
                                                {"seed": 2, "profile": "ideal"}, {"seed": 2, "profile": "lab"}]
    run = load_scenario(SCENARIOS / "racetrack.yaml", combos[3][1])
    assert run.seed == 2 and run.profile == "lab" and run.components["camera"].params["latency_s"] > 0


TRACKING = Figure("tracking_error_mm")


def _row(interval, seed, mean):
    return {"interval_s": interval, "seed": seed, "tracking_error_mm": {"mean": mean, "std": 0.1, "max": mean * 3},
            "status": "ok"}


def test_seeds_are_pooled_and_decide_the_largest_interval_and_monotonicity():
    rows = [_row(0.1, 1, 1.0), _row(0.1, 2, 1.2), _row(0.5, 1, 4.0), _row(0.5, 2, 4.2),
            _row(1.0, 1, 3.0), _row(1.0, 2, 3.2)]
    pooled = pool_replicates(rows, TRACKING)
    assert [r["interval_s"] for r in pooled] == [0.1, 0.5, 1.0]
    assert pooled[1]["tracking_error_mm"]["mean"] == pytest.approx(4.1)
    assert pooled[1]["tracking_error_mm"]["std"] == pytest.approx(0.1414, abs=1e-3)
    assert largest_below(rows, TRACKING, 4.6) == [{"axis": "interval_s", "largest_below": 1.0,
                                                   "figure": "tracking_error_mm", "threshold": 4.6}]
    assert largest_below(rows, TRACKING, 4.0)[0]["largest_below"] == 0.1
    (mono,) = monotonic_within_spread(pooled, "interval_s", TRACKING)
    assert not mono["monotonic"] and mono["drops"] == [[0.5, 1.0, 4.1, 3.1]]
    wide = [*rows[:4], _row(1.0, 1, 3.0), _row(1.0, 2, 6.0)]  # the drop lies within the seeds' spread
    assert monotonic_within_spread(pool_replicates(wide, TRACKING), "interval_s", TRACKING)[0]["monotonic"]


# ------------------------------------------------------------ the profile's own dataset and models

def test_lab_scenarios_train_their_models_on_the_lab_dataset():
    """The lab profile points the filter's and the MPC's on-demand models at the lab dataset."""
    s = load_scenario(SCENARIOS / "feedback_sweep.yaml", ["profile=lab"])
    assert s.components["estimator"].params["dataset"] == "lab"
    m = load_scenario(SCENARIOS / "controllers_racetrack.yaml",
                      ["profile=lab", "sweep={}", "components.controller.plugin=controller.mpc"])
    assert m.components["controller"].params["dataset"] == "lab"
    assert "dataset" not in load_scenario(SCENARIOS / "feedback_sweep.yaml").components["estimator"].params


def test_the_dataset_cache_key_includes_the_profile(monkeypatch, tmp_path):
    from cosim.contract.errors import UserError
    from cosim_plugins.paper import dataset

    monkeypatch.setenv("COSIM_CACHE", str(tmp_path))
    assert dataset.dataset_folder(True) == tmp_path / "paper_dataset_quick"
    assert dataset.dataset_folder(True, "lab") == tmp_path / "paper_dataset_quick_lab"
    assert dataset.profile_overrides("ideal") == [] and dataset.profile_overrides("lab") == ["profile=lab"]
    ideal, lab = dataset._fingerprint(True), dataset._fingerprint(True, "lab")
    assert ideal != lab
    # a changed lab value changes the key (the models trained on it are retrained)
    monkeypatch.setitem(LAB["camera.emulator"], "noise_px", LAB["camera.emulator"]["noise_px"] + 1.0)
    assert dataset._fingerprint(True, "lab") not in (ideal, lab)
    with pytest.raises(UserError, match="unknown"):
        api.profile_values("nosuch")

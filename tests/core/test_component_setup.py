"""setup_component: what a component is given at set-up (its parameters and dt, its path, its run folder)
and its private random generator: the same for the same seed and name, another for another of either."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cosim import ComponentError
from cosim.runtime.stepper import setup_component
from cosim.runtime.wiring import build_wiring
from cosim.scenario.schema import PathSpec, load_scenario

LOOP = Path(__file__).parent / "data" / "loop.yaml"


def recording(base, **flags):
    """A subclass of ``base`` keeping the parameters and the first draws of the generator it is set up with."""
    class Recording(base):
        original = base

        def setup(self, params, rng):
            self.params, self.draws = dict(params), rng.random(4)
            if params.get("fail"):
                raise ComponentError("refused on purpose")
            super().setup(params, rng)

    for key, value in flags.items():
        setattr(Recording, key, value)
    return Recording


@pytest.fixture
def loop(toy_plugins):
    scenario = load_scenario(LOOP)
    return scenario, build_wiring(scenario)


def set_up(loop, name="summer", seed=None, run_dir=None, **flags):
    scenario, wiring = loop
    if seed is not None:
        scenario.seed = seed
    cls = wiring.classes[name]
    wiring.classes[name] = recording(getattr(cls, "original", cls), **flags)
    return setup_component(scenario, wiring, name, run_dir)


def test_a_component_gets_its_params_and_the_scenarios_dt(loop):
    summer = set_up(loop)
    assert summer.params == {"dt": 0.02, "y0": 0.25}
    assert summer.initial_outputs()["y"].tolist() == [0.25]


def test_the_generator_is_fixed_by_the_seed_and_the_components_name(loop):
    first, again = set_up(loop).draws, set_up(loop).draws
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(set_up(loop, "gain").draws, first)  # another component: another stream
    assert not np.array_equal(set_up(loop, seed=1).draws, first)  # another seed: another stream


def test_a_component_that_needs_a_path_in_a_scenario_without_one_is_refused(loop):
    with pytest.raises(ComponentError) as err:
        set_up(loop, uses_path=True)
    assert str(err.value) == "component 'summer' (test.summer) needs a path; the scenario has none"


def test_a_component_that_writes_files_gets_the_run_folder_and_its_name(loop, tmp_path):
    summer = set_up(loop, run_dir=str(tmp_path), uses_run_dir=True)
    assert summer.params["run_dir"] == tmp_path and summer.params["name"] == "summer"
    assert summer.params["recording_id"] == loop[0].recording_id
    assert set_up(loop, uses_run_dir=True).params["run_dir"] is None


def test_a_refusal_at_set_up_names_the_component_and_its_plugin(loop):
    scenario, _ = loop
    scenario.components["gain"].params["fail"] = True
    with pytest.raises(ComponentError) as err:
        set_up(loop, "gain")
    assert str(err.value) == "components.gain (test.gain): refused on purpose"


def test_a_component_that_needs_a_path_gets_the_scenarios_path(loop):
    scenario, _ = loop
    scenario.path = PathSpec(plugin="circle", params={"radius_mm": 40.0, "center_mm": [0.0, 0.0, 5.0]})
    path = set_up(loop, uses_path=True).params["path"]
    assert type(path).__name__ == "Circle" and path.radius_mm == 40.0
    assert path.center.tolist() == [0.0, 0.0, 0.005]  # [m]
    assert "path" not in set_up(loop).params  # one that does not ask gets none


class _Plain:
    """A component written without the framework's base class: no uses_path, no uses_run_dir."""

    def setup(self, params, rng):
        self.params = dict(params)


def test_a_component_without_the_base_class_gets_neither_path_nor_run_folder(loop, tmp_path):
    scenario, wiring = loop
    scenario.path = PathSpec(plugin="circle", params={})
    wiring.classes["summer"] = _Plain
    summer = setup_component(scenario, wiring, "summer", tmp_path)
    assert summer.params == {"dt": 0.02, "y0": 0.25}

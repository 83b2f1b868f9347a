"""The wiring of a scenario, on the toy loop (data/loop.yaml): edges, step order, cycles, the printed
table and each wiring error, with the message it names."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.contract.errors import WiringError
from cosim.runtime.wiring import Edge, build_wiring, connection_table
from cosim.scenario.schema import load_scenario
from cosim_plugins.resources import SCENARIOS_DIR

LOOP = Path(__file__).parent / "data" / "loop.yaml"


def wiring_of(*overrides):
    scenario = load_scenario(LOOP, list(overrides))
    return scenario, build_wiring(scenario)


def test_edges_order_periods_and_delays_of_the_loop():
    _, w = wiring_of("components.summer.inputs.u.delay=2")
    assert w.edges == [Edge("gain", "u", "summer", "u", 2), Edge("summer", "y", "gain", "y", 0)]
    assert w.order == ["summer", "gain"]  # gain reads summer undelayed: summer first
    assert w.periods == {"summer": 1, "gain": 1}
    assert w.edges_into("gain") == [Edge("summer", "y", "gain", "y", 0)]
    assert w.max_delay() == 2 and w.max_delay("summer") == 2 and w.max_delay("gain") == 0
    assert w.unused_outputs() == []
    assert Edge("gain", "u", "summer", "u", 2).label() == "gain.u -> summer.u (delay 2)"
    assert Edge("summer", "y", "gain", "y", 0).label() == "summer.y -> gain.y"


def test_the_step_order_follows_undelayed_edges_else_the_scenarios_order():
    _, w = wiring_of("components.summer.inputs.u.delay=0", "components.gain.inputs.y.delay=1")
    assert w.order == ["gain", "summer"]  # summer reads gain undelayed now
    _, both = wiring_of("components.gain.inputs.y.delay=3")  # both delayed: as written
    assert both.order == ["summer", "gain"]


def test_a_cycle_without_a_delay_is_named_with_its_edges():
    with pytest.raises(WiringError) as err:
        wiring_of("components.summer.inputs.u.delay=0")
    assert str(err.value) == ("cycle without a delayed edge (mark one edge delay: 1): "
                              "gain.u -> summer.u; summer.y -> gain.y")


def test_the_connection_table():
    scenario, w = wiring_of("components.summer.inputs.u.delay=3")
    lines = connection_table(scenario, w).splitlines()
    assert lines[0] == "scenario loop: 2 components, dt 20 ms, 20 steps"
    assert lines[1].split() == ["signal", "from", "shape", "unit", "delay"]
    assert set(lines[2].replace(" ", "")) == {"-"}
    assert lines[3].split() == ["summer.u", "gain.u", "(1,)", "1", "3"]
    assert lines[4].split() == ["gain.y", "summer.y", "(1,)", "1", "0"]
    assert "step order: summer -> gain" in lines and "unused outputs: none" in lines
    scenario, slow = wiring_of("components.gain.period=2")
    assert "step order: summer -> gain (every 2 steps)" in connection_table(scenario, slow).splitlines()


@pytest.mark.parametrize("override, message", [
    ("components.summer.inputs={v: gain.u}", "components.summer.inputs.v: test.summer has no input 'v' (inputs: u)"),
    ("components.summer.inputs={u: gain.w}", "components.summer.inputs.u: gain has no output 'w' (outputs: u)"),
    ("components.summer.inputs={}", "components.summer.inputs: not wired: u"),
    ("components.gain.inputs.y.from=gain.u",
     "gain.u -> gain.y: a component feeding itself needs delay: 1"),
])
def test_wiring_errors_name_the_field(override, message):
    with pytest.raises(WiringError) as err:
        wiring_of(override)
    assert str(err.value) == message


def test_a_port_of_another_shape_or_unit_is_refused_and_unused_outputs_are_listed():
    with pytest.raises(WiringError) as err:
        wiring_of("components.plant={plugin: test.kinematic, inputs: {omega: gain.u}}")
    assert str(err.value) == "components.plant.inputs.omega: gain.u is (1,) [1] but plant.omega expects (3,) [rad/s]"
    scenario, w = wiring_of("components.probe={plugin: test.summer, inputs: {u: gain.u}}")
    assert w.unused_outputs() == ["probe.y"]
    assert "unused outputs: probe.y" in connection_table(scenario, w)


def test_more_wiring_details():
    """No edges: no delay; every class kept; a unit mismatch alone is refused too."""
    from cosim.runtime.wiring import Wiring

    assert Wiring({}, {}, {}, [], [], {}).max_delay() == 0
    _, w = wiring_of()
    assert sorted(w.classes) == ["gain", "summer"] and w.classes["gain"].__name__ == "Gain"
    with pytest.raises(WiringError) as err:
        wiring_of("components.volts={plugin: test.volt_gain, inputs: {y: summer.y}}",
                  "components.summer.inputs.u.from=volts.u")
    assert str(err.value) == "components.summer.inputs.u: volts.u is (1,) [V] but summer.u expects (1,) [1]"


def test_wiring_errors_list_every_port_and_name_bad_parameters_with_the_scenarios_period():
    racetrack = SCENARIOS_DIR / "racetrack.yaml"
    scenario = load_scenario(racetrack, ["components.coil_driver.inputs.omega=plant.spin"])
    with pytest.raises(WiringError) as err:
        build_wiring(scenario)
    outputs = ", ".join(p.name for p in build_wiring(load_scenario(racetrack)).outputs["plant"])
    assert str(err.value) == f"components.coil_driver.inputs.omega: plant has no output 'spin' (outputs: {outputs})"
    assert outputs.count(", ") >= 2
    daq = ["dt_s=0.01", "components.coil_driver.params.backend=daq", "components.coil_driver.params.daq_rate_hz=150"]
    with pytest.raises(WiringError) as err:
        build_wiring(load_scenario(racetrack, daq))
    assert str(err.value).startswith("components.coil_driver.params (coil_driver.inverse): daq_rate_hz=150 gives "
                                     "1.5 samples per 0.01 s tick")


def test_the_connection_table_lines_exactly():
    scenario, w = wiring_of()
    lines = connection_table(scenario, w).splitlines()
    assert lines[1:5] == ["signal    from      shape  unit  delay",
                          "--------  --------  -----  ----  -----",
                          "summer.u  gain.u    (1,)   1     1",
                          "gain.y    summer.y  (1,)   1     0"]
    assert lines[5] == "" and lines[6].startswith("step order: ")


def test_messages_list_several_ports_comma_separated():
    racetrack = SCENARIOS_DIR / "racetrack.yaml"
    with pytest.raises(WiringError) as err:
        build_wiring(load_scenario(racetrack, ["components.controller.inputs={speed: estimator.velocity}"]))
    assert str(err.value).startswith("components.controller.inputs.speed: controller.pi has no input 'speed' "
                                     "(inputs: position, velocity")
    with pytest.raises(WiringError) as err:
        build_wiring(load_scenario(racetrack, ["components.controller.inputs={}"]))
    assert str(err.value) == "components.controller.inputs: not wired: position, velocity"


def test_a_cycle_is_named_by_the_edges_among_what_is_left_not_those_into_it_or_delayed():
    """summer and gain in an undelayed loop; an adder fed by a source (ordered first) and by gain (so it waits on
    the loop too); a probe fed by gain over a delayed edge. The message lists the undelayed edges among the
    components left unordered: the loop's and gain's into the adder, never the source's edge into them, nor the
    delayed one (the probe, reading gain only a tick late, is ordered)."""
    with pytest.raises(WiringError) as err:
        wiring_of("components.summer.inputs.u.delay=0", "components.src={plugin: test.source}",
                  "components.adder={plugin: test.adder, inputs: {a: src.u, b: gain.u}}",
                  "components.probe={plugin: test.summer, inputs: {u: {from: gain.u, delay: 1}}}")
    assert str(err.value) == ("cycle without a delayed edge (mark one edge delay: 1): "
                              "gain.u -> summer.u; summer.y -> gain.y; gain.u -> adder.b")
    with pytest.raises(WiringError) as err:  # the delayed edge inside what is left: a loop of three, one edge delayed
        wiring_of("components.summer.inputs.u.delay=0", "components.adder={plugin: test.adder, inputs: "
                  "{a: gain.u, b: {from: summer.y, delay: 1}}}")
    assert str(err.value) == ("cycle without a delayed edge (mark one edge delay: 1): "
                              "gain.u -> summer.u; summer.y -> gain.y; gain.u -> adder.a")


def test_a_component_without_inputs_or_outputs_is_said_to_have_none():
    with pytest.raises(WiringError) as err:
        wiring_of("components.src={plugin: test.source, inputs: {y: summer.y}}")
    assert str(err.value) == "components.src.inputs.y: test.source has no input 'y' (inputs: none)"
    with pytest.raises(WiringError) as err:
        wiring_of("components.adder={plugin: test.adder, inputs: {a: gain.u, b: gain.u}}",
                  "components.summer.inputs.u.from=adder.u")
    assert str(err.value) == "components.summer.inputs.u: adder has no output 'u' (outputs: none)"


def test_the_table_of_a_run_until_stopped_and_of_several_unused_outputs():
    scenario, w = wiring_of("duration_s=null", "components.p1={plugin: test.summer, inputs: {u: gain.u}}",
                            "components.p2={plugin: test.summer, inputs: {u: gain.u}}")
    lines = connection_table(scenario, w).splitlines()
    assert lines[0] == "scenario loop: 4 components, dt 20 ms, until stopped"
    assert lines[-1] == "unused outputs: p1.y, p2.y"

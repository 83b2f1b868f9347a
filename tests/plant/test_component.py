"""FmuPlant through the component contract."""

from __future__ import annotations

import os

import numpy as np
import pluggy
import pytest

import cosim_plugins.plant as plant_plugin
from cosim.contract import hookspecs
from cosim.contract.component import Component, ComponentError
from cosim_plugins.plant.fmu_component import FmuPlant


def test_plugin_registers_plant_fmu():
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    pm.register(plant_plugin)
    found = {}
    pm.hook.cosim_register_components(register=lambda name, cls: found.setdefault(name, cls))
    assert found == {"plant.fmu": FmuPlant}


def test_ports_follow_the_contract():
    assert issubclass(FmuPlant, Component)
    ins = {p.name: (p.shape, p.unit) for p in FmuPlant.inputs}
    outs = {p.name: (p.shape, p.unit) for p in FmuPlant.outputs}
    assert ins == {"coil_voltage_amp": ((6,), "V"), "coil_voltage_phase": ((6,), "rad"), "drive_freq": ((), "Hz")}
    assert outs == {
        "position": ((3,), "m"), "velocity": ((3,), "m/s"), "axis": ((3,), "1"),
        "spin_rate": ((), "Hz"), "coil_current_amp": ((6,), "A"), "field": ((3,), "T"),
    }


@pytest.fixture
def plant(plant_fmu):
    p = FmuPlant()
    p.setup({"fmu": plant_fmu, "dt": 0.02, "p0_x": 0.01, "background_flow_on": True,
             "flow_y": 0.003}, np.random.default_rng(0))
    yield p
    p.close()


def test_setup_initial_outputs_step_close(plant, helpers):
    init = plant.initial_outputs()
    for port in FmuPlant.outputs:
        assert init[port.name].shape == port.shape
    assert np.allclose(init["position"], [0.01, 0, 0])
    assert np.allclose(init["axis"], [1, 0, 0])
    drive = helpers.rotating_drive([1, 0, 0], 3e-3, 10.0)
    at_zero = plant.step(0.0, drive)                     # t = 0: nothing to integrate
    assert np.array_equal(at_zero["position"], init["position"])
    out = {}
    for k in range(1, 51):
        out = plant.step(k * 0.02, drive)
    assert out["position"][0] > 0.02                     # swims along +x
    assert out["position"][1] > 0.001                    # carried by the flow
    assert out["spin_rate"] == pytest.approx(10.0, rel=0.02)
    assert np.linalg.norm(out["axis"]) == pytest.approx(1.0)
    assert np.linalg.norm(out["field"]) == pytest.approx(3e-3, rel=0.05)
    assert out["coil_current_amp"][2] == pytest.approx(3e-3 / helpers.PAIR_FIELD_PER_AMP, rel=0.02)
    again = plant.step(1.0, drive)                       # same time: same outputs
    assert np.array_equal(again["position"], out["position"])
    with pytest.raises(ComponentError, match="backwards"):
        plant.step(0.5, drive)
    unzip = plant._unzip_dir
    plant.close()
    plant.close()                                        # idempotent
    assert not os.path.exists(unzip)


def test_snapshot_restore_replays_identically(plant, helpers):
    drive = helpers.rotating_drive([0, 1, 0], 3e-3, 12.0)
    plant.step(0.2, drive)
    snap = plant.snapshot()
    first = [plant.step(0.2 + 0.02 * k, drive)["position"] for k in range(1, 11)]
    plant.restore(snap)
    second = [plant.step(0.2 + 0.02 * k, drive)["position"] for k in range(1, 11)]
    assert np.array_equal(np.array(first), np.array(second))


def test_unknown_parameter_lists_the_valid_ones(plant_fmu):
    p = FmuPlant()
    with pytest.raises(ComponentError) as exc:
        p.setup({"fmu": plant_fmu, "mas": 1e-5}, np.random.default_rng(0))
    p.close()
    msg = str(exc.value)
    assert "mas" in msg and "mass" in msg and "background_flow_on" in msg and "dt_internal" in msg


def test_parameter_types_are_checked(plant_fmu):
    p = FmuPlant()
    with pytest.raises(ComponentError, match="wall_drag_on"):
        p.setup({"fmu": plant_fmu, "wall_drag_on": "yes"}, np.random.default_rng(0))
    with pytest.raises(ComponentError, match="mass"):
        p.setup({"fmu": plant_fmu, "mass": "heavy"}, np.random.default_rng(0))
    p.close()


def test_a_missing_fmu_file_is_a_clear_error(tmp_path):
    from cosim import ComponentError
    from cosim_plugins.plant.fmu_component import FmuPlant

    missing = tmp_path / "lab_plant.fmu"
    with pytest.raises(ComponentError, match="no such FMU file"):
        FmuPlant().setup({"fmu": str(missing), "dt": 0.02}, None)
    assert not missing.exists()  # nothing was built in its place

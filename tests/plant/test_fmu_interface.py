"""The FMU as an FMI 2.0 artefact: description, defaults, errors, stepping."""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.validation import validate_fmu

from cosim.contract.component import ComponentError
from cosim_plugins.plant.fmu_component import FmuPlant

INPUTS = [f"V_amp_{i}" for i in range(1, 7)] + [f"V_phase_{i}" for i in range(1, 7)] + ["freq"]
OUTPUTS = (["p_x", "p_y", "p_z", "v_x", "v_y", "v_z", "axis_x", "axis_y", "axis_z", "spin_rate"]
           + [f"I_amp_{i}" for i in range(1, 7)] + ["B_x", "B_y", "B_z"])
SWITCHES = ["background_flow_on", "wall_drag_on", "gradient_force_on", "quadratic_drag_on",
            "anisotropic_drag_on", "actuation_lag_on", "heading_dynamics_on", "added_mass_on"]


class Raw:
    """A low-level fmpy instance that records the FMU's log messages."""

    def __init__(self, fmu_path):
        self.md = read_model_description(str(fmu_path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.dir = extract(str(fmu_path))
        self.log = []
        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(lambda env, inst, status, cat, msg: self.log.append(msg.decode()))
        self.cb = cb
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier="swimmer_plant", instanceName="raw")
        self.fmu.instantiate(callbacks=cb)
        self.fmu.setupExperiment(startTime=0.0)

    def close(self):
        self.fmu.freeInstance()
        shutil.rmtree(self.dir, ignore_errors=True)


@pytest.fixture
def raw(plant_fmu):
    r = Raw(plant_fmu)
    yield r
    r.close()


def test_validates_and_declares_the_agreed_interface(plant_fmu):
    assert validate_fmu(str(plant_fmu)) == []
    md = read_model_description(str(plant_fmu))
    assert md.coSimulation.modelIdentifier == "swimmer_plant"
    assert md.coSimulation.canHandleVariableCommunicationStepSize
    by_name = {v.name: v for v in md.modelVariables}
    assert all(by_name[n].causality == "input" and by_name[n].type == "Real" for n in INPUTS)
    assert all(by_name[n].causality == "output" for n in OUTPUTS)
    assert all(by_name[n].type == "Boolean" and by_name[n].causality == "parameter" for n in SWITCHES)
    for name in ["mass", "coil_turns", "coil_r_inner", "coil_r_outer", "cube_half", "R_coil",
                 "L_coil", "C_coil", "V_supply_max", "tank_half", "dt_internal", "p0_x", "axis0_z"]:
        assert by_name[name].causality == "parameter"
    assert float(by_name["mass"].start) == 12.4e-6
    assert float(by_name["coil_turns"].start) == 795
    assert float(by_name["V_supply_max"].start) == 40.0
    assert float(by_name["dt_internal"].start) <= 1e-3


def test_description_start_values_match_the_binary(raw):
    reals = [v for v in raw.md.modelVariables if v.type == "Real" and v.start is not None]
    values = raw.fmu.getReal([v.valueReference for v in reals])
    for v, got in zip(reals, values):
        assert got == float(v.start), v.name
    bools = [v for v in raw.md.modelVariables if v.type == "Boolean"]
    got = raw.fmu.getBoolean([v.valueReference for v in bools])
    for v, g in zip(bools, got):
        assert bool(g) == (v.start in (True, "true")), v.name


@pytest.mark.parametrize("name, value", [
    ("mass", 0.0), ("mass", -1e-6), ("coil_turns", 0.0), ("R_coil", -1.0), ("dt_internal", 0.0),
    ("dt_internal", -1e-3), ("coil_r_outer", 0.17), ("C_coil", 0.0), ("L_coil", -0.1),
    ("p0_x", 0.2), ("handedness", 0.5), ("rot_drag_axial", 0.0), ("V_supply_max", 0.0),
])
def test_out_of_range_parameter_is_an_error_naming_it(raw, name, value):
    raw.fmu.setReal([raw.vr[name]], [value])
    raw.fmu.enterInitializationMode()
    with pytest.raises(FMICallException) as exc:
        raw.fmu.exitInitializationMode()
    assert exc.value.status == 3  # fmi2Error
    assert any(name in m for m in raw.log), raw.log


def test_non_finite_values_are_rejected(raw):
    with pytest.raises(FMICallException):
        raw.fmu.setReal([raw.vr["mass"]], [math.nan])
    assert "mass" in raw.log[-1]
    raw.fmu.enterInitializationMode()
    raw.fmu.exitInitializationMode()
    with pytest.raises(FMICallException):
        raw.fmu.setReal([raw.vr["V_amp_3"]], [math.inf])
    assert "V_amp_3" in raw.log[-1]
    raw.fmu.doStep(0.0, 0.02)
    out = raw.fmu.getReal([raw.vr[n] for n in OUTPUTS])
    assert all(math.isfinite(x) for x in out)


def test_component_reports_the_fmu_message(plant_fmu):
    plant = FmuPlant()
    with pytest.raises(ComponentError, match="coil_turns"):
        try:
            plant.setup({"fmu": plant_fmu, "coil_turns": 0}, np.random.default_rng(0))
        finally:
            plant.close()
    plant = FmuPlant()
    plant.setup({"fmu": plant_fmu}, np.random.default_rng(0))
    bad = {"coil_voltage_amp": np.full(6, np.nan), "coil_voltage_phase": np.zeros(6), "drive_freq": np.array(5.0)}
    with pytest.raises(ComponentError, match="V_amp_1"):
        plant.step(0.02, bad)
    plant.close()


def test_one_long_step_equals_many_short_ones(raw):
    fmu, vr = raw.fmu, raw.vr
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    state = fmu.getFMUstate()
    drive = {"V_amp_3": 20.0, "V_amp_4": 20.0, "V_amp_5": 20.0, "V_amp_6": 20.0,
             "V_phase_5": -math.pi / 2, "V_phase_6": -math.pi / 2, "freq": 10.0}
    fmu.setReal([vr[n] for n in drive], list(drive.values()))
    fmu.doStep(0.0, 1.0)
    long = fmu.getReal([vr["p_x"], vr["p_y"], vr["p_z"]])
    fmu.setFMUstate(state)                                      # restores the inputs too
    fmu.setReal([vr[n] for n in drive], list(drive.values()))
    for k in range(50):
        fmu.doStep(k * 0.02, 0.02)
    short = fmu.getReal([vr["p_x"], vr["p_y"], vr["p_z"]])
    fmu.freeFMUstate(state)
    assert long[0] > 0.015                                      # it swam along +x
    # G, dG/dx are re-linearised every 0.25 mm and at step ends: agreement to 20 um
    assert np.allclose(long, short, atol=2e-5)
    with pytest.raises(FMICallException):                       # wrong communication point
        fmu.doStep(0.5, 0.02)


def test_fmpy_simulate_runs(plant_fmu):
    result = simulate_fmu(str(plant_fmu), stop_time=1.0, output_interval=0.02)
    assert len(result) == 51
    assert result["p_z"][-1] < 0                                # it sinks with the field off
    assert np.isfinite(result["p_z"]).all()

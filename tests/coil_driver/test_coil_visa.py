"""Backend ``visa`` against supplies simulated by pyvisa-sim: the SCPI sent, the state it leaves, the faults.

Each test drives the bridge itself (``InverseMagnetics`` with ``backend: visa``)
and reads the simulated supplies' state through sessions of its own.
"""

from __future__ import annotations

import numpy as np
import pytest
from coil_fakes import ADDRESSES, DT, STUCK, RecordingReference, spin

from cosim import ComponentError
from cosim_plugins.coil_driver.backends import Rig
from cosim_plugins.coil_driver.visa_backend import KepcoSupplies, parse_error


def visa_params(sim_supplies, addresses=ADDRESSES, **extra) -> dict:
    return {"backend": "visa", "visa_library": sim_supplies.library, "visa_resources": list(addresses),
            "watchdog_clock": "sim", **extra}


def test_configure_run_and_stop_leave_each_supply_in_the_state_they_command(make_driver, sim_supplies):
    assert sim_supplies.outputs() == [1] * 12  # the file's defaults differ from what the driver sets
    driver = make_driver(**visa_params(sim_supplies, i_trip_a=3.5))
    for address in ADDRESSES:  # configured: voltage mode on the external reference, limits, output off
        assert sim_supplies.query(address, "FUNC:MODE?") == "VOLT"
        assert sim_supplies.query(address, "VOLT:MODE?") == "EXT"
        assert float(sim_supplies.query(address, "VOLT:LIM?")) == 20.0  # v_max 40 V over two in series
        assert sim_supplies.query(address, "CURR:PROT:MODE?") == "FIX"
        assert float(sim_supplies.query(address, "CURR:PROT?")) == 3.5  # i_trip_a
        assert sim_supplies.query(address, "SYST:ERR?") == '0,"No error"'
    assert sim_supplies.outputs() == [0] * 12
    assert driver.rig.supplies.idn[0].startswith("KEPCO,BOP 20-50MG")

    for k in range(30):  # more than two rounds of read-backs (one supply per tick)
        out = driver.step(k * DT, {"omega": spin(8.0)})
        assert driver.fault is None and out["coil_voltage_amp"].max() > 0
    assert sim_supplies.outputs() == [1] * 12

    driver.close()
    assert sim_supplies.outputs() == [0] * 12
    assert driver.fault is None


def test_each_supply_session_answers_within_the_timeout_given(make_driver, sim_supplies):
    driver = make_driver(**visa_params(sim_supplies, visa_timeout_ms=1234))
    assert [res.timeout for res in driver.rig.supplies.supplies] == [1234] * 12  # [ms]


def test_the_reference_starts_before_the_outputs_go_on_and_ramps_before_they_go_off(make_driver, sim_supplies):
    seen = {}
    reference = RecordingReference([], on_start=lambda: seen.setdefault("start", sim_supplies.outputs()),
                                   on_stop=lambda: seen.setdefault("stop", sim_supplies.outputs()))
    supplies = KepcoSupplies(ADDRESSES, 2, sim_supplies.library, 20.0, 3.6, "BOP 20-50", 500, 12)
    driver = make_driver(rig=Rig(reference, supplies), watchdog_clock="sim")
    driver.step(0.0, {"omega": spin(8.0)})
    driver.close()
    assert seen == {"start": [0] * 12, "stop": [1] * 12}  # reference at zero while off; ramped while on
    assert sim_supplies.outputs() == [0] * 12


def test_an_error_in_a_supply_queue_stops_the_run_with_every_output_off(make_driver, sim_supplies):
    driver = make_driver(**visa_params(sim_supplies))
    omega = spin(8.0)
    driver.step(0.0, {"omega": omega})
    sim_supplies.write(ADDRESSES[6], "VOLT:BOGUS 1")  # an unknown command: -100 in its error queue
    for k in range(1, 6):  # supply 7 is read at tick 6
        driver.step(k * DT, {"omega": omega})
        assert driver.fault is None
    out = driver.step(6 * DT, {"omega": omega})
    assert driver.fault == ('supply_error: supply GPIB0::7::INSTR (coil -y, supply 1) reports -100,"Command error"')
    assert np.all(out["coil_voltage_amp"] == 0) and float(out["drive_freq"]) == 0
    assert sim_supplies.outputs() == [0] * 12


def test_a_measured_overcurrent_trips_and_switches_every_output_off(make_driver, sim_supplies):
    driver = make_driver(**visa_params(sim_supplies, i_trip_a=3.6))
    sim_supplies.write(ADDRESSES[2], "SIM:CURR -3.7")  # test-only: what MEAS:CURR? answers
    out = {}
    for k in range(3):
        out = driver.step(k * DT, {"omega": spin(8.0)})
    assert driver.fault == ("overcurrent: supply GPIB0::3::INSTR (coil -x, supply 1) measured -3.700 A "
                            "(trip 3.6 A)")
    assert np.all(out["coil_voltage_amp"] == 0)
    assert sim_supplies.outputs() == [0] * 12


def test_a_supply_that_stays_on_at_stop_is_a_fault_naming_it(make_driver, sim_supplies):
    addresses = [*ADDRESSES[:11], STUCK]
    driver = make_driver(**visa_params(sim_supplies, addresses))
    driver.step(0.0, {"omega": spin(8.0)})
    driver.close()
    assert driver.fault == ("supply_error: supply GPIB0::13::INSTR (coil -z, supply 2) still reports output '1' "
                            "after OUTP 0")
    assert sim_supplies.outputs(ADDRESSES[:11]) == [0] * 11  # every other supply was still switched off


@pytest.mark.filterwarnings("ignore:read string doesn't end with termination characters")
@pytest.mark.parametrize("params,message", [
    ({"visa_idn": "BOP 50-8"}, "backend 'visa': supply GPIB0::1::INSTR (coil +x, supply 1) identifies as "
                               "'KEPCO,BOP 20-50MG,SIM0001,4.12', expected 'BOP 50-8'"),
    ({"visa_resources": [*ADDRESSES[:11], "GPIB0::99::INSTR"]},
     "backend 'visa': supply GPIB0::99::INSTR (coil -z, supply 2) "),  # pyvisa-sim opens it, answers ''
])
def test_a_supply_that_is_not_the_expected_one_fails_the_set_up_naming_it(sim_supplies, params, message):
    from cosim_plugins.coil_driver.inverse import InverseMagnetics

    with pytest.raises(ComponentError) as err:
        InverseMagnetics().setup({"dt": DT, **visa_params(sim_supplies), **params}, np.random.default_rng(0))
    assert str(err.value).startswith(message) and "\n" not in str(err.value)
    if "visa_resources" in params:  # the supplies configured before the failure were left off
        assert sim_supplies.outputs(ADDRESSES[:11]) == [0] * 11


def test_parse_error_reads_the_queue_answer():
    assert parse_error('0,"No error"') == (0, "No error")
    assert parse_error('-222,"Data out of range"\n') == (-222, "Data out of range")
    assert parse_error("garbage")[0] == -1

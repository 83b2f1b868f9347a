"""``cosim run`` of the racetrack with the coil driver on simulated supplies (``backend: visa``).

The runs go through ``cosim.cli.main`` in this process, as pyvisa-sim's
supplies live in the process that simulates them: afterwards the test asks
each supply, as another client would, whether its output is off.
"""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from pathlib import Path

import pytest
from coil_fakes import ADDRESSES, STUCK, skip_if_ni_daqmx_installed
from recording_checks import recorded_events

from cosim.cli import main
from cosim_plugins.resources import SCENARIOS_DIR

RACETRACK = SCENARIOS_DIR / "racetrack.yaml"


def cosim_run(out: Path, sim_supplies, addresses=ADDRESSES, duration_s: float = 0.5, *extra: str) -> int:
    driver = "components.coil_driver.params"
    return main(["run", str(RACETRACK), "--out", str(out), "--quiet", "--set", f"duration_s={duration_s}",
                 "--set", f"{driver}.backend=visa", "--set", f"{driver}.visa_library={sim_supplies.library}",
                 "--set", f"{driver}.visa_resources={json.dumps(list(addresses))}",
                 # 1 s: a busy test machine must not trip the wall-clock watchdog between two steps
                 "--set", f"{driver}.watchdog_ticks=50", *extra])


def summary_of(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


def test_an_overcurrent_in_a_run_ends_it_with_a_named_fault_and_every_output_off(tmp_path, sim_supplies, capsys):
    sim_supplies.write(ADDRESSES[4], "SIM:CURR 5.0")  # test-only: supply 5 reads 5 A (it is read at tick 4)
    assert cosim_run(tmp_path, sim_supplies) == 2
    summary = summary_of(tmp_path)
    fault = "overcurrent: supply GPIB0::5::INSTR (coil +y, supply 1) measured 5.000 A (trip 3.6 A)"
    assert summary["status"] == "fault" and summary["steps"] == 5
    assert summary["error"] == f"component 'coil_driver': fault: {fault} (t = 0.080 s)"
    assert fault in capsys.readouterr().err
    assert len((tmp_path / "log.csv").read_text().splitlines()) == 1 + 5
    assert recorded_events(tmp_path / "recording.rrd") == [summary["error"]]
    assert sim_supplies.outputs() == [0] * 12


def test_a_supply_that_stays_on_when_the_run_ends_is_a_fault_of_the_run(tmp_path, sim_supplies):
    assert cosim_run(tmp_path, sim_supplies, [*ADDRESSES[:11], STUCK]) == 2
    summary = summary_of(tmp_path)
    fault = ("supply_error: supply GPIB0::13::INSTR (coil -z, supply 2) still reports output '1' after OUTP 0 "
             "(while closing)")
    assert summary["status"] == "fault" and summary["steps"] == 25  # every step ran
    assert summary["error"] == f"component 'coil_driver': fault: {fault}"
    assert recorded_events(tmp_path / "recording.rrd") == [summary["error"]]
    assert sim_supplies.outputs(ADDRESSES[:11]) == [0] * 11


def test_ctrl_c_stops_a_run_with_every_output_off(tmp_path, sim_supplies):
    """Ctrl-C once the log holds 20 rows (the run's signal handlers are in place by then). The watcher
    never gives up silently: past its deadline it interrupts the run anyway and the test fails naming why."""
    seen = {"rows": 0, "in_time": False}
    ended = threading.Event()  # the run returned by itself (an error): no signal then

    def interrupt_once_running():
        deadline = time.monotonic() + 120
        log = tmp_path / "log.csv"
        # log rows: the run (and its signal handlers) is under way
        while time.monotonic() < deadline and not ended.is_set():
            seen["rows"] = len(log.read_text().splitlines()) - 1 if log.is_file() else 0
            if seen["rows"] >= 20:
                seen["in_time"] = True
                break
            time.sleep(0.02)
        if not ended.is_set():
            os.kill(os.getpid(), signal.SIGINT)

    watcher = threading.Thread(target=interrupt_once_running, daemon=True)
    watcher.start()
    try:
        code = cosim_run(tmp_path, sim_supplies, ADDRESSES, 600.0)
    finally:
        ended.set()
    watcher.join()
    assert seen["in_time"], f"the run logged only {seen['rows']} rows before it ended or 120 s passed"
    assert code == 130
    summary = summary_of(tmp_path)
    assert summary["status"] == "interrupted" and summary["error"].startswith("stopped by SIGINT")
    assert 20 <= summary["steps"] < 30_000
    assert recorded_events(tmp_path / "recording.rrd") == ["stopped by SIGINT"]
    assert sim_supplies.outputs() == [0] * 12


@pytest.mark.parametrize("backend", ["daq", "visa+daq"])
def test_backend_daq_without_ni_daqmx_fails_the_run_in_one_line_naming_it(tmp_path, capsys, backend):
    skip_if_ni_daqmx_installed()
    code = main(["run", str(RACETRACK), "--out", str(tmp_path), "--quiet", "--set", "duration_s=0.1",
                 "--set", f"components.coil_driver.params.backend={backend}",
                 "--set", f"components.coil_driver.params.visa_resources={json.dumps(ADDRESSES)}",
                 "--set", "components.coil_driver.params.visa_library=nonexistent.yaml@sim"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert f"backend '{backend}': nidaqmx could not create a task: NI-DAQmx (NI's driver) is missing" in err
    assert summary_of(tmp_path)["status"] == "failed"

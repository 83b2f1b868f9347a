"""The lockstep loop end to end: outputs, determinism across process layouts, failures."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cosim.api import RunRequest, run
from cosim.runtime.scheduler import REPLY_BATCH, RunError
from cosim_plugins.raw_log import HEADER, read_log

DATA = Path(__file__).parent / "data"
TOY = DATA / "toy.yaml"
FAULTY = DATA / "faulty.yaml"


def test_run_writes_summary_log_trace_and_recording(tmp_path):
    summary = run(RunRequest(TOY, tmp_path, progress=False))
    assert set(summary["tracking_error_mm"]) == {"mean", "std", "max"}
    assert summary["steps"] == 200 and summary["sim_time_s"] == pytest.approx(4.0)
    assert summary["realtime_factor"] > 0 and summary["status"] == "ok"
    assert json.loads((tmp_path / "summary.json").read_text())["steps"] == 200
    assert (tmp_path / "log.csv").read_text().splitlines()[0] == HEADER
    log = read_log(tmp_path / "log.csv", outlier_mm=50.0)
    assert log.n == 200 and 0.3 < np.isnan(log.p_mm[:, 0]).mean() < 0.7  # frames every 40 ms, some dropped
    trace = np.load(tmp_path / "trace.npz")
    assert trace["plant.position"].shape == (200, 3) and trace["t_s"][-1] == pytest.approx(3.98)
    assert (tmp_path / "recording.rrd").stat().st_size > 1000


def test_same_seed_same_bytes_in_one_process_and_in_many(tmp_path):
    one = tmp_path / "one"
    again = tmp_path / "again"
    procs = tmp_path / "procs"
    run(RunRequest(TOY, one, progress=False))
    run(RunRequest(TOY, again, progress=False))
    run(RunRequest(TOY, procs, processes=True, progress=False))
    reference = (one / "log.csv").read_bytes()
    assert (again / "log.csv").read_bytes() == reference
    assert (procs / "log.csv").read_bytes() == reference
    other = tmp_path / "other"
    run(RunRequest(TOY, other, ["seed=4"], progress=False))
    assert (other / "log.csv").read_bytes() != reference


@pytest.mark.parametrize("mode,processes,message", [
    ("raise", False, "deliberate failure"),
    ("raise", True, "deliberate failure"),
    ("hang", False, "did not finish within 0.5 s (hung)"),
    ("hang", True, "did not finish within 0.5 s (hung)"),
    ("exit", True, "its process ended unexpectedly"),
])
def test_failing_component_is_named_and_the_record_so_far_is_kept(tmp_path, mode, processes, message):
    overrides = [f"components.relay.params.mode={mode}", "components.relay.timeout_s=0.5"]
    with pytest.raises(RunError) as err:
        run(RunRequest(FAULTY, tmp_path, overrides, processes=processes, progress=False))
    assert err.value.component == "relay" and message in str(err.value)
    summary = json.loads((tmp_path / "summary.json").read_text())
    # fails at t = 1 s: ticks 0-49 are kept, but a node that dies takes the steps it had not reported
    lost = REPLY_BATCH - 1 if mode == "exit" else 0
    assert summary["status"] == "failed" and 50 - lost <= summary["steps"] <= 50
    log = read_log(tmp_path / "log.csv", outlier_mm=50.0)
    assert log.n == summary["steps"]
    assert (tmp_path / "recording.rrd").is_file() and (tmp_path / "trace.npz").is_file()


def test_a_failed_set_up_with_processes_ends_the_nodes_still_starting(tmp_path):
    """The relay's set-up fails while another node is still in its own (60 s long): the run names the
    relay, and no node process of the run is left behind."""
    slow = "components.slow={plugin: test.faulty, params: {setup_s: 60}, inputs: {position: camera.position}}"
    with pytest.raises(RunError) as err:
        run(RunRequest(FAULTY, tmp_path, ["components.relay.params.mode=setup", slow], processes=True,
                       progress=False))
    assert err.value.component == "relay" and "deliberate set-up failure" in str(err.value)
    assert json.loads((tmp_path / "summary.json").read_text())["status"] == "failed"
    left = [p for p in Path("/proc").glob("[0-9]*") if str(tmp_path) in _cmdline(p)]
    assert left == []


def _cmdline(proc: Path) -> str:
    try:
        return (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


@pytest.mark.parametrize("processes", [False, True])
def test_a_fault_set_while_closing_is_the_run_outcome_named_in_summary_and_recording(tmp_path, processes):
    from recording_checks import recorded_events

    overrides = ["components.relay.params.mode=close_fault", "duration_s=0.5"]
    with pytest.raises(RunError) as err:
        run(RunRequest(FAULTY, tmp_path, overrides, processes=processes, progress=False))
    expected = "component 'relay': fault: deliberate fault on close (while closing)"
    assert str(err.value).startswith(expected)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "fault" and summary["error"] == expected and summary["steps"] == 25
    assert recorded_events(tmp_path / "recording.rrd") == [expected]


def test_a_failing_sweep_run_does_not_stop_the_others(tmp_path, capsys):
    from cosim.cli import main

    sweep = 'sweep={"components.relay.params.fail_at_s": [1.0, 100.0]}'
    assert main(["run", str(FAULTY), "--out", str(tmp_path), "--set", sweep, "--quiet"]) == 1
    rows = json.loads((tmp_path / "summary.json").read_text())["sweep"]
    assert [(r["fail_at_s"], r["status"]) for r in rows] == [(1.0, "failed"), (100.0, "ok")]
    assert "1 of 2 sweep runs did not finish" in capsys.readouterr().err


def test_a_smaller_sweep_into_the_same_folder_clears_the_earlier_runs(tmp_path, capsys):
    from cosim.cli import main

    three = 'sweep={"components.camera.params.interval_s": [0.02, 0.04, 0.06]}'
    one = 'sweep={"components.camera.params.interval_s": [0.08]}'
    common = ["run", str(TOY), "--out", str(tmp_path), "--set", "duration_s=0.4"]
    assert main([*common, "--set", three]) == 0
    assert len(list((tmp_path / "runs").iterdir())) == 3
    capsys.readouterr()
    assert main([*common, "--set", one, "--quiet"]) == 0
    out, err = capsys.readouterr()
    assert out == ""  # --quiet: no summary lines
    assert f"cleared 3 run folder(s) of an earlier sweep in {tmp_path / 'runs'}" in err
    assert [d.name for d in (tmp_path / "runs").iterdir()] == ["000_interval_s=0.08"]


def test_node_cpus_without_processes_is_an_error(tmp_path, capsys):
    from cosim.cli import main

    assert main(["run", str(TOY), "--out", str(tmp_path), "--node-cpus", "0"]) == 2
    assert "--node-cpus 0: only applies with --processes" in capsys.readouterr().err

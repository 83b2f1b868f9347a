"""Sweeps on several worker processes (``cosim run --jobs N``): same rows and logs as one after
another, a failing, crashing or hung run is one failed row, parallel runs' nodes on CPUs of their own."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from sweep_checks import FAULTY, TOY, logs_of, rows_of, stop_a_parallel_sweep, sweep_arg, without_timings

from cosim.cli import main
from cosim.scale.executors import cpu_groups

INTERVALS = sweep_arg({"components.camera.params.interval_s": [0.02, 0.04, 0.06, 0.08]})


def test_two_jobs_give_the_rows_and_logs_of_one_after_another(tmp_path):
    serial, parallel = tmp_path / "serial", tmp_path / "parallel"
    common = ["run", str(TOY), "--set", INTERVALS, "--set", "duration_s=1", "--quiet"]
    assert main([*common, "--out", str(serial)]) == 0
    assert main([*common, "--out", str(parallel), "--jobs", "2"]) == 0
    rows = rows_of(parallel)
    assert [r["interval_s"] for r in rows] == [0.02, 0.04, 0.06, 0.08]  # combination order
    assert without_timings(rows) == without_timings(rows_of(serial))
    assert all(r["status"] == "ok" and r["host"] and r["code"] and r["artifacts"] for r in rows)
    logs = logs_of(parallel)
    assert logs == logs_of(serial) and len(set(logs.values())) == 4  # four different runs, each as before


CASES = sweep_arg({"case": [
    {"label": "ok", "components.relay.params.fail_at_s": 100},
    {"label": "crash", "components.relay.params.mode": "exit", "components.relay.params.fail_at_s": 2.5},
    {"label": "raise", "components.relay.params.mode": "raise"},
    {"label": "hang", "components.relay.params.mode": "hang", "components.relay.timeout_s": 0.5},
    {"label": "ok2", "components.relay.params.fail_at_s": 100},
]})


def test_a_run_that_fails_crashes_or_hangs_is_one_failed_row_and_the_others_go_on(tmp_path, capsys):
    assert main(["run", str(FAULTY), "--out", str(tmp_path), "--set", CASES, "--jobs", "2", "--quiet"]) == 1
    rows = {r["case"]: r for r in rows_of(tmp_path)}
    assert list(rows) == ["ok", "crash", "raise", "hang", "ok2"]
    assert rows["ok"]["status"] == rows["ok2"]["status"] == "ok"
    assert rows["crash"]["status"] == "failed" and "worker process ended abruptly" in rows["crash"]["error"]
    assert rows["raise"]["status"] == "failed" and "deliberate failure" in rows["raise"]["error"]
    assert rows["hang"]["status"] == "failed" and "(hung)" in rows["hang"]["error"]
    assert "3 of 5 sweep runs did not finish" in capsys.readouterr().err
    # the crashed run's folder says so, with what it recorded before its process died (all but the last second)
    crashed = tmp_path / rows["crash"]["dir"]
    assert '"status": "failed"' in (crashed / "summary.json").read_text()
    assert (crashed / "log.csv").read_text().count("\n") > 50


def test_a_run_past_the_run_timeout_is_stopped_and_failed(tmp_path):
    sweep = sweep_arg({"components.camera.params.interval_s": [0.02, 0.04]})
    code = main(["run", str(TOY), "--out", str(tmp_path), "--set", sweep, "--realtime", "1", "--jobs", "2",
                 "--run-timeout", "2", "--quiet"])
    assert code == 1
    for row in rows_of(tmp_path):  # paced at real time, a 4 s run is stopped 2 s after its job started
        assert row["status"] == "failed" and "run timeout of 2 s" in row["error"]
        summary = json.loads((tmp_path / row["dir"] / "summary.json").read_text())
        log = (tmp_path / row["dir"] / "log.csv").read_text().splitlines()
        assert summary["status"] == "failed" and summary["steps"] < 200 and len(log) == summary["steps"] + 1


def test_a_run_that_ignores_the_timeout_has_its_process_killed(tmp_path, monkeypatch):
    import cosim.scale.sweep

    monkeypatch.setattr(cosim.scale.sweep, "GIVE_UP_GRACE_S", 1.0)
    sweep = sweep_arg({"case": [{"label": "stuck", "components.relay.params.mode": "hang",
                                 "components.relay.timeout_s": 600},
                                {"label": "ok", "components.relay.params.fail_at_s": 100}]})
    code = main(["run", str(FAULTY), "--out", str(tmp_path), "--set", sweep, "--jobs", "2",
                 "--run-timeout", "6", "--quiet"])
    assert code == 1
    stuck, ok = rows_of(tmp_path)
    assert stuck["status"] == "failed" and "its worker process was killed" in stuck["error"]
    assert ok["status"] == "ok", ok


def test_cpu_groups_are_disjoint_and_cover_the_cpus():
    cpus = os.sched_getaffinity(0)
    for n in range(1, len(cpus) + 1):
        groups = cpu_groups(n)
        assert len(groups) == n and set().union(*groups) == cpus
        assert sum(len(g) for g in groups) == len(cpus)  # disjoint
    assert len(cpu_groups(len(cpus) + 1)) == len(cpus) + 1  # more runs than CPUs: dealt round


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two CPUs")
def test_the_nodes_of_parallel_runs_with_processes_use_cpus_of_their_own(tmp_path):
    probe = Path(__file__).parent / "probe_plugins.py"
    code = main(["run", str(TOY), "--out", str(tmp_path), "--processes", "--jobs", "2", "--quiet",
                 "--set", "duration_s=0.4", "--set", f'plugins=["../toy_plugins.py", "{probe}"]',
                 "--set", "components.probe={plugin: test.cpu_probe}",
                 "--set", sweep_arg({"components.camera.params.interval_s": [0.02, 0.04]})])
    assert code == 0
    masks = [set(np.load(tmp_path / row["dir"] / "trace.npz")["probe.cpus"].astype(int)) for row in rows_of(tmp_path)]
    assert all(len(m) == 1 for m in masks)  # every step of a run's node on the same CPUs
    (first,), (second,) = masks
    assert first & second == 0 and first and second


def test_bad_jobs_and_executor_are_named(tmp_path, capsys):
    assert main(["run", str(TOY), "--out", str(tmp_path), "--jobs", "0"]) == 2
    assert "--jobs 0: expected a whole number >= 1 or auto" in capsys.readouterr().err
    assert main(["run", str(TOY), "--out", str(tmp_path), "--executor", "spark", "--set", INTERVALS]) == 2
    assert "--executor spark: expected local, dask or dask://HOST:PORT" in capsys.readouterr().err
    assert main(["run", str(TOY), "--out", str(tmp_path), "--processes", "--node-cpus", "1", "--jobs", "2"]) == 2
    assert "every parallel run's nodes would share these CPUs" in capsys.readouterr().err


def test_a_stopped_parallel_sweep_stops_its_runs_after_their_tick(tmp_path):
    code, rows = stop_a_parallel_sweep(tmp_path, "--jobs", "2")
    assert code == 130
    for row in rows:  # each run stopped within seconds of 30, its record kept
        assert row["status"] == "interrupted" and "stopped by SIGTERM" in row["error"]
        assert 50 < (tmp_path / row["dir"] / "log.csv").read_text().count("\n") < 1500

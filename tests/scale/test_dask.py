"""Sweeps on a Dask cluster (``--executor dask``): each run's folder comes back under ``--out`` with
the rows and logs of the serial sweep; a dead worker is one failed row; an unreachable scheduler is named."""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest
from sweep_checks import FAULTY, TOY, logs_of, rows_of, stop_a_parallel_sweep, sweep_arg, without_timings

from cosim.cli import main

pytest.importorskip("distributed", reason="the cluster extra (dask[distributed]) is not installed")


def test_a_sweep_on_a_local_dask_cluster_gives_the_serial_rows_and_logs(tmp_path):
    sweep = sweep_arg({"components.camera.params.interval_s": [0.02, 0.06, 0.1]})
    serial, dask = tmp_path / "serial", tmp_path / "dask"
    common = ["run", str(TOY), "--set", sweep, "--set", "duration_s=1", "--quiet"]
    assert main([*common, "--out", str(serial)]) == 0
    assert main([*common, "--out", str(dask), "--executor", "dask", "--jobs", "2"]) == 0
    rows = rows_of(dask)
    assert without_timings(rows) == without_timings(rows_of(serial))  # host and code fingerprint included
    assert logs_of(dask) == logs_of(serial)
    for row in rows:  # the whole run folder came back from the worker's scratch folder
        written = {f.name for f in (dask / row["dir"]).iterdir()}
        assert {"summary.json", "log.csv", "trace.npz", "recording.rrd"} <= written


def test_a_run_that_kills_its_dask_worker_is_one_failed_row(tmp_path):
    sweep = sweep_arg({"case": [{"label": "crash", "components.relay.params.mode": "exit"},
                                {"label": "ok", "components.relay.params.fail_at_s": 100}]})
    assert main(["run", str(FAULTY), "--out", str(tmp_path), "--set", sweep, "--executor", "dask", "--jobs", "2",
                 "--quiet"]) == 1
    crash, ok = rows_of(tmp_path)
    assert crash["status"] == "failed" and "Dask worker process died" in crash["error"]
    assert ok["status"] == "ok"
    assert '"status": "failed"' in (tmp_path / crash["dir"] / "summary.json").read_text()


def test_an_unreachable_dask_scheduler_is_named(tmp_path, capsys, monkeypatch):
    import cosim.scale.executors

    monkeypatch.setattr(cosim.scale.executors, "DASK_CONNECT_TIMEOUT_S", 1.0)
    sweep = sweep_arg({"components.camera.params.interval_s": [0.02, 0.04]})
    assert main(["run", str(TOY), "--out", str(tmp_path), "--set", sweep, "--executor", "dask://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err
    assert "--executor dask://127.0.0.1:9: no Dask scheduler answered at 127.0.0.1:9 within 1 s" in err


def test_a_stopped_sweep_stops_the_runs_on_its_dask_workers(tmp_path):
    code, rows = stop_a_parallel_sweep(tmp_path, "--executor", "dask", "--jobs", "2",
                                       scratch=Path(tempfile.gettempdir()))
    assert code == 130
    for row in rows:
        assert row["status"] == "interrupted" and "the sweep was interrupted" in row["error"]
        assert 50 < (tmp_path / row["dir"] / "log.csv").read_text().count("\n") < 1500

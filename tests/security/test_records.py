"""Paths and records: a scenario name is a plain name; a sweep removes only folders it made; a stale
recording part of another run is not merged; a write error stops the run with one line naming the file."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import pytest

from cosim.cli import main

ROOT = Path(__file__).resolve().parents[2]
TOY = ROOT / "tests" / "core" / "data" / "toy.yaml"


def _scenario(tmp_path: Path, name: str) -> Path:
    text = TOY.read_text().replace("name: toy", f"name: {json.dumps(name)}")
    text = text.replace("../toy_plugins.py", str(TOY.parent.parent / "toy_plugins.py"))
    path = tmp_path / "s.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("name", ["../../x", "/etc/x", "a/b", "..", ".hidden"])
def test_a_scenario_name_with_a_path_is_refused(tmp_path, capsys, name, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(_scenario(tmp_path, name)), "--set", "duration_s=0.1", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"name (line 1): Value error, {name!r} is not a plain name" in err, err
    assert not (tmp_path / "runs").exists() and not (tmp_path.parent / "x").exists()


def test_a_sweep_removes_only_the_folders_it_made(tmp_path, capsys):
    out = tmp_path / "out"
    sweep = ["--set", 'sweep={"seed": [1, 2]}', "--set", "duration_s=0.2", "--quiet"]
    assert main(["run", str(TOY), "--out", str(out), *sweep]) == 0
    mine = sorted(p.name for p in (out / "runs").iterdir())
    assert len(mine) == 2 and all((out / "runs" / m / ".cosim-sweep-run").is_file() for m in mine)
    keep = out / "runs" / "777_mine"  # a folder named like a run's, holding a summary, that no sweep made
    keep.mkdir()
    (keep / "summary.json").write_text("{}")
    assert main(["run", str(TOY), "--out", str(out), *sweep]) == 0
    assert (keep / "summary.json").read_text() == "{}"
    squatter = out / "runs" / mine[0]  # a folder where the sweep would write, not made by a sweep
    for f in squatter.iterdir():
        f.unlink()
    squatter.rmdir()
    squatter.mkdir()
    (squatter / "notes.txt").write_text("mine")
    assert main(["run", str(TOY), "--out", str(out), *sweep]) == 2
    assert f"{squatter} exists and was not made by a sweep: move it away" in capsys.readouterr().err
    assert (squatter / "notes.txt").read_text() == "mine"


def test_a_write_error_stops_the_run_naming_the_file_and_keeps_what_was_written(tmp_path, capsys, monkeypatch):
    """The trace's chunk file fills the disk after a few batches (as a full disk does: ENOSPC on write)."""
    from cosim.record.trace_files import CHUNKS_DIR, CURRENT, ChunkedTrace

    out = tmp_path / "run"
    written = ChunkedTrace.append
    calls = {"n": 0}

    def append(self, table):
        calls["n"] += 1
        if calls["n"] > 2:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        written(self, table)

    monkeypatch.setattr(ChunkedTrace, "append", append)
    assert main(["run", str(TOY), "--out", str(out), "--set", "duration_s=4", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    chunk = out / CHUNKS_DIR / CURRENT
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"cosim run: error: writing {chunk} failed: No space left on device "
                          "(the run stopped at t = "), err
    assert "while stepping; what was written before is kept" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["phase"] == "stepping"
    assert f"{CURRENT} failed: No space left on device" in summary["error"]
    rows = (out / "log.csv").read_text().splitlines()
    assert len(rows) > 1 and len(rows) - 1 == summary["steps"]  # the log kept every step the run took


def test_a_stale_recording_part_of_another_run_is_not_merged(tmp_path, capsys):
    first, out = tmp_path / "first", tmp_path / "run"
    assert main(["run", str(TOY), "--out", str(first), "--set", "duration_s=0.2", "--quiet"]) == 0
    out.mkdir()
    stale = (first / "recording.rrd").read_bytes()  # a recording of another run, as a component's part
    (out / "recording.camera.rrd").write_bytes(stale)
    assert main(["run", str(TOY), "--out", str(out), "--set", "duration_s=0.2", "--quiet"]) == 0
    assert "set aside 1 recording part(s) of an earlier run" in capsys.readouterr().err
    assert not (out / "recording.camera.rrd").exists()
    assert (out / "earlier.recording.camera.rrd").read_bytes() == stale
    assert (out / "recording.rrd").stat().st_size < 1.5 * len(stale)  # this run's alone, not merged with it

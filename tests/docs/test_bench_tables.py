"""The docs' measured tables are what the kept benchmark JSON renders: `tools/bench_tables.py` makes every
table marked `<!-- table: NAME -->`, from `docs/benchmarks/data/NAME.json`; a table typed over by hand, or
data changed without rendering again, fails here."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("bench_tables", ROOT / "tools" / "bench_tables.py")
bench_tables = importlib.util.module_from_spec(spec)
sys.modules["bench_tables"] = bench_tables  # its dataclasses look their module up
spec.loader.exec_module(bench_tables)


def test_every_marked_table_is_what_its_data_render():
    problems = bench_tables.stale()
    assert not problems, "\n".join(problems)


def test_every_data_file_has_its_header_and_is_used():
    used = {name for row in bench_tables.ROWS for name in row.data}
    used |= {"archive", "walkthrough_hidden_effects"} | {n for n, _ in bench_tables.DRIFT_SEEDS}
    used |= {n for n, _ in bench_tables.SEVERAL_SEEDS}
    used |= {n for names in bench_tables.SOAK_TABLES.values() for n in names}
    used |= {"sweep_jobs_reproduce_quick", "sweep_jobs_reproduce"} | set(bench_tables.TWIN_INJECT_TABLES.values())
    files = {p.stem: json.loads(p.read_text()) for p in bench_tables.DATA.glob("*.json")}
    assert used <= set(files), used - set(files)
    assert set(files) <= used, f"data no table renders: {set(files) - used}"
    for name, data in files.items():
        assert set(bench_tables.HEADER) <= set(data), name
        assert data["source"] == bench_tables.PRINTED or data["source"].startswith("transcribed from the page of "), \
            (name, data["source"])


def _stale_with(monkeypatch, name: str, edit) -> list[str]:
    """What the check says once data ``name`` reads with ``edit(output)`` applied (the file is left as it is)."""
    real = bench_tables.load

    def changed(which):
        data = real(which)
        if which == name:
            data = json.loads(json.dumps(data))
            edit(data["output"])
        return data

    monkeypatch.setattr(bench_tables, "load", changed)
    return bench_tables.stale()


def test_the_check_names_the_page_whose_table_a_figure_changed(monkeypatch):
    problems = _stale_with(monkeypatch, "archive", lambda o: o["runs"][-1].update(wall_s=o["runs"][-1]["wall_s"] + 0.1))
    assert any("docs/diagnose/drift.md: table diagnose-archive differs" in p for p in problems), problems
    assert any("docs/benchmarks.md: table benchmarks differs" in p for p in problems), problems  # archive's row
    assert not any("several-effects" in p for p in problems), problems


def test_a_changed_soak_figure_makes_the_long_runs_table_stale(monkeypatch):
    """The long-runs page's soak tables are rendered from the kept runs, every column of them."""
    problems = _stale_with(monkeypatch, "soak_processes_first",
                           lambda o: o["runs"][0].update(files_mb=o["runs"][0]["files_mb"] + 0.1))
    assert problems == ["docs/long-runs.md: table soak-hours-1-12 differs from its data; remake it: "
                        ".venv/bin/python tools/bench_tables.py"], problems


def test_an_unknown_or_missing_table_and_missing_data_are_named(monkeypatch, tmp_path):
    page = tmp_path / "page.md"
    page.write_text("<!-- table: no-such-table -->\n| a |\n<!-- /table -->\n")
    monkeypatch.setattr(bench_tables, "ROOT", tmp_path)
    monkeypatch.setattr(bench_tables, "PAGES", (".",))
    problems = bench_tables.stale()
    assert "page.md: unknown table no-such-table" in problems[0]
    assert any("table benchmarks is marked on no page" in p for p in problems)
    monkeypatch.setattr(bench_tables, "DATA", tmp_path / "data")
    with pytest.raises(SystemExit, match="record it"):
        bench_tables.load("plant")


def test_record_keeps_what_a_command_printed_under_a_header(monkeypatch, tmp_path):
    monkeypatch.setattr(bench_tables, "DATA", tmp_path)
    script = tmp_path / "fake_bench.py"
    script.write_text('import json\nprint(json.dumps({"wall_s": 0.5}))\nprint(json.dumps({"budget": 1}))\n')
    path = bench_tables.record("fake", [str(script)], "quiet")
    data = json.loads(path.read_text())
    assert data["output"] == [{"wall_s": 0.5}, {"budget": 1}] and data["machine_load"] == "quiet"
    assert data["source"] == bench_tables.PRINTED and data["date"] and data["command"] == str(script)

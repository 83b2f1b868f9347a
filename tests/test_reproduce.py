"""`cosim reproduce --quick --readme` end to end: every table of the report is filled with numbers, and
the README given gets those tables between its results markers, its plots beside it (the same run:
--readme costs nothing more)."""

from __future__ import annotations

import json
import re

from figure_checks import assert_labelled

from cosim.cli import main
from cosim_plugins.paper.report_format import filled
from cosim_plugins.paper.reproduce import README_END, README_START


def test_quick_reproduction_fills_every_table(tmp_path, monkeypatch, capsys, saved_figures):
    out = tmp_path / "report"
    readme = tmp_path / "project" / "README.md"
    readme.parent.mkdir()
    readme.write_text(f"# A project\n\n{README_START}\nstale results\n{README_END}\n\n## Next section\n")
    assert main(["reproduce", "--quick", "--out", str(out), "--readme", str(readme)]) == 0
    assert f"updated the results in {readme}" in capsys.readouterr().out
    md = (out / "report.md").read_text()
    text = readme.read_text()
    assert text.startswith("# A project\n") and text.endswith("## Next section\n") and "stale results" not in text
    block = text.split(README_START, 1)[1].split(README_END, 1)[0]
    assert "## Table II" in block and "## Table IV" in block  # the report's sections
    plots = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", block)
    assert plots and all((readme.parent / link).is_file() for link in plots)  # the figures beside the page
    for title in ("Table II", "Table III", "Table IV", "Fig. 6", "Fig. 3, Fig. 7"):
        assert f"## {title}" in md
    assert filled(md) == [], filled(md)
    # every body row of every table carries numbers, not placeholders
    lines = md.splitlines()
    rows = [ln for i, ln in enumerate(lines) if ln.startswith("| ") and i > 0
            and not re.fullmatch(r"\|(-+\|)+", lines[i + 1] if i + 1 < len(lines) else "")]
    assert len(rows) >= 4 + 3 * 4 + 4 + 4 * 4 + 5 + 3 + 3
    assert all(re.search(r"\d", ln) for ln in rows), [ln for ln in rows if not re.search(r"\d", ln)]
    report = json.loads((out / "report.json").read_text())
    assert report["quick"] is True and report["wall_time_s"] > 0
    assert "<table>" in (out / "report.html").read_text()
    assert list((out / "runs").rglob("recording.rrd"))
    assert any(name.startswith("paths_") for name in saved_figures)
    assert_labelled(saved_figures)
    assert "on this 2-core machine" not in md and f"{report['machine']['cpus']}-CPU machine" in md


def test_reproduce_names_a_missing_readme_before_running_anything(tmp_path, capsys):
    missing = tmp_path / "nowhere" / "README.md"
    assert main(["reproduce", "--quick", "--out", str(tmp_path / "report"), "--readme", str(missing)]) == 2
    assert f"--docs {missing} does not exist" in capsys.readouterr().err  # --readme is its other name
    assert not (tmp_path / "report").exists()

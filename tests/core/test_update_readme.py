"""`cosim reproduce --docs` copies the report's plots next to the results page: two profiles' plots
with the same file name (each profile's feedback sweep writes sweep_interval_s.png) must not
land on one asset, or the page shows the lab's figure under the ideal profile too."""

from __future__ import annotations

import json

from cosim_plugins.paper.reproduce import README_END, README_START, update_results


def test_plots_sharing_a_name_get_their_own_assets(tmp_path):
    report = tmp_path / "report"
    for run, content in (("feedback_sweep", b"ideal"), ("feedback_sweep_lab", b"lab")):
        (report / "runs" / run).mkdir(parents=True)
        (report / "runs" / run / "sweep_interval_s.png").write_bytes(content)
    (report / "report.md").write_text(
        "# Reproduction\n\n## Fig. 6\n\n### Profile: ideal\n\n"
        "![a (ideal)](runs/feedback_sweep/sweep_interval_s.png)\n\n"
        "### Profile: lab\n\n![a (lab)](runs/feedback_sweep_lab/sweep_interval_s.png)\n")
    (report / "report.json").write_text(json.dumps({"wall_time_s": 1.0}))
    readme = tmp_path / "results.md"
    readme.write_text(f"intro\n{README_START}\nold\n{README_END}\nend\n")
    update_results(report, readme, tmp_path / "results")
    text = readme.read_text()
    links = [line.split("](")[1].rstrip(")") for line in text.splitlines() if line.startswith("![")]
    assert len(links) == 2 and links[0] != links[1], links
    assert [(tmp_path / link).read_bytes() for link in links] == [b"ideal", b"lab"]
    assert text.startswith("intro\n") and text.endswith("end\n") and "old" not in text

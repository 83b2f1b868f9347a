"""A diagnosis rendered in one place (:mod:`cosim_plugins.diagnose.render`), checked against files the code
before the typed result wrote (milliseconds each, no fit).

``data/rendered/CASE/`` holds, for five diagnoses, the diagnosis.json, report.md and printed summary
(terminal.txt) that ``cosim diagnose`` wrote when the result was still a dict: two library effects chosen
stepwise with discovery finding nothing (fw), an effect added by hand (flow_add), a look-alike group with its
experiment and no drift test (late), drift between logs (drift), a discovered form (swirl). Each
diagnosis.json is read into the typed result and rendered again: every file must come out byte for byte.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from cosim_plugins.diagnose.render import markdown, terminal, to_json
from cosim_plugins.diagnose.result import DiagnosisResult, load
from cosim_plugins.identify.fit import json_default

RENDERED = Path(__file__).parent / "data" / "rendered"
CASES = ("fw", "flow_add", "late", "drift", "swirl")


def _case(name: str) -> tuple[str, DiagnosisResult]:
    text = (RENDERED / name / "diagnosis.json").read_text()
    return text, DiagnosisResult.from_json(json.loads(text))


@pytest.mark.parametrize("name", CASES)
def test_diagnosis_json_keeps_every_key_and_value(name):
    text, result = _case(name)
    assert json.dumps(to_json(result), indent=2, default=json_default) + "\n" == text


@pytest.mark.parametrize("name", CASES)
def test_the_printed_summary_and_report_read_as_before(name):
    _, result = _case(name)
    assert terminal(result) == (RENDERED / name / "terminal.txt").read_text()
    report = (RENDERED / name / "report.md").read_text()
    pngs = re.findall(r"!\[[^\]]*\]\(([^)]+\.png)\)", report)
    assert markdown(result, pngs) == report


def test_a_round_is_rendered_with_the_model_it_was_given():
    """A round run given a tentative step that was dropped later names that step, not the effects chosen before
    it (files that did not record the rounds' models render as before, above); the record survives
    diagnosis.json."""
    _, result = _case("fw")
    chosen = [st.effects[0] for st in result.stepwise.steps]
    result.stepwise.rounds_given = [[]] + [["quadratic_drag"]] * (len(result.stepwise.rounds) - 1)
    text = terminal(result)
    assert "round 2, given quadratic_drag:" in text and f"round 2, given {chosen[0]}:" not in text
    again = DiagnosisResult.from_json(json.loads(json.dumps(to_json(result), default=json_default)))
    assert again.stepwise.rounds_given == result.stepwise.rounds_given


def test_the_cases_cover_every_optional_section():
    """Each optional part of a result is in at least one case, so the checks above render it."""
    results = [_case(name)[1] for name in CASES]
    assert any(r.added for r in results) and any(r.reference for r in results)
    assert any(r.experiment for r in results) and any(st.group for r in results for st in r.stepwise.steps)
    assert any(r.discovered and r.discovered.status == "found" for r in results)
    assert any(r.discovered and r.discovered.status != "found" for r in results)
    assert any(r.drift.skipped for r in results) and any(r.drift.flagged for r in results)
    assert any(len(r.stepwise.steps) >= 2 for r in results)


def test_a_key_that_does_not_fit_is_named_with_where_it_is():
    _, result = _case("late")
    data = to_json(result)
    data["stepwise"]["joint"]["extra"] = 1
    with pytest.raises(ValueError, match=r"diagnosis.json.stepwise.joint: unknown key\(s\) extra for Joint"):
        DiagnosisResult.from_json(data)
    data = to_json(result)
    del data["verdict"]["status"]
    with pytest.raises(ValueError, match=r"diagnosis.json.verdict: missing key 'status' of Verdict"):
        load(DiagnosisResult, data)


def test_the_report_lists_each_effect_checked_again_once_the_drift_is_in():
    from cosim_plugins.diagnose.result import GivenDrift

    _, result = _case("drift")
    result.drift.given_drift = [GivenDrift(effect="wall_drag", reduction=0.02, t_stat=0.5, kept=False)]
    lines = markdown(result).splitlines()
    assert "- once the drift is in, wall_drag lowers the error by 2% (t = 0.5): dropped" in lines
    assert to_json(result)["drift"]["given_drift"] == [{"effect": "wall_drag", "reduction": 0.02, "t_stat": 0.5,
                                                        "kept": False}]

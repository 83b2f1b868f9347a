"""estimator.kf's parameters: the estimators page's table against the code, each bound from both sides,
and every malformed value refused with a message that names it (at validation, before any training)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest

from cosim import ComponentError
from cosim.contract.plugins import lookup
from cosim_plugins.estimators.kalman import PARAMS

PAGE = Path(__file__).resolve().parents[2] / "docs" / "estimators.md"
ROW = re.compile(r"^\| `(\w+)` \| `([^`]*)` \| ([^|]*) \| (.*) \|$", flags=re.M)


def page_rows() -> dict[str, tuple]:
    section = PAGE.read_text().split("## Parameters of `estimator.kf`", 1)[1]
    return {m[0]: (json.loads(m[1]), m[2].strip(), m[3].strip()) for m in ROW.findall(section)}


def validate(**params):
    lookup("component", "estimator.kf").validate_params(params)


def test_the_page_lists_every_parameter_with_its_default_range_and_meaning():
    rows = page_rows()
    assert list(rows) == list(PARAMS)
    for key, (default, span, doc) in rows.items():
        p = PARAMS[key]
        assert (default, doc) == (p.default, p.doc), key
        assert type(default) is type(p.default), key  # 2.0 is a float parameter, 3 a whole number
        bounds = [float(v) for v in span.split(" to ")] if span else [None, None]
        assert bounds == [p.lo, p.hi], key


NUMBERS = [key for key, p in PARAMS.items() if p.lo is not None]


@pytest.mark.parametrize("key", NUMBERS)
def test_each_bound_is_accepted_and_a_hair_beyond_it_refused(key):
    p = PARAMS[key]
    whole = isinstance(p.default, int)
    for bound, outside in ((p.lo, -1), (p.hi, 1)):
        validate(**{key: int(bound) if whole else bound})
        beyond = bound + outside if whole else math.nextafter(bound, outside * math.inf)
        with pytest.raises(ComponentError) as err:
            validate(**{key: beyond})
        assert str(err.value) == f"parameter {key}={beyond!r} out of range [{p.lo}, {p.hi}]"


@pytest.mark.parametrize("params, message", [
    ({"model": ""}, "parameter model='': expected a model file path or kind name"),
    ({"model": 3}, "parameter model=3: expected a model file path or kind name"),
    ({"dataset": ""}, "parameter dataset='': expected a profile name (ideal, lab, ...)"),
    ({"dataset": ["lab"]}, "parameter dataset=['lab']: expected a profile name (ideal, lab, ...)"),
    ({"q_logs": "runs/*.csv"}, "parameter q_logs='runs/*.csv': expected a list"),
    ({"q_diag": 1.0}, "parameter q_diag=1.0: expected a list"),
    ({"q_logs": ["a.csv", 3]}, "parameter q_logs: expected a list of file paths or glob patterns"),
    ({"q_diag": [1.0] * 5}, "parameter q_diag: expected 6 or 9 non-negative variances, got [1.0, 1.0, 1.0, 1.0, "
                            "1.0]"),
    ({"q_diag": [1.0] * 8 + [-1.0]}, "parameter q_diag: expected 6 or 9 non-negative variances, got "
                                     "[1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, -1.0]"),
    ({"q_diag": [1.0] * 8 + ["1"]}, "expected 6 or 9 non-negative variances"),
    ({"q_diag": [1.0] * 6}, "parameter q_diag has 6 entries but drift is True: give 9 with drift, 6 without"),
    ({"q_diag": [1.0] * 9, "drift": False},
     "parameter q_diag has 9 entries but drift is False: give 9 with drift, 6 without"),
    ({"max_rejects": 2.5}, "max_rejects and relinearize_steps must be whole numbers"),
    ({"relinearize_steps": 1.5}, "max_rejects and relinearize_steps must be whole numbers"),
])
def test_a_malformed_parameter_is_refused_by_name(params, message):
    with pytest.raises(ComponentError) as err:
        validate(**params)
    assert message in str(err.value)


@pytest.mark.parametrize("params", [
    {"q_diag": [0, 0, 0, 1, 1, 1, 0.5, 0.5, 0.5]},  # zeros and whole numbers are variances too
    {"q_diag": [0.0] * 6, "drift": False},
    {"max_rejects": 0, "relinearize_steps": 1.0},  # 1.0 is a whole number
    {"q_logs": ["runs/*/log.csv", "lab/a.csv"]},
])
def test_well_formed_parameters_pass(params):
    validate(**params)

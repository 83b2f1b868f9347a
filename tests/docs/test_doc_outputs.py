"""The docs show what the commands print today: every marked output is one `tools/doc_outputs.py`
makes; the quick ones are re-run and compared (wall-clock figures masked); the slow ones must
have been made from the code as it is (the digest in their marker)."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("doc_outputs", ROOT / "tools" / "doc_outputs.py")
doc_outputs = importlib.util.module_from_spec(spec)
sys.modules["doc_outputs"] = doc_outputs  # its dataclasses look their module up
spec.loader.exec_module(doc_outputs)

USED = doc_outputs.used_blocks()
QUICK = [name for name, block in doc_outputs.BLOCKS.items() if not block.slow]
SLOW = [name for name, block in doc_outputs.BLOCKS.items() if block.slow]
REMAKE = ".venv/bin/python tools/doc_outputs.py"


def shown(name: str) -> list[tuple[Path, str]]:
    """Every page showing output ``name``, with what its marker holds (and its marker's digest)."""
    out = []
    for page in USED[name]:
        for match in doc_outputs.MARK.finditer(page.read_text()):
            if match["name"] == name:
                out.append((page, match))
    return out


def test_every_marked_output_is_known_and_every_known_one_is_shown():
    assert set(USED) == set(doc_outputs.BLOCKS), (set(USED) ^ set(doc_outputs.BLOCKS))
    for name in USED:
        for page, match in shown(name):
            assert match["body"].startswith("```text\n$ "), f"{page}: output {name} was never made: run {REMAKE} {name}"


@pytest.mark.parametrize("name", SLOW)
def test_slow_outputs_were_made_from_the_code_as_it_is(name):
    now = doc_outputs.digest(doc_outputs.BLOCKS[name])
    for page, match in shown(name):
        assert match["digest"] == now, (
            f"{page.relative_to(ROOT)}: output {name} is stale (the code it shows changed since it was made); "
            f"remake it: {REMAKE} {name}")


def test_quick_outputs_are_what_the_commands_print_today():
    fresh = doc_outputs.make(QUICK)
    for name in QUICK:
        for page, match in shown(name):
            assert doc_outputs.mask(match["body"]) == doc_outputs.mask(fresh[name]), (
                f"{page.relative_to(ROOT)}: output {name} is stale; remake it: {REMAKE} --quick")


def test_the_check_fails_on_a_changed_output():
    """The comparison the test above makes sees a changed figure, and masks only wall-clock ones."""
    text = "1500 steps, 30.0 s simulated in 2.1 s (14x real time)\ntracking error: 0.42 mm"
    assert doc_outputs.mask(text) == doc_outputs.mask(text.replace("2.1 s (14x", "3.9 s (8x"))
    assert doc_outputs.mask(text) != doc_outputs.mask(text.replace("0.42", "0.43"))
    assert re.search("digest=", doc_outputs.marker(SLOW[0]))

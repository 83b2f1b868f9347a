"""`cosim dataset --quick` end to end: it lists the three splits' raw logs, each readable and of the
documented length, and a second call reuses the cache (the files are not written again).

It shares the quick dataset's cache with the estimator tests (``$COSIM_CACHE`` or ./cache), so the
suite generates it once.
"""

from __future__ import annotations

import re
from pathlib import Path

from cosim.cli import main
from cosim_plugins.paper.dataset import QUICK_DURATION_S, TEST_DURATION_S
from cosim_plugins.raw_log import read_log

DT_S = 0.02


def _listing(text: str) -> dict[str, list[Path]]:
    """{split: [log paths]} from the command's output."""
    splits, current = {}, None
    for line in text.splitlines():
        head = re.fullmatch(r"(\w+) \((\d+) logs\):", line)
        if head:
            current = head[1]
            splits[current] = []
        elif line.startswith("  ") and current:
            splits[current].append(Path(line.strip()))
    return splits


def test_cosim_dataset_lists_readable_logs_and_reuses_its_cache(capsys):
    assert main(["dataset", "--quick"]) == 0
    first = capsys.readouterr().out
    splits = _listing(first)
    assert list(splits) == ["training", "test", "validation"]
    rows = {"training": QUICK_DURATION_S / DT_S, "test": TEST_DURATION_S[1] / DT_S,
            "validation": QUICK_DURATION_S / DT_S}
    for split, files in splits.items():
        assert files, split
        header = re.search(rf"^{split} \((\d+) logs\):$", first, flags=re.M)
        assert int(header[1]) == len(files)
        for path in files:
            log = read_log(path)
            assert log.n == round(rows[split]), (path, log.n)
            assert log.valid.mean() > 0.5  # mostly measured rows
    written = {path: path.stat().st_mtime_ns for files in splits.values() for path in files}
    assert main(["dataset", "--quick"]) == 0
    again = capsys.readouterr().out
    assert _listing(again) == splits and again.startswith("training (")  # nothing generated this time
    assert {path: path.stat().st_mtime_ns for path in written} == written  # reused, not regenerated

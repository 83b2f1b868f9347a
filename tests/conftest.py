"""Shared fixtures: a throwaway plugin registered like any external one; how parallel workers share the tests.

``make test`` runs the suite on every core (pytest-xdist, ``-n auto --dist loadscope``). Each worker
takes whole folders of ``tests/`` (so a folder's session fixtures, recorded plant logs or trained
models, are made once) or a module of :data:`OWN_WORKER` (an expensive fixture of its own, none of the
folder's shared ones). Work units are handed out longest first: those of :data:`FIRST` in its order
(measured), then the others by their number of tests. xdist's own reordering (by number of tests
alone) is off: it put ``tests/core``'s many quick tests before the diagnoses of minutes.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hang_guard import pytest_runtest_protocol  # noqa: F401  (a hook: COSIM_TEST_TIMEOUT ends a hung test)

from cosim.contract import plugins

OWN_WORKER = ("tests/diagnose/test_blind.py", "tests/diagnose/test_lookalike.py", "tests/diagnose/test_drift.py")
#: the longest units, longest first (``--durations`` on 25 Nov 2026, loaded 2-core machine): the folder's plant
#: variants and the diagnoses on them (~2250 s of test time), the blind cases (~1600 s), the look-alike's runs
#: (~700 s), ``tests/test_reproduce.py`` (one test, ~670 s), the docs' outputs (~310 s), the drift logs (~100 s)
FIRST = ("tests/diagnose", "tests/diagnose/test_blind.py", "tests/diagnose/test_lookalike.py", "tests",
         "tests/docs", "tests/diagnose/test_drift.py")


def work_unit(nodeid: str) -> str:
    """The work unit of a test: its module if in :data:`OWN_WORKER`, else its folder."""
    path = nodeid.split("::", 1)[0]
    return path if path in OWN_WORKER else path.rsplit("/", 1)[0]


def pytest_collection_modifyitems(config, items):
    """The longest work first (every worker collects the same order): the units of :data:`FIRST` in its
    order, then the others by their number of tests, most first; a unit's tests stay together, in the
    order collected."""
    count: dict[str, int] = {}
    for item in items:
        count[work_unit(item.nodeid)] = count.get(work_unit(item.nodeid), 0) + 1

    def rank(item):
        unit = work_unit(item.nodeid)
        return (FIRST.index(unit), 0, "") if unit in FIRST else (len(FIRST), -count[unit], unit)

    items.sort(key=rank)  # stable: the collection order within each unit


def pytest_xdist_make_scheduler(config, log):
    """With ``--dist loadscope``: a work unit is a folder of ``tests/`` or a module of :data:`OWN_WORKER`,
    handed out in the collection's order (see :func:`pytest_collection_modifyitems`)."""
    if config.getvalue("dist") != "loadscope":
        return None
    from xdist.scheduler import LoadScopeScheduling

    config.option.loadscopereorder = False  # xdist's order (most tests first) would undo the one above

    class FolderScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return work_unit(nodeid)

    return FolderScheduling(config, log)


@pytest.fixture
def toy_plugins():
    """Register tests/core/toy_plugins.py for one test, then forget it."""
    plugins.reset()
    plugins.load_plugin_file(Path(__file__).parent / "core" / "toy_plugins.py")
    yield
    plugins.reset()



@pytest.fixture
def saved_figures(monkeypatch):
    """{file name: figure_labels(fig)} of every matplotlib figure saved while the test runs."""
    from figure_checks import spy_on_savefig
    from matplotlib.figure import Figure

    seen: dict = {}
    monkeypatch.setattr(Figure, "savefig", spy_on_savefig(Figure.savefig, seen))
    return seen

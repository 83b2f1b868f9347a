"""Shared fixtures: a throwaway plugin registered like any external one; how parallel workers share the tests.

``make test`` runs the suite on every core (pytest-xdist, ``-n auto --dist loadscope``). Each worker
takes whole folders of ``tests/`` (so a folder's session fixtures, recorded plant logs or trained
models, are made once) or a module of :data:`OWN_WORKER` (an expensive fixture of its own); the
folders of :data:`FIRST` are handed out first, so the longest work starts at once.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hang_guard import pytest_runtest_protocol  # noqa: F401  (a hook: COSIM_TEST_TIMEOUT ends a hung test)

from cosim.contract import plugins

OWN_WORKER = ("tests/diagnose/test_blind.py",)
FIRST = ("tests/diagnose/test_blind.py", "tests/diagnose")


def pytest_collection_modifyitems(config, items):
    """The longest work first (every worker collects the same order)."""
    def rank(item):
        return next((i for i, p in enumerate(FIRST) if item.nodeid.startswith(p)), len(FIRST))

    items.sort(key=rank)  # stable: the collection order within each rank


def pytest_xdist_make_scheduler(config, log):
    """With ``--dist loadscope``: a work unit is a folder of ``tests/`` or a module of :data:`OWN_WORKER`."""
    if config.getvalue("dist") != "loadscope":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class FolderScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            return path if path in OWN_WORKER else path.rsplit("/", 1)[0]

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

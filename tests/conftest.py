"""Shared fixtures: a throwaway plugin registered like any external one."""

from __future__ import annotations

import pytest

from cosim.contract import plugins


@pytest.fixture
def toy_plugins():
    """Register tests/core/toy_plugins.py for one test, then forget it."""
    from pathlib import Path

    plugins.reset()
    plugins.load_plugin_file(Path(__file__).parent / "core" / "toy_plugins.py")
    yield
    plugins.reset()



@pytest.fixture
def saved_figures(monkeypatch):
    """{file name: figure_labels(fig)} of every matplotlib figure saved while the test runs."""
    from matplotlib.figure import Figure

    from figure_checks import spy_on_savefig

    seen: dict = {}
    monkeypatch.setattr(Figure, "savefig", spy_on_savefig(Figure.savefig, seen))
    return seen

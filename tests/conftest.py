"""Shared fixtures: a throwaway plugin registered like any external one."""

from __future__ import annotations

import pytest

from cosim import plugins


@pytest.fixture
def toy_plugins():
    """Register tests/core/toy_plugins.py for one test, then forget it."""
    from pathlib import Path

    plugins.reset()
    plugins.load_plugin_file(Path(__file__).parent / "core" / "toy_plugins.py")
    yield
    plugins.reset()

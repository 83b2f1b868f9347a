"""The DC motor example's package, imported from its folder as its plugin file does."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).parents[2] / "examples" / "dc_motor"


@pytest.fixture(scope="session")
def dc_motor():
    """The package ``cosim_example_dc_motor`` (examples/dc_motor), without registering its plugin."""
    spec = importlib.util.spec_from_file_location("dc_motor_example_plugin", EXAMPLE / "plugin.py")
    plugin = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(plugin)
    return importlib.import_module(plugin.PACKAGE)

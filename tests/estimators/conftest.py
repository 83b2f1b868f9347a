"""Fixtures for the estimator tests: the short paper dataset, a user's linear model kind."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.contract import plugins

HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="package", autouse=True)
def quick_dataset():
    """Models named by kind and the default Q logs come from the short paper dataset."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("COSIM_DATASET", "quick")
        yield


@pytest.fixture
def linear_kinds():
    """Register tests/estimators/linear_plugin.py (kinds test-linear, test-small) for one test."""
    plugins.reset()
    plugins.load_plugin_file(HERE / "linear_plugin.py")
    yield
    plugins.reset()

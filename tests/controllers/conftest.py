"""Fixtures for the controller tests: the short dataset for on-demand models, a scenario runner."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.api import RunRequest, run


@pytest.fixture(scope="package", autouse=True)
def quick_dataset():
    """Models named by kind (``sindy-linear``) are trained on the short paper dataset."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("COSIM_DATASET", "quick")
        yield


@pytest.fixture(scope="package")
def run_scenario(tmp_path_factory):
    """``run_scenario(file, *overrides) -> (summary, out_dir)``; runs one combination (no sweep)."""

    def _run(file, *overrides):
        out = tmp_path_factory.mktemp("run")
        summary = run(RunRequest(Path(file), out, ["sweep={}", *overrides], progress=False))
        return summary, out

    return _run

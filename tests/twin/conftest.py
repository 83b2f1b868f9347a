"""Fixtures for the twin tests: one plant FMU built from this checkout's sources per session."""

from __future__ import annotations

import pytest

from cosim_plugins.plant.build import ENV_FMU, build_fmu


@pytest.fixture(scope="session")
def twin_fmu(tmp_path_factory):
    """The FMU built once from the current sources (never the user cache's)."""
    return build_fmu(tmp_path_factory.mktemp("fmu") / "swimmer_plant.fmu")


@pytest.fixture
def use_fmu(twin_fmu, monkeypatch):
    """Runs in this test use the session's FMU (``COSIM_FMU``)."""
    monkeypatch.setenv(ENV_FMU, str(twin_fmu))
    return twin_fmu

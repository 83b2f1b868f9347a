"""Fixtures for the coil driver: a driver factory and the simulated supplies."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from coil_fakes import DATA, DT, SimSupplies

from cosim_plugins.coil_driver.backends import Rig
from cosim_plugins.coil_driver.inverse import InverseMagnetics


@pytest.fixture
def make_driver():
    """``make_driver(rig=None, **params) -> InverseMagnetics`` set up with ``dt`` = 20 ms; closed after the test."""
    made = []

    def _make(rig: Rig | None = None, **params):
        driver = InverseMagnetics()
        driver.setup({"dt": DT, **params}, np.random.default_rng(0), rig=rig)
        made.append(driver)
        return driver

    yield _make
    for driver in made:
        driver.close()


@pytest.fixture
def sim_supplies(tmp_path) -> SimSupplies:
    """The simulated supplies of a private copy of the device file (fresh state for each test)."""
    path = tmp_path / "kepco_bop.yaml"
    shutil.copy(DATA / "kepco_bop.yaml", path)
    return SimSupplies(path)

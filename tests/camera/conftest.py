"""Shared scenes for the camera tests: the renderer's cameras and frames drawn on demand."""

from __future__ import annotations

import numpy as np
import pytest

from cosim_plugins.camera.sources.render import Look, Renderer, acA800_pair


@pytest.fixture(scope="session")
def cameras():
    """The renderer's exact acA800 pair."""
    return acA800_pair()


@pytest.fixture
def draw(cameras):
    """``draw(top_bodies, side_bodies, **look)``: one frame pair, each body (centre [m], axis, contrast)."""

    def _draw(top, side, **look):
        renderer = Renderer(cameras, Look(**look), np.random.default_rng(0))
        return renderer.draw(0, top), renderer.draw(1, side)

    return _draw

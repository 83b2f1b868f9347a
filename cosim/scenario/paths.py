"""A scenario's reference path: built by name (:func:`make_path`) and the distance of a trajectory to it.

What a path plugin implements is :class:`cosim.contract.paths.ReferencePath`
(registered through the ``cosim_register_paths`` hook).
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from cosim.contract.errors import UserError
from cosim.contract.paths import ReferencePath
from cosim.contract.plugins import lookup


def distance_to_path(path: ReferencePath, positions_m: np.ndarray, times_s: np.ndarray | None = None) -> np.ndarray:
    """Distance [m] from each position (n, 3) to the path polyline (at each time if it moves); (n,)."""
    positions_m = np.asarray(positions_m, dtype=float)
    out = np.full(len(positions_m), np.nan)
    if not path.time_varying:
        pts = path.points(0.0)
        for start in range(0, len(positions_m), 512):
            chunk = positions_m[start : start + 512]
            d2 = ((chunk[:, None, :] - pts[None, :, :]) ** 2).sum(axis=2)
            out[start : start + 512] = np.sqrt(d2.min(axis=1))
        return out
    for i, (p, t) in enumerate(zip(positions_m, times_s)):
        out[i] = np.sqrt(((path.points(float(t)) - p) ** 2).sum(axis=1).min())
    return out


def make_path(plugin: str, params: Mapping[str, Any] | None = None) -> ReferencePath:
    """Build the registered path ``plugin`` with ``params``; errors name the path and parameter."""
    factory = lookup("path", plugin)
    try:
        return factory(**dict(params or {}))
    except TypeError as exc:
        raise UserError(f"path {plugin!r}: bad parameters: {exc}") from None
    except ValueError as exc:
        raise UserError(f"path {plugin!r}: {exc}") from None

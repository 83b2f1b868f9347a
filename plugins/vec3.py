"""Helpers for single 3-vectors, where numpy's per-call overhead is the whole cost.

Components run these on (3,) arrays every 20 ms tick, on the critical path of
the loop. ``np.linalg.norm(v)`` costs ~1.6 us on a (3,) array,
``np.all(np.isfinite(v))`` ~3.5 us and ``np.cross`` ~20 us, nearly all of it
dispatch; these give the same values in a fraction of that. Large arrays
should stay vectorised with numpy.
"""

from __future__ import annotations

import math

import numpy as np


def norm(v: np.ndarray) -> float:
    """Euclidean norm of a 1-D float array: the same value as ``np.linalg.norm(v)``
    (which computes ``sqrt(v.dot(v))``), as a Python float."""
    return math.sqrt(v.dot(v))


def all_finite(v: np.ndarray) -> bool:
    """True when no element of the small 1-D array ``v`` is NaN or infinite."""
    return all(map(math.isfinite, v.tolist()))


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product ``a x b`` of two (3,) arrays, shape (3,)."""
    ax, ay, az = a.tolist()
    bx, by, bz = b.tolist()
    return np.array([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx])

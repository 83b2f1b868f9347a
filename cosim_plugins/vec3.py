"""Helpers for single 3-vectors, where numpy's per-call overhead is the whole cost.

Components run these every 20 ms tick, on the critical path of the loop.
``np.linalg.norm(v)`` costs ~1.6 us on a (3,) array, ``np.all(np.isfinite(v))``
~3.5 us and ``np.cross`` ~20 us, nearly all of it dispatch; arithmetic on
three Python floats costs a fraction of a microsecond. So a hot path turns
its (3,) input arrays into tuples once (``tuple(v.tolist())``), works on
:data:`Vec3` tuples with the functions below, and builds an array only for
its outputs. Large arrays should stay vectorised with numpy.

Each function does the same floating-point operations, in the same order,
as the numpy expression it replaces (named in its docstring). Elementwise
ones (cross, add, scale...) give the same bits as numpy. A dot product or a
norm in numpy goes through the BLAS, whose kernel the CPU picks: on one
machine it summed ``a0 b0 + a1 b1`` first, then ``+ a2 b2``, as :func:`dot`
does, on an AVX-512 machine it fuses multiply-adds and differs in the last
bit. ``tests/test_float_paths.py`` holds the elementwise functions to the bit
and the BLAS ones to rounding. Either way a run is byte-identical to itself
on one machine, in one process or many: every process runs these functions.
"""

from __future__ import annotations

import math

import numpy as np

#: A 3-vector as three Python floats.
Vec3 = tuple[float, float, float]


def norm(v: np.ndarray) -> float:
    """Euclidean norm of a 1-D float array: the same value as ``np.linalg.norm(v)``
    (which computes ``sqrt(v.dot(v))``), as a Python float."""
    return math.sqrt(v.dot(v))


def all_finite(v) -> bool:
    """True when no element of the small 1-D array (or sequence of floats) ``v`` is NaN or infinite."""
    return all(map(math.isfinite, v.tolist() if isinstance(v, np.ndarray) else v))


def dot(a: Vec3, b: Vec3) -> float:
    """``a . b``, as ``a.dot(b)`` on (3,) arrays."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def length(v: Vec3) -> float:
    """Euclidean norm of ``v``, as :func:`norm` (``sqrt(v.dot(v))``) on a (3,) array."""
    x, y, z = v
    return math.sqrt(x * x + y * y + z * z)


def cross(a: Vec3, b: Vec3) -> Vec3:
    """Cross product ``a x b``."""
    ax, ay, az = a
    bx, by, bz = b
    return (ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx)


def add(a: Vec3, b: Vec3) -> Vec3:
    """``a + b``."""
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a: Vec3, b: Vec3) -> Vec3:
    """``a - b``."""
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def scale(v: Vec3, k: float) -> Vec3:
    """``k * v`` (also ``v * k``: the product is the same either way)."""
    return (k * v[0], k * v[1], k * v[2])


def div(v: Vec3, k: float) -> Vec3:
    """``v / k``, element by element (not ``v * (1 / k)``, which rounds differently)."""
    return (v[0] / k, v[1] / k, v[2] / k)

"""Named extra force terms the physical model can include and fit jointly.

A term has a name, parameters (initial value, bounds, unit) and a vectorised
force ``force(p, v, u, params) -> (n, 3)`` in uN, with p (n, 3) mm,
v (n, 3) mm/s, u (n, 3) Hz and ``params`` a ``{name: float}`` dict of the
term's own parameters. Effects (wall drag, background flow, gradient force...)
are built on this; any object with the same attributes works.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class Param:
    """A fitted scalar: name, initial value, bounds, unit (for reports)."""

    name: str
    init: float
    lo: float = -math.inf
    hi: float = math.inf
    unit: str = ""


@dataclass(frozen=True)
class ForceTerm:
    """An extra force: ``force(p, v, u, params) -> (n, 3)`` [uN]."""

    name: str
    params: tuple[Param, ...]
    force: Callable[[np.ndarray, np.ndarray, np.ndarray, dict], np.ndarray]

    def param_names(self) -> list[str]:
        """Fully qualified names ``term.param`` used in reports and files."""
        return [f"{self.name}.{p.name}" for p in self.params]


def quadratic_drag(init: float = 0.0) -> ForceTerm:
    """Isotropic quadratic drag -c |v| v (c in uN s^2/mm^2); an example term."""

    def force(p, v, u, params):
        return -params["c"] * np.linalg.norm(v, axis=1, keepdims=True) * v

    return ForceTerm("quadratic_drag", (Param("c", init, 0.0, math.inf, "uN s^2/mm^2"),), force)

"""The library's wall_drag parameters that come closest to the FMU's built-in wall drag.

The FMU (``wall_drag_on``) multiplies its drag by 1 + gain sum_walls exp(-gap / length),
gap the distance from the centre to a wall less ``wall_margin``. Near one wall, along
the long axis, that is an extra drag coefficient

    kappa_fmu(d) = gain drag_axial exp(-(d - margin) / length)     [N s/m]

with d the distance to the nearest wall (the effects' d, 75 mm less max |p|). The
library's ``wall_drag`` is kappa(d) = c ell / (d + ell) [uN s/mm]: a 1/d law, not an
exponential, so it cannot match everywhere. :func:`wall_drag_like_fmu` fits (c, ell)
by least squares on kappa over the distances the swimmer can reach near a wall
(margin to ``d_max_mm``) and reports how close the fit is.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np
from scipy.optimize import least_squares

from cosim_plugins.twin.units import MM_PER_M, N_PER_UN_PER_MM, fmu_defaults


def fmu_wall_kappa(d_mm: np.ndarray, fmu_params: Mapping[str, float] | None = None) -> np.ndarray:
    """The FMU's extra drag coefficient near the nearest wall [uN s/mm] at distances d_mm (n,) [mm]."""
    p = {**fmu_defaults(), **(fmu_params or {})}
    margin, length = p["wall_margin"] * MM_PER_M, p["wall_drag_length"] * MM_PER_M
    gap = np.maximum(np.asarray(d_mm, dtype=float) - margin, 0.0)
    return p["wall_drag_gain"] * p["drag_axial"] / N_PER_UN_PER_MM * np.exp(-gap / length)


def wall_drag_like_fmu(fmu_params: Mapping[str, float] | None = None, d_max_mm: float = 20.0) -> dict:
    """(c, ell) of the library's ``wall_drag`` closest to the FMU's law, and how close.

    Returns ``{"c": uN s/mm, "ell": mm, "max_abs_error": uN s/mm, "rms_error": uN s/mm,
    "at_contact": (fmu, fit) uN s/mm, "at_20mm": (fmu, fit), "at_centre": (fmu, fit)}``; the errors
    are over d in [wall_margin, d_max_mm] mm.
    """
    p = {**fmu_defaults(), **(fmu_params or {})}
    margin = p["wall_margin"] * MM_PER_M
    d = np.linspace(margin, d_max_mm, 400)
    target = fmu_wall_kappa(d, p)

    def law(x, dd):
        c, ell = x
        return c * ell / (dd + ell)

    fit = least_squares(lambda x: law(x, d) - target, x0=[target[0] * 2.0, 2.0],
                        bounds=([0.0, 0.5], [5.0, 40.0]))
    err = law(fit.x, d) - target

    def pair(dd):
        return float(fmu_wall_kappa(np.array([dd]), p)[0]), float(law(fit.x, dd))

    return {"c": float(fit.x[0]), "ell": float(fit.x[1]), "max_abs_error": float(np.max(np.abs(err))),
            "rms_error": float(np.sqrt(np.mean(err ** 2))), "at_contact": pair(margin), "at_20mm": pair(20.0),
            "at_centre": pair(75.0)}


def wall_drag_exp_like_fmu(fmu_params: Mapping[str, float] | None = None) -> dict:
    """(c [uN s/mm], ell [mm]) of ``examples/my_effect.py``'s ``wall_drag_exp`` (-c exp(-d / ell) v), which has
    the FMU's exponential form: c = gain drag_axial exp(margin / length), ell = length. Exact near one wall."""
    p = {**fmu_defaults(), **(fmu_params or {})}
    length = p["wall_drag_length"] * MM_PER_M
    c = p["wall_drag_gain"] * p["drag_axial"] / N_PER_UN_PER_MM * np.exp(p["wall_margin"] * MM_PER_M / length)
    return {"c": float(c), "ell": float(length)}

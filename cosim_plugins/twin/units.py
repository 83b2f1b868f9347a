"""Units at the edge between the effects (mm, mm/s, Hz, uN) and the plant FMU (SI).

The effects (:mod:`cosim_plugins.effects`) take position p [mm], velocity v
[mm/s] and the command u = omega [Hz] and return a force [uN]; the FMU's ports
are p [m], v [m/s], omega [rad/s] and its external force input is in N
(derivatives in N/m and N s/m). This module holds the factors and the host
parameters the effects may reuse (``k``, ``Cd0``, ``Cd1``, ``Cl0``, ``Fvs``,
``Fmax``), taken from the FMU's own physical parameters.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Mapping

MM_PER_M = 1e3          # p [mm] = MM_PER_M * p [m]; also v [mm/s] per [m/s]
HZ_PER_RAD_S = 1.0 / (2.0 * math.pi)
N_PER_UN = 1e-6         # F [N] = N_PER_UN * F [uN]
#: dF/dp [N/m] = N_PER_UN_PER_MM * dF/dp [uN/mm]; the same factor takes dF/dv [uN s/mm] to [N s/m]
N_PER_UN_PER_MM = N_PER_UN * MM_PER_M

#: The host (physical model) parameters an effect may read, with their units.
HOST_UNITS = {"k": "uN/Hz", "Cd0": "uN s/mm", "Cd1": "uN s/mm", "Cl0": "uN s/mm", "Fvs": "uN", "Fmax": "uN"}


@lru_cache(maxsize=1)
def fmu_defaults() -> dict[str, float]:
    """The plant FMU's parameters at their start values, by FMI name (reals and booleans as floats)."""
    from fmpy import read_model_description

    from cosim_plugins.plant.build import SOURCE_DIR

    md = read_model_description(str(SOURCE_DIR / "modelDescription.xml"))
    out = {}
    for var in md.modelVariables:
        if var.causality == "parameter" and var.start is not None:
            out[var.name] = float(var.start in (True, "true")) if var.type == "Boolean" else float(var.start)
    return out


def host_params_from_fmu(fmu_params: Mapping[str, float] | None = None) -> dict[str, float]:
    """The physical model's parameters that the FMU's law implies, in the effects' units.

    ``fmu_params``: FMU parameters by FMI name overriding its defaults (e.g. a scenario's
    ``drag_axial``). k = handedness prop_coeff 2 pi [N/Hz] (the thrust per Hz of spin), Cd1 =
    drag_axial [N s/m] (the drag along the long axis, where the swimmer mostly moves), Fvs =
    -(mass - rho_fluid volume) g [N] (weight minus buoyancy, on +z), converted to uN, uN s/mm;
    Cd0 = Cl0 = Fmax = 0 (the FMU has no angle-of-attack drag, lift or centring force of the
    paper's form).
    """
    p = {**fmu_defaults(), **(fmu_params or {})}
    return {
        "k": p["handedness"] * p["prop_coeff"] * 2.0 * math.pi / N_PER_UN,
        "Cd0": 0.0,
        "Cd1": p["drag_axial"] / N_PER_UN_PER_MM,
        "Cl0": 0.0,
        "Fvs": -(p["mass"] - p["rho_fluid"] * p["volume"]) * p["g"] / N_PER_UN,
        "Fmax": 0.0,
    }

"""The paper's forces the plant FMU's law has no counterpart for: the angle-of-attack drag, lift, centring.

The physical model (paper Eq. 1-7, :mod:`cosim_plugins.models.physical`) has a drag
-(Cd0 sin(alpha) + Cd1) v, a lift Cl0 sin(2 alpha) |v| v_perp [uN s/mm x mm/s] and a
centring force Fmax sin(pi |p| / |P_b|) (-p_hat) [uN]. The FMU's drag is a tensor,
drag_axial along the long axis and anisotropy_ratio x drag_axial across it: for a
velocity at an angle alpha to the axis it pushes partly sideways, where the paper's
drags along -v with a coefficient growing with sin(alpha); the FMU has no lift or
centring force at all. The paper's Cd0 term (with the FMU's anisotropy at 1, the
FMU's drag is the paper's Cd1 term), the lift and the centring force reach the
FMU through its external force input as the force effect ``twin_paper_forces`` (not registered in the
library, so a diagnosis never ranks it: a twin's ``twin_effects.py`` registers it for
``cosim run``). Units: p mm, v mm/s, u Hz, force uN.
"""

from __future__ import annotations

import math

import numpy as np

from cosim_plugins.identify.effect import Effect, EffectParam
from cosim_plugins.models.physical import geometry

NAME = "twin_paper_forces"
PB_NORM_MM = 70.0 * math.sqrt(3.0)  # the physical model's |P_b|, P_b = [70, 70, 70] mm


def paper_forces(p, v, u, params):
    """Cd0 drag + Cl0 lift + Fmax centring force [uN], (n, 3), at p (n, 3) [mm], v (n, 3) [mm/s], u (n, 3)
    [Hz]."""
    v = np.asarray(v, dtype=float)
    sin_a, lift, cent = geometry(np.asarray(p, dtype=float), v, np.asarray(u, dtype=float), PB_NORM_MM)
    return -(params["Cd0"] * sin_a)[:, None] * v + params["Cl0"] * lift + params["Fmax"] * cent


def paper_forces_effect() -> Effect:
    """The effect ``twin_paper_forces`` (Cd0, Cl0 [uN s/mm], Fmax [uN])."""
    return Effect(name=NAME, params=(EffectParam("Cd0", 0.0, -5.0, 5.0, "uN s/mm", scale=0.02),
                                     EffectParam("Cl0", 0.0, -5.0, 5.0, "uN s/mm", scale=0.02),
                                     EffectParam("Fmax", 0.0, -10.0, 10.0, "uN", scale=0.1)),
                  force=paper_forces,
                  doc="The paper's angle-of-attack drag -Cd0 sin(alpha) v, lift Cl0 sin(2 alpha) |v| v_perp and "
                      "centring force Fmax sin(pi |p| / |P_b|) (-p_hat), which the plant FMU's law lacks [uN].")


EFFECT_FILE = '''"""Registers the calibrated twin's {name} effect (written by `cosim twin calibrate`)."""

from cosim import hookimpl
from cosim_plugins.twin.host_forces import paper_forces_effect


@hookimpl
def cosim_register_effects(register):
    register(paper_forces_effect())
'''


def effect_file_source() -> str:
    """The source of a twin's ``twin_effects.py`` (the scenario lists it under ``plugins``)."""
    return EFFECT_FILE.format(name=NAME)

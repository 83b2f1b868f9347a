"""A test effect that is not in the library: the water turning about the vertical axis.

A slow solid-body rotation of the water (a stirrer, thermal convection):
w = Omega z_hat x p [mm/s] with Omega [rad/s]; the drag acts on v - w, so
the force is +Cd1 w. No library effect has this curl-type field
(gradient_force is curl-free, background_flow uniform).
"""

import numpy as np

from cosim import hookimpl
from cosim_plugins.identify.effect import Effect, EffectParam


def swirl_force(p, v, u, params):
    w = np.zeros_like(p)
    w[:, 0] = -params["omega"] * p[:, 1]
    w[:, 1] = params["omega"] * p[:, 0]
    return params["Cd1"] * w


SWIRL = Effect(
    name="swirl",
    params=(EffectParam("omega", 0.0, -2.0, 2.0, "rad/s"),),
    force=swirl_force,
    doc="Water turning about the vertical axis through the centre: drag on v - Omega z x p.",
)


@hookimpl
def cosim_register_effects(register):
    register(SWIRL)

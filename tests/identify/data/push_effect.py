"""A user's own force effect for the `cosim fit --effects-file` test: a constant push along x [uN]."""

import numpy as np

from cosim import hookimpl
from cosim_plugins.identify.effect import Effect, EffectParam


def _push(p, v, u, prm):
    f = np.zeros_like(v)
    f[:, 0] = prm["f_x"]
    return f


PUSH = Effect(name="test_push", params=(EffectParam("f_x", 0.0, -20.0, 20.0, "uN", 1.0),), force=_push,
              doc="A constant push along x (a test effect).")


@hookimpl
def cosim_register_effects(register):
    register(PUSH)

"""A user-defined effect: wall drag that decays exponentially with the distance to the wall.

The effect library's ``wall_drag`` grows as 1/d near a wall (the far-field
law of a sphere near a plane). Suppose your lab measured that the drag rise
dies out faster, within a few body lengths, and wants to test that law on
its logs. Write it as an effect and give the file to ``cosim diagnose``::

    cosim diagnose runs/diag_wall/runs/*/log.csv --effects-file examples/my_effect.py --out runs/diag_wall_mine

It is ranked with the library's effects (``--effects wall_drag,wall_drag_exp``
to compare only the two), and ``--add wall_drag_exp`` refits with it.

The contract (see ``cosim/identify/effect.py``): a name, a doc, parameters
with initial values, bounds and units, and a vectorised force
``force(p, v, u, params) -> (n, 3)`` in uN, with p [mm], v [mm/s] and
u = omega [Hz] as (n, 3) arrays and ``params`` the parameters by short name
(plus the host model's, e.g. ``Cd1``). Register it with the
``cosim_register_effects`` hook.
"""

import numpy as np

from cosim import hookimpl
from cosim_plugins.identify.effect import Effect, EffectParam

TANK_HALF_MM = 75.0  # the tank is a 150 mm cube centred at the origin


def wall_drag_exp(p, v, u, params):
    """-c exp(-d / ell) v, d = distance from the centre to the nearest wall [mm]."""
    d = np.maximum(TANK_HALF_MM - np.max(np.abs(p), axis=1), 0.0)
    return -(params["c"] * np.exp(-d / params["ell"]))[:, None] * v


MY_EFFECT = Effect(
    name="wall_drag_exp",
    params=(EffectParam("c", 0.0, 0.0, 1.0, "uN s/mm"), EffectParam("ell", 5.0, 0.5, 40.0, "mm")),
    force=wall_drag_exp,
    doc="Wall drag decaying exponentially: the linear drag near a wall rises by c exp(-d / ell) [uN s/mm], "
        "d the distance from the centre to the nearest wall [mm], ell [mm] the decay length.",
    # the fit tries these starts too: with c = 0 the cost does not depend on ell
    starts=({"c": 0.2, "ell": 3.0}, {"c": 0.2, "ell": 10.0}),
)


@hookimpl
def cosim_register_effects(register):
    register(MY_EFFECT)

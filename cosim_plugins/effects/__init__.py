"""The effect library: named physical effects the physical model can include.

Each is a :class:`cosim_plugins.identify.effect.Effect` registered through the
``cosim_register_effects`` hook, exactly as a user's effect file does (see
``examples/my_effect.py``). Forms are generic (they must work on any lab's
logs): each is documented with its physics, parameters and units.

Forces (:mod:`.forces`): ``background_flow``, ``wall_drag``, ``step_out``,
``gradient_force``, ``anisotropic_drag``, ``quadratic_drag``.
Transforms (:mod:`.transforms`): ``actuation_lag`` and ``heading_lag``
(input), ``sensor_latency`` (sensor).
"""

from cosim import hookimpl


@hookimpl
def cosim_register_effects(register):
    from cosim_plugins.effects.forces import FORCE_EFFECTS
    from cosim_plugins.effects.transforms import TRANSFORM_EFFECTS

    for effect in (*FORCE_EFFECTS, *TRANSFORM_EFFECTS):
        register(effect)

"""The effect library: named physical effects the physical model can include.

Each is a :class:`cosim_plugins.identify.effect.Effect` registered through the
``cosim_register_effects`` hook, exactly as a user's effect file does (see
``examples/my_effect.py``). Forms are generic (they must work on any lab's
logs): each is documented with its physics, parameters and units.

Forces (:mod:`.forces`): ``background_flow``, ``wall_drag``,
``gradient_force``, ``anisotropic_drag``, ``quadratic_drag``.
Input transforms: ``step_out`` (:mod:`.step_out`, the magnet's phase by Adler's
equation), ``actuation_lag`` and ``heading_lag`` (:mod:`.transforms`); sensor:
``sensor_latency`` (:mod:`.transforms`). They are registered in this order
(forces and step-out first, as the library lists them).
"""

from cosim import hookimpl


@hookimpl
def cosim_register_effects(register):
    from cosim_plugins.effects import forces, transforms
    from cosim_plugins.effects.step_out import STEP_OUT

    for effect in (forces.BACKGROUND_FLOW, forces.WALL_DRAG, STEP_OUT, forces.GRADIENT_FORCE, forces.ANISOTROPIC_DRAG,
                   forces.QUADRATIC_DRAG, *transforms.TRANSFORM_EFFECTS):
        register(effect)

"""The twin plugin: the plant FMU with effects added from outside, calibrated to a lab's logs.

Registers three components: ``plant.fmu_forced`` (the plant FMU with its external
force input as ports, :class:`cosim_plugins.plant.fmu_component.FmuForcedPlant`) and
``twin.effect`` (:mod:`.component`), which evaluates force effects (library effects
by name, a user's effect file loaded as a plugin, or every force effect of a saved
physical model) at the plant's own state and the command and sends the force to
the plant; ``twin.effect_on_axis`` the same with the command turned onto the plant's
real axis (for the plant FMU's own laws, :mod:`.fmu_laws`). The effects work in the
identification units (mm, mm/s, Hz, uN); the FMU
in SI: :mod:`.units` converts at that edge. And the command ``cosim twin calibrate``
(:mod:`.cli`, :mod:`.calibrate`): the FMU's parameters and the effects' fitted to a
lab's logs, written as a scenario of the lab's loop on its twin. See ``docs/twin.md``.
"""

from cosim import hookimpl


@hookimpl
def cosim_register_components(register):
    from cosim_plugins.plant.fmu_component import FmuForcedPlant
    from cosim_plugins.twin.component import EffectInjector, EffectOnPlantAxis

    register("plant.fmu_forced", FmuForcedPlant)
    register("twin.effect", EffectInjector)
    register("twin.effect_on_axis", EffectOnPlantAxis)


@hookimpl
def cosim_register_commands(register):
    from cosim_plugins.twin import cli

    register(cli.add_commands)

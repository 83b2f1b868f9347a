"""Plant plugin: the six-coil manipulator + swimmer + tank FMU as component ``plant.fmu``,
the same FMU with its external force input as ``plant.fmu_forced``, and the component that
applies effects through that input, ``twin.effect`` (:mod:`cosim_plugins.twin`)."""

from cosim import hookimpl
from cosim_plugins.plant.fmu_component import FmuForcedPlant, FmuPlant

__all__ = ["FmuForcedPlant", "FmuPlant"]


@hookimpl
def cosim_register_components(register):
    from cosim_plugins.twin.component import EffectInjector

    register("plant.fmu", FmuPlant)
    register("plant.fmu_forced", FmuForcedPlant)
    register("twin.effect", EffectInjector)

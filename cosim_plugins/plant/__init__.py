"""Plant plugin: the six-coil manipulator + swimmer + tank FMU as component ``plant.fmu``."""

from cosim import hookimpl
from cosim_plugins.plant.build import ENV_FMU
from cosim_plugins.plant.fmu_component import FmuPlant

__all__ = ["FmuPlant"]


@hookimpl
def cosim_register_components(register):
    register("plant.fmu", FmuPlant)


@hookimpl
def cosim_register_environment(register):
    register(ENV_FMU)  # a prebuilt plant FMU instead of the one built from the sources

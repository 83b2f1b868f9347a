"""Coil-driver bridges: inverse magnetics with the FMU's voltage inputs as backend."""

from cosim import hookimpl
from cosim_plugins.coil_driver.inverse import InverseMagnetics


@hookimpl
def cosim_register_components(register):
    register("coil_driver.inverse", InverseMagnetics)

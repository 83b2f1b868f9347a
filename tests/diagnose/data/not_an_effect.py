"""A plugin file that registers something that is not an effect (no force, bad name)."""

from cosim import hookimpl


class Broken:
    name = "broken_effect"
    kind = "force"
    params = ()
    force = None  # not callable


@hookimpl
def cosim_register_effects(register):
    register(Broken())

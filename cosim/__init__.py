"""cosim: a lockstep co-simulation framework for data-driven control of a magnetic swimmer.

The framework knows components, time, wiring and data; the physics lives in the
``cosim_plugins`` package and in users' plugins, registered through pluggy hooks
(see :mod:`cosim.hookspecs`).
"""

from cosim.component import Component, ComponentError, ComponentFault, Port
from cosim.hookspecs import hookimpl

__all__ = ["Component", "ComponentError", "ComponentFault", "Port", "hookimpl"]

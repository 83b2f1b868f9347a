"""Components any domain can use as they are or subclass: :class:`~cosim.components.fmu.FmuComponent`
runs an FMI 2.0 co-simulation FMU (fmpy) behind ports that map onto its variables.
"""

from cosim.components.fmu import FmuComponent

__all__ = ["FmuComponent"]

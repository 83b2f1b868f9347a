"""The twin: the plant FMU with effects added from outside.

Component ``twin.effect`` (:mod:`.component`) evaluates force effects (library
effects by name, a user's effect file loaded as a plugin, or every force effect of a
saved physical model) at the plant's own state and the command, and sends the force to
the plant component ``plant.fmu_forced`` (the FMU's external force input). The
effects work in the identification units (mm, mm/s, Hz, uN); the FMU in SI:
:mod:`.units` converts at that edge. See ``docs/twin.md``.
"""

from cosim_plugins.twin.applied import AppliedEffects
from cosim_plugins.twin.component import EffectInjector

__all__ = ["AppliedEffects", "EffectInjector"]

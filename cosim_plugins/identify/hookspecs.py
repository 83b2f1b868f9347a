"""The identification's own hooks: the models and effects the swimmer's plugins provide.

Added to the plugin manager by :func:`cosim_addhooks` in
:mod:`cosim_plugins.identify.plugin`; ``cosim.contract.plugins.registry("model")``
and ``registry("effect")`` then find what these hooks register.
"""

from __future__ import annotations

from cosim.contract.hookspecs import hookspec


@hookspec
def cosim_register_models(register):
    """Provide dynamics models for identification and estimation.

    Call ``register(name, cls)`` where ``cls`` follows
    :class:`cosim_plugins.identify.model.Model` (``fit``, vectorised ``predict``,
    ``save``/``load``).
    """


@hookspec
def cosim_register_effects(register):
    """Provide named physical effects the physical model can include.

    Call ``register(effect)`` with an object following
    :class:`cosim_plugins.identify.effect.Effect` (name, parameters with initial
    values and bounds, a vectorised force or input/sensor transform).
    """

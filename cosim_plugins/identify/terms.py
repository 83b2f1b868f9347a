"""Extra force terms of the physical model: force-kind effects.

A term is a :class:`~cosim_plugins.identify.effect.Effect` of kind ``"force"``:
a name, parameters (initial value, bounds, unit) and a vectorised force
``force(p, v, u, params) -> (n, 3)`` in uN, with p (n, 3) mm, v (n, 3) mm/s,
u (n, 3) Hz and ``params`` the term's own parameters by short name (plus
the host model's, see :mod:`cosim_plugins.identify.effect`). ``ForceTerm(name,
params, force)`` builds one; the effect library (``cosim_plugins.effects``)
registers the named ones, which a saved model refers to by name.
"""

from __future__ import annotations

from cosim_plugins.identify.effect import Effect, EffectParam

__all__ = ["ForceTerm", "EffectParam", "quadratic_drag"]


def ForceTerm(name: str, params, force, doc: str = "") -> Effect:  # noqa: N802 (kept for its old class name)
    """A force-kind :class:`Effect`: ``force(p, v, u, params) -> (n, 3)`` [uN]."""
    return Effect(name=name, params=tuple(params), force=force, kind="force", doc=doc)


def quadratic_drag(init: float = 0.0) -> Effect:
    """The library's isotropic quadratic drag -c |v| v (c in uN s^2/mm^2), starting at c = ``init``."""
    from dataclasses import replace

    from cosim_plugins.identify.effect import resolve

    (effect,) = resolve(["quadratic_drag"])
    return replace(effect, params=tuple(replace(p, init=init) for p in effect.params))

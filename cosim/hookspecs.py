"""The plugin contract: every hook a plugin may implement.

A plugin is any Python module or object with functions decorated by
``@cosim.hookimpl`` whose names match the specs below. Built-in plugins
(``cosim_plugins.*``) are registered exactly like external ones, which are
found through the ``cosim`` entry-point group of installed packages or loaded
from a file (``--effects-file`` and friends).

Each hook receives a ``register`` callback and calls it once per thing it
provides; names must be unique across all plugins of a kind.
"""

from __future__ import annotations

import pluggy

PROJECT = "cosim"
hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


@hookspec
def cosim_register_components(register):
    """Provide component classes.

    Call ``register(name, cls)`` for each; ``cls`` follows
    :class:`cosim.component.Component` and is instantiated with no argument.
    ``name`` is what a scenario's ``plugin:`` field refers to
    (e.g. ``"plant.fmu"``, ``"controller.pi"``).
    """


@hookspec
def cosim_register_paths(register):
    """Provide reference paths.

    Call ``register(name, factory)`` where ``factory(**params)`` returns an
    object with ``sample(s_m) -> (n, 3) positions [m]`` over arc length and
    ``length_m``; see :mod:`cosim.paths`.
    """


@hookspec
def cosim_register_models(register):
    """Provide dynamics models for identification and estimation.

    Call ``register(name, cls)`` where ``cls`` follows
    :class:`cosim.identify.model.Model` (``fit``, vectorised ``predict``,
    ``save``/``load``).
    """


@hookspec
def cosim_register_effects(register):
    """Provide named physical effects the physical model can include.

    Call ``register(effect)`` with an object following
    :class:`cosim.identify.effect.Effect` (name, parameters with initial
    values and bounds, a vectorised force or input/sensor transform).
    """


@hookspec
def cosim_register_commands(register):
    """Provide ``cosim`` subcommands.

    Call ``register(add_commands)`` for each group, where ``add_commands(subparsers)``
    adds argparse parsers to the ``cosim`` command's subparsers and sets ``func``
    on each to a callable taking the parsed arguments and returning an exit code
    (the contract of :mod:`cosim.cli`'s own command modules).
    """


@hookspec
def cosim_register_profiles(register):
    """Provide parameter profiles a scenario selects with its ``profile`` field.

    Call ``register(name, values)`` where ``values`` is ``{plugin name: {param: value}}``:
    every component of a scenario using that plugin gets those parameters (``ideal``, the
    parameters as the scenario gives them, needs no registration).
    """

"""The plugin contract: every hook the framework calls.

A plugin is any Python module or object with functions decorated by
``@cosim.hookimpl`` whose names match the specs below. Plugins are found
through the ``cosim`` entry-point group of installed packages (a domain's
package lists its modules there) or loaded from a file (a scenario's
``plugins:``).

Each ``cosim_register_*`` hook receives a ``register`` callback and calls it
once per thing it provides; names must be unique across all plugins of a
kind. A domain that lets its own plugins provide kinds of things the
framework does not know (models, effects, ...) adds their hook
specifications through :func:`cosim_addhooks`; ``registry(kind)`` then finds
them by the name ``cosim_register_<kind>s``.
"""

from __future__ import annotations

import pluggy

PROJECT = "cosim"
hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


@hookspec(historic=True)
def cosim_addhooks(pluginmanager):
    """Add hook specifications of a domain's own (``pluginmanager.add_hookspecs(module)``).

    Called once for every plugin as it is registered, so a plugin's hooks are
    known before any is called.
    """


@hookspec
def cosim_register_components(register):
    """Provide component classes.

    Call ``register(name, cls)`` for each; ``cls`` follows
    :class:`cosim.contract.component.Component` and is instantiated with no argument.
    ``name`` is what a scenario's ``plugin:`` field refers to
    (e.g. ``"plant.fmu"``, ``"controller.pi"``).
    """


@hookspec
def cosim_register_paths(register):
    """Provide reference paths.

    Call ``register(name, factory)`` where ``factory(**params)`` returns a
    :class:`cosim.contract.paths.ReferencePath`: ``points(t_s) -> (n, 3)``
    positions [m] of its polyline at time ``t_s``, and ``length_m``.
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
    parameters as the scenario gives them, needs no registration). Give ``values`` as a
    :class:`cosim.contract.params.Profile` to say what the profile is (``cosim plugins`` lists it).
    """


@hookspec
def cosim_register_views(register):
    """Provide recording views: what a domain draws of a run and the files it writes beside the trace.

    Call ``register(name, view)`` with an object following
    :class:`cosim.contract.views.RunView`: the roles it reads (with their default
    ports), its rerun views and drawing, and its files written as the run goes.
    """


@hookspec
def cosim_summary_figures(register):
    """Provide figures of every run: call ``register(figure_set)`` with a
    :class:`cosim.contract.figures.FigureSet` (its keys, its accumulator, its exact
    computation from a trace, its sweep-table columns). Their keys follow the
    framework's ``tracking_error_mm`` in ``summary.json`` and in a sweep's rows.
    """


@hookspec
def cosim_default_roles(register):
    """Give the framework's recorded roles (``truth``, ``measured``, ``estimate``, ``solve_time``,
    ``prediction_error``, ``capture_time``; see :class:`cosim.scenario.schema.RecordSpec`) their
    default ports in this domain.

    Call ``register(role, "component.port")`` for each; the first registration of a role wins and
    a scenario's ``record:`` overrides it. A role no plugin gives is unbound unless the scenario binds it.
    """


@hookspec
def cosim_register_environment(register):
    """Name the environment variables that change what a run of the plugin's components does.

    Call ``register(name)`` for each (e.g. a domain's dataset size or the file of a prebuilt
    model): a sweep's jobs carry the client's values of them, and of the framework's own
    ``COSIM_CACHE``, to the workers that run them (see :mod:`cosim.scale.jobs`).
    """


@hookspec
def cosim_register_scenarios(register):
    """Provide scenario files shipped inside a package, so they run by name (``cosim run NAME``).

    Call :func:`cosim.scenario.catalog.register_folder` ``(register, folder)`` with the
    package folder holding them, or ``register(name, ShippedScenario(path))`` for each.
    """

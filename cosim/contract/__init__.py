"""The contract between the framework and the plugins that give it a domain.

A domain (a plant, its sensors, controllers and analyses) is a set of pluggy
plugins: :mod:`~cosim.contract.hookspecs` lists every hook a plugin may
implement (components, reference paths, parameter profiles, CLI commands,
recording views, the default ports of the recorded roles, environment
variables, and hooks of its own that a domain adds for its own plugins),
:mod:`~cosim.contract.plugins` is the one plugin manager that finds them
(the ``cosim`` entry-point group and plugin files),
:mod:`~cosim.contract.component` is the protocol every component follows
(ports, ``setup``, ``step``, ``close``), :mod:`~cosim.contract.params` reads
a component's parameters (their defaults, types and bounds; units are in
their names), :mod:`~cosim.contract.paths` is what a reference path is,
:mod:`~cosim.contract.views` what a domain's view of a run is, and
:mod:`~cosim.contract.errors` holds the errors.
"""

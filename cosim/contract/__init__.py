"""The contract between the framework and the plugins that give it a domain.

A domain (a plant, its sensors, controllers and analyses) is a set of pluggy
plugins: :mod:`~cosim.contract.hookspecs` lists every hook a plugin may
implement (components, reference paths, parameter profiles, CLI commands,
recording views, and hooks of its own that a domain adds for its own
plugins), :mod:`~cosim.contract.plugins` is the one plugin manager that
finds them (the ``cosim`` entry-point group and plugin files),
:mod:`~cosim.contract.component` is the protocol every component follows
(ports, ``setup``, ``step``, ``close``), :mod:`~cosim.contract.params` reads
a component's parameters with units and bounds, and
:mod:`~cosim.contract.errors` holds the error a user's input raises.
"""

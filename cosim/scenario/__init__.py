"""Scenarios: what a run is, read from YAML and checked before anything starts.

:mod:`~cosim.scenario.schema` is the scenario format (pydantic, unknown keys
refused): components and their plugins, wiring edges, the reference path,
the recorded roles, sweeps and profiles, with ``--set`` overrides;
:mod:`~cosim.scenario.paths` builds a scenario's reference path by name (what
a path is: :mod:`cosim.contract.paths`) and measures a trajectory's distance
to it; :mod:`~cosim.scenario.catalog` finds the scenarios packages ship, to
run by name.
"""

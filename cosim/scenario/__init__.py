"""Scenarios: what a run is, read from YAML and checked before anything starts.

:mod:`~cosim.scenario.schema` is the scenario format (pydantic, unknown keys
refused): components and their plugins, wiring edges, the reference path,
the recorded roles, sweeps and profiles, with ``--set`` overrides;
:mod:`~cosim.scenario.paths` is the reference-path contract (a curve over arc
length, possibly moving in time) and the distance of a trajectory to it.
"""

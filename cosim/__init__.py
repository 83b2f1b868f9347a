"""cosim: a lockstep co-simulation framework over eclipse-zenoh.

The framework knows components, time, wiring, scenarios and recordings; a
domain (a plant, its sensors, controllers and analyses) is a package of
plugins registered through pluggy hooks (see :mod:`cosim.contract`). Its
rooms: :mod:`cosim.contract` (what a plugin implements), :mod:`cosim.scenario`
(what a run is), :mod:`cosim.runtime` (the path of a tick), :mod:`cosim.record`
(what a run leaves behind), :mod:`cosim.scale` (many runs at once),
:mod:`cosim.components` (components any domain can use), :mod:`cosim.api`
(what a domain or a script calls: load, check, run, sweep, serve a node,
fingerprints and caches) and :mod:`cosim.cli`, each importing only those
before it.

The names below are the contract a plugin implements; ``FmuComponent`` and
``component_recording`` are loaded on first use (they bring fmpy and rerun).
"""

import sys

try:
    from cosim.contract.component import Component, ComponentError, ComponentFault, InputEnded, Port
    from cosim.contract.errors import UserError
    from cosim.contract.hookspecs import hookimpl, hookspec
    from cosim.contract.params import Param, read_params, whole_ticks
except ModuleNotFoundError as _missing:  # `python -m cosim` from a Python without the dependencies
    if sys.argv[:1] != ["-m"] or (_missing.name or "").startswith("cosim"):
        raise
    sys.exit(f"python -m cosim: this Python ({sys.executable}) lacks cosim's dependency {_missing.name!r}. "
             "Run cosim with the Python it is installed in: `make venv` makes .venv in a checkout, then "
             "`.venv/bin/cosim` (or `. .venv/bin/activate` and `cosim`); or `pip install .` into this one.")

__all__ = ["Component", "ComponentError", "ComponentFault", "FmuComponent", "InputEnded", "Param", "Port",
           "UserError", "component_recording", "hookimpl", "hookspec", "read_params", "whole_ticks"]


def __getattr__(name: str):
    if name == "FmuComponent":
        from cosim.components.fmu import FmuComponent

        return FmuComponent
    if name == "component_recording":
        from cosim.record.rerun_log import component_recording

        return component_recording
    raise AttributeError(f"module 'cosim' has no attribute {name!r}")

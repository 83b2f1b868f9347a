"""The DC motor example's plugin file: registers its components and its log (a scenario loads it
with ``plugins: [plugin.py]``).

A scenario's plugin file is imported on its own, not as part of a package,
so this file first imports the folder beside it as the package
``cosim_example_dc_motor`` (once per process) and registers that package's
components.
"""

import importlib.util
import sys
from pathlib import Path

from cosim import hookimpl

PACKAGE = "cosim_example_dc_motor"


def _import_package():
    here = Path(__file__).resolve().parent
    loaded = sys.modules.get(PACKAGE)
    if loaded is not None:
        if Path(loaded.__file__).resolve().parent != here:
            raise ImportError(f"another {PACKAGE} is already imported, from {loaded.__file__}")
        return loaded
    spec = importlib.util.spec_from_file_location(PACKAGE, here / "__init__.py", submodule_search_locations=[str(here)])
    package = importlib.util.module_from_spec(spec)
    sys.modules[PACKAGE] = package
    spec.loader.exec_module(package)
    return package


_import_package()
from cosim_example_dc_motor.controller import SpeedPi  # noqa: E402
from cosim_example_dc_motor.log import MotorLog  # noqa: E402
from cosim_example_dc_motor.motor import MotorFmu  # noqa: E402
from cosim_example_dc_motor.scope import Scope  # noqa: E402
from cosim_example_dc_motor.steps import Steps  # noqa: E402


@hookimpl
def cosim_register_components(register):
    register("dc_motor.fmu", MotorFmu)
    register("dc_motor.pi_speed", SpeedPi)
    register("dc_motor.steps", Steps)
    register("dc_motor.scope", Scope)


@hookimpl
def cosim_register_views(register):
    register("dc_motor.log", MotorLog())

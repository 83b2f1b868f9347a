"""The files the swimmer lab ships inside its package, and where it caches what it builds.

Read through :mod:`importlib.resources`, so they are found wherever the package is
installed (a wheel, an editable checkout): the shipped scenarios (``scenarios/``,
registered here so ``cosim run racetrack`` finds them), the plant FMU's C sources
(``plant/swimmer_plant/``) and the renderer's camera set-up (``camera/acA800_pair.yaml``).
"""

from __future__ import annotations

import os
from importlib.resources import files
from pathlib import Path

from cosim import hookimpl
from cosim.api import register_folder
from cosim.contract.errors import UserError

#: Sub-folder of the user cache dir this project writes to.
CACHE_NAME = "cosim-swimmer"


def package_path(*parts: str) -> Path:
    """A file or folder of the installed ``cosim_plugins`` package, as a file-system path."""
    found = files("cosim_plugins").joinpath(*parts)
    if not isinstance(found, Path):  # a zipped install: the C compiler and YAML loader need real files
        raise UserError(f"cosim_plugins/{'/'.join(parts)} is not on the file system ({found}); "
                        "install the package unzipped (pip install)")
    return found


def user_cache_dir() -> Path:
    """Where built artefacts are kept between runs: ``$XDG_CACHE_HOME/cosim-swimmer``
    (default ``~/.cache/cosim-swimmer``)."""
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / CACHE_NAME


#: The shipped scenarios' folder.
SCENARIOS_DIR = package_path("scenarios")


@hookimpl
def cosim_register_scenarios(register):
    register_folder(register, SCENARIOS_DIR)

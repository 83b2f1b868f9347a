"""Scenarios shipped inside installed packages, run by name (``cosim run NAME``).

A domain ships its scenario files as package data and registers their folder through the
hook ``cosim_register_scenarios`` with :func:`register_folder`: every ``*.yaml`` file under
it is a scenario named by its path in the folder without the suffix (``step_response``,
``lab/training``). ``cosim scenarios`` lists them with their ``description``; every
command that takes a scenario file takes such a name too (:func:`resolve_scenario`).
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from pathlib import Path

from cosim.contract.errors import UserError
from cosim.contract.plugins import registry
from cosim.scenario.schema import ScenarioError, load_document

SUFFIX = ".yaml"


@dataclass(frozen=True)
class ShippedScenario:
    """One scenario file a package ships (``path``: where the installed package holds it)."""

    path: Path

    @property
    def doc(self) -> str:
        """The scenario's ``description`` field, else the first sentence of the file's opening
        comment ("" when it has neither or does not parse)."""
        try:
            data, document = load_document(self.path)
        except ScenarioError:
            return ""
        if data.get("description"):
            return str(data["description"])
        comment = []
        for line in document.text.splitlines():
            if not line.startswith("#"):
                break
            comment.append(line.lstrip("# ").strip())
        return re.split(r"(?:(?<=[a-z]{4})|(?<=\)))[.:] ", " ".join(comment), maxsplit=1)[0].strip()


def register_folder(register, folder: Path) -> None:
    """Register every ``*.yaml`` under ``folder`` (sub-folders included) by its relative name."""
    folder = Path(folder)
    if not folder.is_dir():
        raise UserError(f"scenario folder {folder} does not exist (is the package installed whole?)")
    for file in sorted(folder.rglob(f"*{SUFFIX}")):
        register(file.relative_to(folder).with_suffix("").as_posix(), ShippedScenario(file))


def shipped_scenarios() -> dict[str, ShippedScenario]:
    """Every shipped scenario by name."""
    return registry("scenario")


def resolve_scenario(given: str | Path) -> Path:
    """The scenario file ``given`` names: an existing file as it is, else a shipped scenario's name
    (with or without ``.yaml``); neither raises :class:`UserError` naming both readings."""
    path = Path(given)
    if path.is_file():
        return path
    name = str(given).removesuffix(SUFFIX)
    found = shipped_scenarios()
    if name in found:
        return found[name].path
    close = difflib.get_close_matches(path.stem if path.suffix == SUFFIX else name, list(found), n=3)
    hint = (f"; shipped scenarios by that name: {' or '.join(close)}" if close
            else "; `cosim scenarios` lists the shipped ones")
    if path.suffix == SUFFIX or path.is_absolute() or str(given).startswith("."):
        raise UserError(f"scenario file {given} does not exist{hint}")
    raise UserError(f"no scenario file {given} and no shipped scenario named {name!r}{hint}")

"""Recording views: what a domain draws of a run and writes beside its trace.

The framework records every port of every component (``trace.npz``) and draws
what it knows of any controlled system: the reference path and the tracking
error (see :mod:`cosim.record.rerun_log`). A domain adds the rest (its 3D
world, e.g. the ``truth``, ``measured`` and ``estimate`` positions)
with a :class:`RunView`, registered through the ``cosim_register_views``
hook: the roles it reads (so a scenario's ``record:`` may bind them), rerun
views and what it draws into them batch by batch, and files it writes as the
run goes (a domain's own log format). A view applies to a run when every
role it reads is bound to a recorded port, so views of other domains stay
out of the way.
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import numpy as np

from cosim.contract.plugins import get_plugin_manager, registry


class RunFile(Protocol):
    """A file a view writes as the run goes."""

    path: Path

    def append(self, recorder, start: int, stop: int) -> None:
        """Write ticks ``start:stop`` of the recorder (see :meth:`TraceRecorder.signal`)."""

    def close(self) -> None:
        """Flush and close the file."""


class RunView:
    """Base of a domain's view of a run; every method has a do-nothing default."""

    #: the roles this view reads, each with its default port ``"component.port"`` (a scenario's
    #: ``record:`` binds them to other ports, or to none with null)
    roles: dict[str, str | None] = {}
    #: ``{key: file name}`` of the files it writes (the keys of summary.json's ``files``)
    files: dict[str, str] = {}
    #: it draws into the 3D view (entities under ``world/``, where the framework draws the path)
    spatial: bool = False

    def applies(self, recorder) -> bool:
        """Whether the run has what this view shows: by default, every role it reads is recorded."""
        return all(recorder.signal(role) is not None for role in self.roles)

    def layout(self) -> list:
        """Rerun blueprint views for the layout's column of plots (``rerun.blueprint`` objects)."""
        return []

    def start(self, rec, recorder) -> None:
        """Log what does not change (static entities) to the recording stream ``rec``."""

    def draw(self, rec, recorder, start: int, stop: int, t_s: np.ndarray) -> None:
        """Log ticks ``start:stop`` (at times ``t_s``, shape (stop - start,)) to ``rec``."""

    def open_files(self, recorder, out_dir: Path) -> dict[str, RunFile]:
        """Open the files it writes (headers only), by the keys of :attr:`files`."""
        return {}


def registered_views() -> dict[str, RunView]:
    """Every recording view the installed plugins register, by name."""
    return registry("view")


def view_roles() -> dict[str, str | None]:
    """Every role's default port: those the domain gives the framework's roles (hook
    ``cosim_default_roles``), then every role a registered view reads."""
    roles: dict[str, str | None] = {}
    get_plugin_manager().hook.cosim_default_roles(register=roles.setdefault)
    for view in registered_views().values():
        for role, port in view.roles.items():
            roles.setdefault(role, port)
    return roles

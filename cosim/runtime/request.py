"""What one run is asked to do: :class:`RunRequest`, the options of a single run.

A sweep's options (how many runs at a time, where they execute, their wall-time
limit) are not a run's: they are :class:`cosim.scale.options.SweepOptions`.
This module imports nothing heavy, so :mod:`cosim.api` can name it without
loading the bus.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class RunRequest:
    """What to run: a scenario file, its overrides, where its outputs go, and how it steps."""

    scenario_file: Path
    out_dir: Path
    overrides: list[str] = field(default_factory=list)
    #: every component in a ``cosim node`` process of its own (zenoh over unix sockets or TCP)
    processes: bool = False
    #: a progress bar on stderr (a sweep: a line per run too)
    progress: bool = True
    #: with ``processes``: where the nodes run (see :mod:`cosim.runtime.placement`)
    node_cpus: str = "auto"
    #: pace the ticks at this factor of real time (None: the scenario's ``realtime``)
    realtime: float | None = None
    #: with ``processes``: a HOSTS.yaml placing the nodes on machines (see :mod:`cosim.runtime.hosts`)
    hosts: Path | None = None
    #: cut the recording into parts of this much simulated time [s] (``part-000/``, ...); None: one
    rotate_s: float | None = None

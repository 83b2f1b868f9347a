"""How a sweep's runs execute: :class:`SweepOptions`, and the ``--jobs`` argument that sets how many at a time.

Apart from a run's own options (:class:`cosim.runtime.request.RunRequest`);
imports nothing heavy.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from cosim.contract.errors import UserError

if TYPE_CHECKING:
    from cosim.runtime.bus import TlsFiles


@dataclass
class SweepOptions:
    """Where and how a sweep's runs execute (a scenario without a sweep ignores them)."""

    #: runs at a time: 1 runs them one after another in this process
    jobs: int = 1
    #: where the runs execute: None (local worker processes when ``jobs`` > 1), ``local``,
    #: ``dask`` or ``dask://HOST:PORT`` (see :mod:`cosim.scale.executors`)
    executor: str | None = None
    #: with ``executor`` ``dask://tls://HOST:PORT``: this client's files of the run's CA (``cosim certs``)
    executor_tls: TlsFiles | None = None
    #: a run still going after this many seconds of wall time is stopped and failed
    run_timeout_s: float | None = None
    #: open workers the sweep runs on instead of its own (several sweeps in a row: see
    #: :func:`cosim.scale.executors.workers`)
    workers: Any = None

    def serial(self) -> bool:
        """Whether the runs go one after another in this process (no workers)."""
        return self.jobs == 1 and self.executor is None and self.workers is None


def add_jobs_argument(parser, what: str) -> None:
    """Add ``--jobs N|auto`` to the argparse ``parser``; ``what`` says what runs that many at a time."""
    parser.add_argument("--jobs", default=None, metavar="N|auto",
                        help=f"{what} (auto: one per CPU this process may use; default 1)")


def parse_jobs(text: str | None, default: int | str = 1) -> int:
    """``--jobs``: a whole number >= 1, or ``auto`` (the CPUs this process may use)."""
    text = str(default) if text is None else text
    if text == "auto":
        return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if not text.isdigit() or int(text) < 1:
        raise UserError(f"--jobs {text}: expected a whole number >= 1 or auto")
    return int(text)

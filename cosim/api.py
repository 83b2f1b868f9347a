"""The framework's public API: what a domain package, a script or a notebook calls.

A plugin implements the contract (:mod:`cosim.contract`: components, paths,
views, hooks) and calls the framework only through this module:

* scenarios: :func:`load_scenario`, :func:`check_scenario`, :func:`load_document`,
  :func:`profile_values`, :func:`make_path`, :func:`component_classes`,
  :func:`register_folder` (ship scenarios to run by name);
* runs and sweeps: :class:`RunRequest` (one run's options), :class:`SweepOptions`
  (where a sweep's runs execute), :func:`run`, :func:`workers` (worker
  processes several sweeps share), :func:`add_jobs_argument` / :func:`parse_jobs`
  (a command's ``--jobs``);
* nodes: :func:`serve_node` (one component of a run in this process);
* figures: :class:`Moments`, :class:`Quantiles` (statistics of a run's values
  accumulated batch by batch, for a :class:`cosim.contract.figures.FigureSet`);
* what a run left: :func:`load_trace`, :func:`iter_trace`; drawing into its
  recording: :data:`TIMELINE`, :func:`log_scalars`, :func:`log_points`, :func:`log_arrows`,
  :func:`component_recording` (these bring rerun, loaded on first use);
* fingerprints and caches: :class:`Fingerprint`, :func:`fingerprint`,
  :func:`class_sources`, :func:`files_digest`, :func:`cache_dir`, :class:`CacheLock`.

Importing this module loads neither the bus (zenoh) nor the recorder: the
run machinery is imported when :func:`run` or :func:`serve_node` is first
called, so a plugin that imports this module costs a command like
``cosim plugins`` nothing.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

from cosim.contract.errors import UserError
from cosim.contract.paths import ReferencePath
from cosim.record.streaming import Moments, Quantiles
from cosim.record.trace_files import iter_trace, load_trace
from cosim.runtime.cache import CacheLock, cache_dir
from cosim.runtime.check import check_runs
from cosim.runtime.fingerprint import Fingerprint, class_sources, files_digest
from cosim.runtime.fingerprint import fingerprint as _fingerprint
from cosim.runtime.request import RunRequest
from cosim.runtime.wiring import build_wiring
from cosim.scale.options import SweepOptions, add_jobs_argument, parse_jobs
from cosim.scenario.catalog import register_folder, resolve_scenario
from cosim.scenario.paths import make_path
from cosim.scenario.schema import Scenario, load_document, profile_values
from cosim.scenario.schema import load_scenario as _load_scenario

#: Names that bring rerun, imported on first use (see :func:`__getattr__`).
_RECORDING_NAMES = ("TIMELINE", "component_recording", "log_arrows", "log_points", "log_scalars")

__all__ = [
    "CacheLock", "Fingerprint", "Moments", "Quantiles", "ReferencePath", "RunRequest", "Scenario", "SweepOptions",
    "add_jobs_argument",
    "cache_dir", "check_scenario", "class_sources", "component_classes", "files_digest", "fingerprint",
    "iter_trace", "load_document", "load_scenario", "load_trace", "make_path", "parse_jobs", "profile_values",
    "register_folder", "resolve_scenario", "run", "serve_node", "workers", *_RECORDING_NAMES,
]


def __getattr__(name: str):
    """The recording helpers of :mod:`cosim.record.rerun_log`, loaded on first use (they bring rerun)."""
    if name in _RECORDING_NAMES:
        from cosim.record import rerun_log

        return getattr(rerun_log, name)
    raise AttributeError(f"module 'cosim.api' has no attribute {name!r}")


def load_scenario(scenario: str | Path, overrides: Sequence[str] = ()) -> Scenario:
    """The validated scenario of a YAML file, or of a shipped scenario by name (``cosim scenarios``),
    with ``overrides`` (``"dotted.key=value"``, as ``cosim run --set``) applied. Raises
    :class:`~cosim.contract.errors.UserError` naming the file, field and line of what is wrong."""
    return _load_scenario(resolve_scenario(str(scenario)), list(overrides))


def check_scenario(scenario_file: str | Path, overrides: Sequence[str] = ()):
    """Check a scenario as ``cosim validate`` and ``cosim run`` do (fields, plugins, parameters, wiring,
    path; each run of a sweep); returns its :class:`~cosim.runtime.wiring.Wiring`."""
    scenario_file = resolve_scenario(str(scenario_file))
    return check_runs(_load_scenario(scenario_file, list(overrides)), scenario_file, list(overrides))


def component_classes(scenario: Scenario) -> dict[str, type]:
    """The component class of each of ``scenario``'s components, by name (its wiring checked)."""
    return dict(build_wiring(scenario).classes)


def fingerprint(scenario: Scenario, scenario_file: str | Path) -> Fingerprint:
    """What running ``scenario`` (read from ``scenario_file``) depends on here: digests of the scenario,
    the code and the files besides code (see :mod:`cosim.runtime.fingerprint`)."""
    return _fingerprint(scenario, scenario_file)


def run(request: RunRequest, sweep: SweepOptions | None = None) -> dict[str, Any]:
    """Run the scenario of ``request``, or every combination of its sweep (where and how ``sweep``
    says: serial in this process by default); returns the summary written to ``request.out_dir``.

    Every run is checked first as ``cosim validate`` checks it: a scenario that does not validate
    writes nothing and raises :class:`~cosim.contract.errors.UserError`. SIGINT and SIGTERM stop the
    run after its tick (``"status": "interrupted"``); a failing component raises
    :class:`~cosim.runtime.scheduler.RunError` once the outputs are written.
    """
    from cosim.runtime.runner import run_one, stop_on_signals

    scenario = _load_scenario(request.scenario_file, request.overrides)
    check_runs(scenario, request.scenario_file, request.overrides)
    if scenario.sweep and (scenario.n_steps is None or None in scenario.sweep.get("duration_s", [])):
        raise UserError(f"{request.scenario_file}: a sweep runs its combinations one after another, so each "
                        "needs a duration_s (null, run until stopped, is for a single run)")
    with stop_on_signals() as stop:
        if not scenario.sweep:
            return run_one(scenario, request, stop)
        from cosim.scale.sweep import run_sweep

        return run_sweep(scenario, request, sweep or SweepOptions(), stop)


def workers(jobs: int, executor: str | None = None):
    """A context manager yielding worker processes that several sweeps share (pass it as
    ``SweepOptions(workers=...)``): ``jobs`` of them, where ``executor`` says (see
    :func:`cosim.scale.executors.open_executor`); None (serial) with ``jobs == 1`` and no executor."""
    from cosim.scale.executors import workers as open_workers

    return open_workers(jobs, executor)


def serve_node(scenario_file: str | Path, component: str, run_id: str, connect: list[str],
               listen: Sequence[str] = (), overrides: Sequence[str] = (), cpus: str | None = None,
               run_dir: Path | None = None, expected: Fingerprint | None = None, tls=None, rights=None) -> int:
    """Serve ``component`` of the scenario in this process until its run ends (what ``cosim node``
    does); returns the exit status. ``connect``: the scheduler's zenoh endpoint and those of the nodes
    started before this one; ``listen``: where later nodes connect; ``expected``: the run's
    fingerprint (another here: refuse to join, status 2); ``tls``: a
    :class:`cosim.runtime.bus.TlsFiles`; ``rights``: the per-host rights of
    :func:`cosim.runtime.rights.parse_rights`."""
    from cosim.runtime.node import serve

    scenario_file = resolve_scenario(str(scenario_file))
    scenario = _load_scenario(scenario_file, list(overrides))
    if component not in scenario.components:
        raise UserError(f"no component {component!r} in {scenario_file} (have: {', '.join(scenario.components)})")
    return serve(scenario, build_wiring(scenario), component, run_id, list(connect), list(listen), cpus, run_dir,
                 expected, tls, scenario_file, rights)

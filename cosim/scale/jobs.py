"""One combination of a sweep as a job: what to run, and running it wherever an executor puts it.

:func:`run_job` runs in a worker process (a local process pool's or a Dask
worker's, possibly on another machine) and returns a plain dict: the run's
summary, the host, the fingerprint of the code and files that made it, and,
for a job that ``ship``s, its run folder as the bytes of a tar archive for
the client to unpack under ``--out``. A run that fails returns its summary
like any other; the job itself raises only if its process breaks.

A job that ships carries its scenario file and the plugin files the
scenario loads, written on the worker under a folder named by their
content (so a worker that runs many jobs registers each plugin once).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import shutil
import tarfile
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

from cosim.contract.errors import RunError
from cosim.contract.plugins import environment_keys, get_plugin_manager, plugin_file_sources
from cosim.record.summary import metric_keys
from cosim.runtime.cache import CACHE_ENV
from cosim.runtime.fingerprint import fingerprint, host_name
from cosim.runtime.request import RunRequest
from cosim.runtime.runner import run_one, stop_on_signals, write_json
from cosim.scenario.schema import load_scenario


@dataclass(frozen=True)
class Job:
    """One run of a sweep. Paths are the client's (absolute)."""

    index: int
    labels: dict[str, Any]
    scenario_file: str
    overrides: tuple[str, ...]
    run_dir: str
    processes: bool = False
    node_cpus: str = "auto"
    realtime: float | None = None
    #: with ``processes``: the HOSTS.yaml placing the nodes (a run over machines; one run at a time)
    hosts: str | None = None
    #: the run's own progress bar (a run in the client's process, one at a time)
    progress: bool = False
    #: stop the run after this many seconds of wall time (None: no limit)
    timeout_s: float | None = None
    env: tuple[tuple[str, str], ...] = ()
    #: run in a scratch folder and return its files (the worker may be another machine)
    ship: bool = False
    #: the name of a Dask event that, once set, stops the run after its tick (a job on a Dask worker)
    stop_event: str | None = None
    #: with ``ship``: (path relative to their common folder, bytes) of the scenario and its plugin files
    sources: tuple[tuple[str, bytes], ...] = ()
    scenario_rel: str = ""


def env_keys() -> tuple[str, ...]:
    """The environment variables that change what a run does, so a job carries the client's: the
    framework's cache folder and those the plugins name (hook ``cosim_register_environment``)."""
    return tuple(dict.fromkeys((CACHE_ENV, *environment_keys())))


def client_env() -> tuple[tuple[str, str], ...]:
    """The environment variables a run's workers need from this process (those of :func:`env_keys` that are set)."""
    return tuple((k, os.environ[k]) for k in env_keys() if k in os.environ)


def scenario_sources(scenario_file: Path, plugin_files: list[Path]) -> tuple[tuple[tuple[str, bytes], ...], str]:
    """The scenario file and the plugin files it loads (with the Python files beside each, see
    :func:`~cosim.contract.plugins.plugin_file_sources`) as ``(relative path, bytes)``, and the
    scenario's own relative path, relative to the folder that holds them all."""
    files = [scenario_file.resolve(), *dict.fromkeys(f.resolve() for p in plugin_files for f in plugin_file_sources(p))]
    root = Path(os.path.commonpath([f.parent for f in files]))
    return tuple((str(f.relative_to(root)), f.read_bytes()) for f in files), str(files[0].relative_to(root))


@contextlib.contextmanager
def _environment(env: tuple[tuple[str, str], ...]) -> Iterator[None]:
    keys = env_keys()
    before = {k: os.environ.get(k) for k in keys}
    for k in keys:
        os.environ.pop(k, None)
    os.environ.update(dict(env))
    try:
        yield
    finally:
        for k, v in before.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _materialise(job: Job) -> Path:
    """Write a shipped job's scenario and plugin files on this worker; returns the scenario's path."""
    digest = hashlib.sha256(b"".join(rel.encode() + b"\0" + data for rel, data in job.sources)).hexdigest()[:16]
    root = Path(tempfile.gettempdir()) / "cosim-jobs" / digest
    for rel, data in job.sources:
        target = root / rel
        if not target.is_file() or target.read_bytes() != data:
            target.parent.mkdir(parents=True, exist_ok=True)
            staging = target.with_name(f".{target.name}.{os.getpid()}.tmp")
            staging.write_bytes(data)
            os.replace(staging, target)
    return root / job.scenario_rel


def warm_up() -> None:
    """Load the plugins (this module's imports brought the runner, the bus and the recorder), so a
    new worker does it while the client still prepares the caches."""
    get_plugin_manager()


def run_job(job: Job) -> dict[str, Any]:
    """Run ``job``; returns ``{"index", "summary", "host", "fingerprint", "files", "stuck"}``.

    ``files``: the run folder as a tar archive (a job that ships), else None;
    ``stuck``: a component's step never returned, so a thread of this process
    is still inside it (the caller retires the process).
    """
    with _environment(job.env):
        if job.ship:
            scenario_file = _materialise(job)
            scratch = Path(tempfile.mkdtemp(prefix="cosim-run-"))
            run_dir = scratch / Path(job.run_dir).name
        else:
            scenario_file, scratch, run_dir = Path(job.scenario_file), None, Path(job.run_dir)
        try:
            summary, made_by = _run(job, scenario_file, run_dir)
            files = pack(run_dir) if job.ship else None
        finally:
            if scratch is not None:
                shutil.rmtree(scratch, ignore_errors=True)
    stuck = any(t.name == "cosim-scheduler" and t.is_alive() for t in threading.enumerate())
    return {"index": job.index, "summary": summary, "host": host_name(), "fingerprint": made_by,
            "files": files, "stuck": stuck}


def _run(job: Job, scenario_file: Path, run_dir: Path) -> tuple[dict, dict | None]:
    """The run's summary (as written in ``run_dir``) and the fingerprint of what made it."""
    made_by = None
    with stop_on_signals() as stop:
        timer = None
        if job.timeout_s:
            timer = threading.Timer(job.timeout_s, stop.request, [f"run timeout ({job.timeout_s:g} s)"])
            timer.daemon = True
            timer.start()
        watching = _watch_stop_event(job.stop_event, stop) if job.stop_event else None
        try:
            scenario = load_scenario(scenario_file, job.overrides)
            made_by = fingerprint(scenario, scenario_file).as_dict()
            request = RunRequest(scenario_file, run_dir, list(job.overrides), job.processes, job.progress,
                                 job.node_cpus, job.realtime, hosts=Path(job.hosts) if job.hosts else None)
            summary = run_one(scenario, request, stop)
        except RunError as exc:
            written = run_dir / "summary.json"
            summary = json.loads(written.read_text()) if written.is_file() else failed_summary(str(exc))
        except Exception as exc:  # bad input or a crash in set-up: this run's row says what
            summary = failed_summary(f"{type(exc).__name__}: {exc}")
            write_json(run_dir / "summary.json", summary)
        finally:
            if timer is not None:
                timer.cancel()
            if watching is not None:
                watching.set()
    if job.timeout_s and stop.reason and stop.reason.startswith("run timeout") and summary["status"] == "interrupted":
        summary = {**summary, "status": "failed",
                   "error": f"did not finish within the run timeout of {job.timeout_s:g} s ({summary['error']})"}
        write_json(run_dir / "summary.json", summary)
    return summary, made_by


def _watch_stop_event(name: str, stop) -> threading.Event:
    """Request ``stop`` when the Dask event ``name`` is set (the sweep was stopped); returns the
    event that ends the watching."""
    from distributed import Event, get_client

    client, done = get_client(), threading.Event()  # the task's client: only its own thread finds it

    def watch() -> None:
        event = Event(name, client=client)
        while not done.is_set():
            try:
                if event.wait(timeout=0.5):
                    stop.request("stopped: the sweep was interrupted")
                    return
            except Exception:  # the cluster went away: nothing to watch
                return

    threading.Thread(target=watch, name="cosim-stop-watch", daemon=True).start()
    return done


def failed_summary(error: str) -> dict[str, Any]:
    """The summary of a run that produced none: failed, with ``error``, no figures."""
    return {"status": "failed", "error": error, **dict.fromkeys(metric_keys())}


def pack(folder: Path) -> bytes:
    """``folder``'s files as a gzip'd tar archive (paths relative to it)."""
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz", compresslevel=1) as tar:
        for path in sorted(folder.rglob("*")):
            if path.is_file():
                tar.add(path, arcname=str(path.relative_to(folder)))
    return buffer.getvalue()


def unpack(data: bytes, folder: Path) -> None:
    """Write the files of a :func:`pack` archive into ``folder`` (replacing what it held)."""
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    with tarfile.open(fileobj=io.BytesIO(data), mode="r:gz") as tar:
        tar.extractall(folder, filter="data")


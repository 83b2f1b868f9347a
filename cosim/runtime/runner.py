"""Run one scenario end to end and write its outputs (a sweep's dispatch: :func:`cosim.api.run`).

One run writes into its output folder: ``summary.json``, ``log.csv``,
``trace.npz`` and ``recording.rrd`` (see :mod:`cosim.runtime.recorder`), the last
three as the run goes. A sweep (:mod:`cosim.scale.sweep`) writes one such
folder per combination under ``runs/``.

Ctrl-C (SIGINT) and SIGTERM stop a run after the tick under way: the
components are closed (outputs made safe), everything recorded is kept and
``summary.json`` says ``"status": "interrupted"``. ``summary.json`` says
``"running"`` while the run goes, so a folder whose process was killed tells so.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from cosim.contract.errors import OutputWriteError, RunError, RunFault, WriteError
from cosim.record.rerun_log import merge_parts, set_aside_parts
from cosim.record.summary import run_figures
from cosim.runtime import bus
from cosim.runtime.fingerprint import fingerprint
from cosim.runtime.groups import WINDOW, LocalGroup, RemoteGroup, with_close_faults
from cosim.runtime.hosts import load_hosts
from cosim.runtime.launch import NODE_START_TIMEOUT_S, node_commands, start_nodes
from cosim.runtime.placement import node_cpus, threads_started_off
from cosim.runtime.portcache import PortCache, PortStore
from cosim.runtime.private_bus import PrivateEndpoints
from cosim.runtime.recorder import TraceRecorder
from cosim.runtime.request import RunRequest
from cosim.runtime.rights import access_control, format_rights, rights_of
from cosim.runtime.scheduler import Scheduler, StopRequest
from cosim.runtime.security_log import FILE_NAME as SECURITY_FILE
from cosim.runtime.security_log import SecurityLog, ZenohDenials
from cosim.runtime.stepper import Stepper, setup_component
from cosim.runtime.wiring import build_wiring
from cosim.scenario.paths import make_path
from cosim.scenario.schema import Scenario


@contextlib.contextmanager
def stop_on_signals():
    """SIGINT and SIGTERM request a stop (yields the :class:`StopRequest`); a second signal
    only says that the stop is under way. Outside the main thread, signals are left alone."""
    stop = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def handler(signum, frame):
        name = signal.Signals(signum).name
        if stop.request(f"stopped by {name}"):
            print(f"\ncosim: {name}: stopping after this tick (outputs made safe, everything recorded kept)",
                  file=sys.stderr, flush=True)
        else:
            print(f"\ncosim: {name}: already stopping", file=sys.stderr, flush=True)

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stop
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def run_one(scenario: Scenario, request: RunRequest, stop: StopRequest | None = None) -> dict[str, Any]:
    """Run one scenario (no sweep) into ``request.out_dir``; returns and writes ``summary.json``.

    A component failure still writes the outputs recorded so far and the
    summary (with ``status: "failed"``), then raises :class:`RunError`; a
    ``stop`` request ends the run with ``status: "interrupted"``.
    """
    stop = stop or StopRequest()
    cpus = node_cpus(request.node_cpus) if request.processes else None
    wiring = build_wiring(scenario)
    path = make_path(scenario.path.plugin, scenario.path.params) if scenario.path else None
    plan = load_hosts(request.hosts, scenario) if request.processes and request.hosts else None
    out = Path(request.out_dir)  # made only once the scenario and the hosts file have validated
    out.mkdir(parents=True, exist_ok=True)
    run_id = secrets.token_hex(4)
    set_aside_parts(out)  # an earlier run's parts are never merged into this run's recording
    recorder = TraceRecorder(scenario, wiring, out, path, request.rotate_s)
    recorder.open()
    realtime = request.realtime or scenario.realtime
    write_json(out / "summary.json", {"scenario": scenario.name, "status": "running", "pid": os.getpid(),
                                       "note": "written when the run started; a run that ends rewrites it"})
    # one machine: unix sockets in a 0700 folder of this run, which no other user can reach
    private = PrivateEndpoints() if request.processes and not plan else None
    endpoint = (plan.scheduler_listen if plan else private.endpoint("scheduler")) if request.processes else None
    rights = rights_of(plan) if plan and plan.scheduler_tls else None  # TLS: rights by certificate name
    access = access_control(run_id, wiring, rights) if rights else None
    security = SecurityLog(out, "scheduler")
    denials = ZenohDenials(security) if access else None  # what access control refuses, in security.jsonl
    away = cpus if endpoint and not plan else None  # the scheduler's threads keep off the nodes' CPUs
    try:
        with threads_started_off(away):
            session = bus.open_session(listen=[endpoint], tls=plan.scheduler_tls if plan else None,
                                       access=access) if endpoint else bus.open_session()
    except BaseException:
        if private is not None:
            private.close()
        if denials is not None:
            denials.close()
        raise
    # in one process the scheduler reads every port off the bus; nodes' replies carry their outputs
    # rows kept per producer: a consumer over a delay of d ticks reads d rows back, behind producers up to
    # WINDOW ticks ahead (nodes) or one (lockstep)
    delay = wiring.max_delay()
    cache = PortStore(wiring.outputs, keep=WINDOW + 1 + max(delay, 1)) if endpoint \
        else PortCache(session, run_id, wiring.outputs, keep=2 + max(delay, 1))
    procs: list[subprocess.Popen] = []
    group = scheduler = error = None
    completed = 0
    late_faults: dict[str, str] = {}  # set by components closed here, after a failed set-up
    wall0 = time.perf_counter()
    try:
        if endpoint:
            with threads_started_off(away):  # its subscribers' callback threads
                group = RemoteGroup(session, run_id, wiring, cache, security)
            expected = fingerprint(scenario, request.scenario_file)
            commands = node_commands(request.scenario_file, request.overrides, wiring.order, run_id, endpoint,
                                     out, expected, cpus, private.endpoint if private else None, plan,
                                     format_rights(rights) if rights else None)
            start_nodes(commands, group, expected, procs, plan.wait_s if plan else NODE_START_TIMEOUT_S, stop)
            group.processes = dict(zip([c.component for c in commands if c.launch != "manual"], procs))
        else:
            steppers = {}
            group = LocalGroup(steppers)
            for name in wiring.order:
                timeout = scenario.components[name].timeout_s or scenario.timeout_s
                steppers[name] = Stepper(name, setup_component(scenario, wiring, name, out), session, run_id,
                                         wiring, cache, timeout)
        scheduler = Scheduler(scenario, wiring, group, cache, [recorder], realtime, stop, away)
        with _progress_bar(scenario.n_steps, request.progress, scheduler.pacer) as bar:
            try:
                completed = scheduler.run(on_progress=bar)
            except RunError as exc:
                error, completed = exc, recorder.ticks
    except RunError as exc:  # in set-up: nothing ran
        error = exc
    except BaseException as exc:  # set-up failed otherwise (or Ctrl-C before the handlers): say so, then raise
        write_json(out / "summary.json", {"scenario": scenario.name, "status": "failed", "phase": "set-up",
                                           "error": f"set-up: {type(exc).__name__}: {exc}"})
        raise
    finally:
        if group is not None:  # closed already unless set-up failed
            late_faults = group.close(hung=None)
        end_nodes(procs)
        if isinstance(cache, PortCache):
            cache.close()
        session.close()
        if denials is not None:
            denials.close()
        if private is not None:
            private.close()
    total_wall = time.perf_counter() - wall0
    if late_faults:
        error = with_close_faults(error, late_faults)
    recorder.finish(str(error) if error else None)  # a no-op unless set-up failed
    merge_parts(out)  # what components recorded themselves, now that their processes have ended
    stopped = stop.event.is_set() and (scenario.n_steps is None or completed < scenario.n_steps)
    summary = _summary(scenario, recorder, completed, scheduler.loop_wall_s if scheduler else 0.0, total_wall,
                       error, stop.reason if stopped else None)
    if scheduler and scheduler.input_ended and not error:
        summary["end"] = f"input ended ({scheduler.input_ended})"
    if scheduler and scheduler.pacer:
        summary["realtime"] = scheduler.pacer.summary()
    if getattr(group, "security_events", None):  # samples and replies dropped as not the rightful publisher's
        summary["security_events"] = group.security_events[:20]
    events = security.count + getattr(group, "node_security_events", 0)
    if events:  # every one with its time, key and reason in security.jsonl (see cosim.runtime.security_log)
        summary["security_event_count"] = events
        summary["security_log"] = SECURITY_FILE
    write_json(out / "summary.json", summary)
    if isinstance(error, WriteError):  # one line naming the file, not a component
        raise error
    if error:
        raise RunError(error.component, f"{str(error).split(': ', 1)[-1]} (recorded so far: {out})")
    return summary


#: How long the node processes started here have to exit by themselves once the run has closed them,
#: and then once sent SIGTERM, before they are killed [s].
NODE_EXIT_S = (1.0, 5.0)


def end_nodes(procs: list[subprocess.Popen]) -> None:
    """End the node processes started here once the run is over. The nodes that joined were told to
    stop and have closed their components (or did not confirm within the close timeout), so they
    exit by themselves; a node still starting (another's set-up failed meanwhile) never heard it,
    so the ones still running are sent SIGTERM (a node closes its component on it) and then killed."""
    for grace_s, last in zip(NODE_EXIT_S, (False, True)):
        deadline = time.monotonic() + grace_s
        for proc in procs:
            try:
                proc.wait(timeout=max(deadline - time.monotonic(), 0.0))
            except subprocess.TimeoutExpired:
                if last:
                    proc.kill()
                    proc.wait()
        if not last:
            for proc in procs:
                if proc.poll() is None:
                    proc.terminate()


def _summary(scenario: Scenario, recorder: TraceRecorder, completed: int, wall_s: float,
             total_wall_s: float, error: RunError | None, interrupted: str | None) -> dict[str, Any]:
    """``wall_time_s`` and ``realtime_factor`` cover the stepping loop; ``total_wall_time_s``
    adds set-up (processes, FMU instantiation) and writing the outputs."""
    sim = completed * scenario.dt_s
    status = "fault" if isinstance(error, RunFault) else "failed" if error else \
        "interrupted" if interrupted else "ok"
    return {
        "scenario": scenario.name,
        "status": status,
        "error": str(error) if error else f"{interrupted} at t = {sim:.3f} s" if interrupted else None,
        **({"phase": error.phase} if isinstance(error, WriteError) else {}),
        **run_figures(recorder),
        "steps": completed,
        "sim_time_s": sim,
        "wall_time_s": wall_s,
        "realtime_factor": sim / wall_s if wall_s > 0 else None,
        "total_wall_time_s": total_wall_s,
        "files": recorder.file_names(),
    }


class _progress_bar:
    """tqdm over ticks, shown only when a run lasts more than a couple of seconds;
    with a :class:`~cosim.runtime.pacing.Pacer`, the last tick's lateness and the misses so far."""

    def __init__(self, total: int, enabled: bool, pacer=None):
        self.total, self.enabled, self.pacer, self.bar = total, enabled, pacer, None

    def __enter__(self):
        if self.enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=self.total, unit="step", delay=2.0, file=sys.stderr, leave=False)
        return self

    def __call__(self, done: int) -> None:
        if self.bar is not None:
            if self.pacer is not None:
                self.bar.set_postfix_str(f"late {self.pacer.latest_ms():.2f} ms, missed {self.pacer.missed}",
                                         refresh=False)
            self.bar.update(done - self.bar.n)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()


def write_json(path: Path, obj) -> None:
    """Write ``obj`` as JSON; a failure (a full disk) is an OutputWriteError naming the file."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(obj, indent=2) + "\n")
    except OSError as exc:
        raise OutputWriteError(path, exc) from exc

"""The lockstep master: every component steps once per tick of its period.

Each tick ``k`` (``t = k * dt``) every component whose period divides ``k``
takes one step; its outputs go out on the bus and its consumers read them
from there, stamped with the tick that produced them, so the result does
not depend on where components run:

a :class:`~cosim.runtime.groups.LocalGroup` (components in this process) or
a :class:`~cosim.runtime.groups.RemoteGroup` (each in a ``cosim node``
process, up to ``WINDOW`` ticks ahead); see :mod:`cosim.runtime.groups`.

The loop runs in a worker thread while the calling thread watches it: a step
that exceeds its timeout, raises, or whose node disappears (liveliness token
gone) stops the run with the component's name; :class:`StopRequest`
(Ctrl-C, SIGTERM) ends it after the tick under way. Either way the
components are closed first (an actuator's driver makes its outputs safe; a fault it
finds while doing so ends the run with status ``fault``), then the observers
finish what they recorded. With a :class:`~cosim.runtime.pacing.Pacer`
ticks follow the wall clock, and nodes are granted one tick at a time.
"""

from __future__ import annotations

import itertools
import threading
import time
from typing import Callable, Protocol

import numpy as np

from cosim.contract.component import ComponentFault, InputEnded
from cosim.contract.errors import OutputWriteError, PortTimeout, RunError, RunFault, WriteError  # noqa: F401 (named here)
from cosim.runtime.groups import (  # noqa: F401 (the runner and the nodes name them here too)
    CLOSE_TIMEOUT_S,
    FLUSH_GRACE_S,
    REPLY_BATCH,
    STALL_BLAME_S,
    STALL_S,
    WINDOW,
    LocalGroup,
    NodeInputEnded,
    Progress,
    RemoteGroup,
    with_close_faults,
)
from cosim.runtime.pacing import Pacer
from cosim.runtime.placement import keep_thread_off
from cosim.runtime.portcache import PortStore, expected_stamp
from cosim.runtime.wiring import Wiring
from cosim.scenario.schema import Scenario


class StopRequest:
    """A request to stop the run(s) after the tick under way, and why (set from a signal handler)."""

    def __init__(self):
        self.event = threading.Event()
        self.reason: str | None = None

    def request(self, reason: str) -> bool:
        """False when a stop was already requested."""
        if self.event.is_set():
            return False
        self.reason = reason
        self.event.set()
        return True


class Observer(Protocol):
    """Read-only watcher of a run (recorders, loggers). Never changes the run."""

    def on_tick(self, tick: int, t: float, rows: dict[str, np.ndarray]) -> None:
        """Each component's outputs at ``tick`` (flat float64, its ports laid end to end in declared order)."""

    def finish(self, error: str | None, event: str | None = None) -> None:
        """The run ended (``error``: why it failed); ``event``: the failure or stop, to note."""


class Scheduler:
    """Runs one scenario's lockstep loop over a group of components."""

    def __init__(self, scenario: Scenario, wiring: Wiring, group: LocalGroup | RemoteGroup,
                 cache: PortStore, observers: list[Observer], realtime_factor: float | None = None,
                 stop: StopRequest | None = None, node_cpus: str | None = None):
        self.scenario, self.wiring, self.group = scenario, wiring, group
        self.cache, self.observers = cache, observers
        self.stop = stop or StopRequest()
        self.stop_event = self.stop.event
        self.pacer = (Pacer(scenario.dt_s, realtime_factor, scenario.n_steps, self.stop_event)
                      if realtime_factor else None)
        self.timeouts = {n: scenario.components[n].timeout_s or scenario.timeout_s for n in wiring.order}
        #: (component, period) of every component with outputs: what the observers get each tick
        self._observed = [(c, wiring.periods[c]) for c in wiring.order if wiring.outputs[c]]
        self.progress = Progress()
        self.loop_wall_s = 0.0  # wall time of the ticks alone (set-up and writing excluded)
        self.input_ended: str | None = None  # why a replayed input ended the run, if one did
        self._flushed: tuple = (None, 0.0)  # (occasion, time) of the watchdog's last flush
        self._stalled_at: float | None = None  # when this process last resumed after not running
        self._stall_s = 0.0  # for how long it had not run
        self.node_cpus = node_cpus  # the CPUs the nodes run on: the stepping thread keeps off them

    def run(self, on_progress: Callable[[int], None] | None = None) -> int:
        """Run the ticks (all, or up to a requested stop); returns the number completed.

        Raises :class:`RunError` on a failure. The components are closed before
        the observers finish, so outputs are made safe before anything is written.
        """
        worker = threading.Thread(target=self._work, name="cosim-scheduler", daemon=True)
        worker.start()
        state = self.progress
        last = time.monotonic()
        while not state.done:
            worker.join(timeout=0.05)
            now = time.monotonic()
            if now - last > STALL_S:  # this process itself did not run (stopped, starved)
                self._stalled_at, self._stall_s = now, now - last
            last = now
            if on_progress:
                on_progress(state.tick + 1)
            self._watch()
        faulted = isinstance(state.error, RunFault)  # its tick was recorded, as far as it went
        completed = state.tick + 1 if (faulted or not state.error) else state.tick
        close_faults = self.group.close(hung=state.hung)
        if close_faults:
            state.error = with_close_faults(state.error, close_faults)
        error = str(state.error) if state.error else None
        for text in getattr(self.group, "security_events", ())[:20]:  # into the recording, bounded
            for obs in self.observers:
                if hasattr(obs, "security_event"):
                    obs.security_event(text)
        for obs in self.observers:
            try:
                obs.finish(error, error or self.stop.reason or self.input_ended)
            except OutputWriteError as exc:  # the first failure stands (a write that failed while stepping fails again)
                if state.error is None:
                    state.error = WriteError(exc, "writing the outputs")
        if state.error:
            raise state.error
        return completed

    def _watch(self) -> None:
        """Stop the run when a step outlives its timeout or a node's process is gone."""
        state = self.progress
        if state.done:
            return
        dead = self.group.dead()
        if dead:
            tick = max(state.tick, 0)
            if self._stalled_at is not None and time.monotonic() - self._stalled_at < STALL_BLAME_S:
                self._stop("scheduler", f"the scheduler's own process did not run for {self._stall_s:.1f} s "
                                        f"(paused, or starved of CPU), so its nodes took it for gone and stopped "
                                        f"(tick {tick})")
            elif self._heard_out("dead", [n for n in self.wiring.order if n not in dead]):
                first = next(n for n in self.wiring.order if n in dead)  # wiring order, not the alphabet
                self._stop(first, self.group.gone_reason(first, tick))
            return
        pending, since = state.pending, state.since
        if not pending or time.monotonic() - since <= min(self.timeouts[n] for n in pending):
            return
        limit = self.timeouts[pending[0]]  # the first unfinished in wiring order: the others wait on it
        if self._heard_out(since, pending) and time.monotonic() - since > limit:
            t = max(state.tick, 0) * self.scenario.dt_s
            self._stop(pending[0], f"step at t = {t:.3f} s did not finish within {limit:g} s (hung)")
            state.hung = pending[0]

    def _heard_out(self, occasion, names) -> bool:
        """Whether ``names`` have had ``FLUSH_GRACE_S`` to report the steps they hold back
        since the watchdog first asked them on this ``occasion`` (local steps: at once)."""
        if self._flushed[0] != occasion:
            if not self.group.flush(tuple(names)):
                return True
            self._flushed = (occasion, time.monotonic())
        return time.monotonic() - self._flushed[1] >= FLUSH_GRACE_S

    def _stop(self, component: str, reason: str) -> None:
        state = self.progress
        state.error = RunError(component, reason)
        state.done = True
        self.group.interrupt(component, reason)

    def _observed_missing(self) -> list[str]:
        return [c for c, _ in self._observed if not self.cache.has(c, -1)]

    def _work(self) -> None:
        state, dt, order = self.progress, self.scenario.dt_s, self.wiring.order
        periods, pacer = self.wiring.periods, self.pacer
        if self.node_cpus is not None:
            keep_thread_off(self.node_cpus)
        try:
            self.group.start(order, state, self._observed_missing)
            n_steps = self.scenario.n_steps  # None: until stopped
            self.group.plan(n_steps, 1 if pacer else WINDOW)
            if pacer:
                pacer.realtime_priority()
            wall0 = time.perf_counter()
            for tick in (range(n_steps) if n_steps is not None else itertools.count()):
                if self.stop_event.is_set() or (pacer and not pacer.wait()):
                    return
                t = tick * dt
                state.tick = tick
                self.group.step(tick, t, [n for n in order if tick % periods[n] == 0], state)
                state.busy()
                self._observe(tick, t)
                self.loop_wall_s = time.perf_counter() - wall0
                if state.done:  # the watchdog gave up on us
                    return
        except InputEnded as exc:  # a replayed input ran out: the run ends with the ticks before this one
            name = exc.component if isinstance(exc, NodeInputEnded) else \
                state.pending[0] if state.pending else "a component"
            self.input_ended = f"{name}: {exc}"
            if isinstance(exc, NodeInputEnded):  # nodes run ahead: record the ticks every component finished
                self._catch_up(exc.tick)
            state.tick -= 1
        except PortTimeout as exc:
            self._fail(RunError(exc.component, f"{exc.what} for tick {exc.stamp} never arrived"))
        except OutputWriteError as exc:  # an observer could not write (a full disk): stop, keep what was written
            self._fail(WriteError(exc, "stepping", max(state.tick, 0) * dt))
        except RunError as exc:
            self._catch_up(exc.tick)
            if isinstance(exc, RunFault):  # record the fault's tick as far as it went
                self._observe(state.tick, state.tick * dt, partial=True)
            self._fail(exc)
        except ComponentFault as exc:
            self._observe(state.tick, state.tick * dt, partial=True)
            self._fail(RunFault(state.pending[0] if state.pending else "scheduler",
                                f"{exc} (t = {max(state.tick, 0) * dt:.3f} s)"))
        except Exception as exc:  # a local component's failure, reported with its name
            name = state.pending[0] if state.pending else "scheduler"
            self._fail(RunError(name, f"failed at t = {max(state.tick, 0) * dt:.3f} s: {type(exc).__name__}: {exc}"))
        finally:
            state.done = True

    def _catch_up(self, failed_tick: int | None) -> None:
        """Record the ticks before a node's failure that every component finished
        (nodes run ahead of the tick being recorded); ``state.tick`` ends on the first
        tick not recorded."""
        state, dt = self.progress, self.scenario.dt_s
        if failed_tick is None:
            return
        while state.tick < failed_tick and all(self.cache.has(c, expected_stamp(state.tick, per, 0))
                                               for c, per in self._observed):
            self._observe(state.tick, state.tick * dt)
            state.tick += 1

    def _observe(self, tick: int, t: float, partial: bool = False) -> None:
        """Give the observers every port's value at ``tick``; ``partial`` (a fault stopped the
        tick midway) gives what was published and leaves the rest out."""
        cache = self.cache
        if partial:
            rows = {c: cache.row(c, s) for c, per in self._observed if cache.has(c, s := expected_stamp(tick, per, 0))}
        else:
            timeout = self.scenario.timeout_s
            rows = {c: cache.row(c, tick - tick % per, timeout) for c, per in self._observed}
        for obs in self.observers:
            obs.on_tick(tick, t, rows)

    def _fail(self, error: RunError) -> None:
        if self.progress.error is None:  # the watchdog's reason, if it spoke first, stands
            self.progress.error = error

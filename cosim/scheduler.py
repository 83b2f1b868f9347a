"""The lockstep master: every component steps once per tick of its period.

Each tick ``k`` (``t = k * dt``) every component whose period divides ``k``
takes one step; its outputs go out on the bus and its consumers read them
from there, stamped with the tick that produced them, so the result does
not depend on where components run:

* :class:`LocalGroup`: components in this process, stepped one by one in
  the wiring's topological order;
* :class:`RemoteGroup`: each component in a ``cosim node`` process; one tick
  message goes to all, each node steps as soon as its inputs for that tick
  have arrived, and the tick ends when every due node has replied.

The loop runs in a worker thread while the calling thread watches it: a step
that exceeds its timeout, raises, or whose node disappears (liveliness token
gone) stops the run with the component's name, after the observers have
flushed what was recorded so far.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np
import zenoh

from cosim import bus
from cosim.component import ComponentFault
from cosim.errors import UserError
from cosim.portcache import PortCache, PortTimeout, expected_stamp
from cosim.scenario import Scenario
from cosim.stepper import Stepper
from cosim.wiring import Wiring


class RunError(UserError):
    """A run stopped because a component failed, hung or vanished."""

    def __init__(self, component: str, message: str):
        super().__init__(f"component {component!r}: {message}")
        self.component = component


class RunFault(RunError):
    """A component stopped the run on an unsafe condition (its outputs were made safe first)."""

    def __init__(self, component: str, message: str):
        super().__init__(component, f"fault: {message}")


class Observer(Protocol):
    """Read-only watcher of a run (recorders, loggers). Never changes the run."""

    def on_tick(self, tick: int, t: float, values: dict[tuple[str, str], np.ndarray]) -> None: ...

    def finish(self, error: str | None) -> None: ...


@dataclass
class Progress:
    """What the worker is doing, read by the watchdog."""

    tick: int = -1
    pending: tuple[str, ...] = ()
    since: float = field(default_factory=time.monotonic)
    error: BaseException | None = None
    done: bool = False

    def busy(self, *names: str) -> None:
        self.pending, self.since = names, time.monotonic()


class LocalGroup:
    """Components in the scheduler's process, stepped in wiring order."""

    def __init__(self, steppers: dict[str, Stepper]):
        self.steppers = steppers

    def start(self, order: list[str], progress: Progress, observed_ready: Callable[[], list[str]]) -> None:
        for name in order:
            progress.busy(name)
            self.steppers[name].publish_initial()

    def plan(self, n_steps: int, dt_s: float) -> None:
        """Nothing to plan: local steps happen one at a time."""

    def step(self, tick: int, t: float, due: list[str], progress: Progress) -> None:
        for name in due:
            progress.busy(name)
            self.steppers[name].step(tick, t)

    def dead(self) -> list[str]:
        return []

    def interrupt(self, name: str, reason: str) -> None:
        """A stuck local step cannot be woken; the worker thread is abandoned."""

    def close(self, hung: str | None) -> None:
        for name, stepper in self.steppers.items():
            if name != hung:  # its thread is stuck inside step(); closing would block too
                _close_quietly(name, stepper.close)


#: Ticks a remote run may send ahead of the one it waits for.
LOOKAHEAD = 2


class RemoteGroup:
    """Components each in a ``cosim node`` process, driven over zenoh (see :mod:`cosim.node`).

    The worker waits for replies in a blocking ``recv``; the watchdog and the
    liveliness watcher wake it by publishing a failure reply on the reply key
    (a local put is delivered at once), so no thread stays blocked in zenoh.
    """

    def __init__(self, session: zenoh.Session, run_id: str, names: list[str]):
        self.names = names
        self._dead: set[str] = set()
        self._tick_pub = bus.publisher(session, bus.tick_key(run_id))
        self._cmd_pubs = {n: bus.publisher(session, bus.ctl_key(run_id, n, "cmd")) for n in names}
        self._wake_pubs = {n: bus.publisher(session, bus.ctl_key(run_id, n, "reply")) for n in names}
        self._replies = session.declare_subscriber(bus.ctl_key(run_id, "*", "reply"))
        self._early: dict[tuple, dict] = {}
        self._alive = session.liveliness().declare_subscriber(bus.alive_key(run_id), self._on_alive)

    def _on_alive(self, sample: zenoh.Sample) -> None:
        name = str(sample.key_expr).rsplit("/", 1)[-1]
        if sample.kind == zenoh.SampleKind.DELETE and name in self._cmd_pubs:
            self._dead.add(name)

    def dead(self) -> list[str]:
        return sorted(self._dead)

    def interrupt(self, name: str, reason: str) -> None:
        self._wake_pubs[name].put(bus.encode_json({"name": name, "ok": False, "error": reason}))

    def command(self, name: str, cmd: str) -> None:
        self._cmd_pubs[name].put(bus.encode_json({"cmd": cmd}))

    def gather(self, names, tick: int, phase: str | None, progress: Progress | None = None,
               resend: Callable[[list[str]], None] | None = None) -> dict[str, dict]:
        """Wait for one reply of ``phase`` for ``tick`` from each of ``names``.

        With ``resend`` (set-up only, where a message can precede its route),
        the request is sent again to those that have not answered within 0.5 s.
        """
        pending, got = set(names), {}

        def answered(name: str, reply: dict) -> None:
            pending.discard(name)
            got[name] = reply
            if progress is not None:  # the first unfinished in wiring order is the one to blame
                progress.pending = tuple(n for n in progress.pending if n in pending)

        for name in list(pending):  # replies that came ahead of their turn
            reply = self._early.pop((name, tick, phase), None)
            if reply is not None:
                answered(name, reply)
        while pending:
            if resend is None:
                sample = self._replies.recv()
            else:
                sample = bus.poll(self._replies.try_recv, 0.5)
                if sample is None:
                    resend(sorted(pending))
                    continue
            reply = bus.decode_json(sample.payload.to_bytes())
            name = reply.get("name", "?")
            if reply.get("fault"):
                raise RunFault(name, reply["fault"])
            if not reply.get("ok", False):
                raise RunError(name, reply.get("error", "failed"))
            if name in pending and reply.get("tick") == tick and reply.get("phase") == phase:
                answered(name, reply)
            elif reply.get("tick", -1) > tick:  # a node already working on a later tick
                self._early[(name, reply["tick"], reply.get("phase"))] = reply
        return got

    def poll_reply(self, timeout_s: float) -> dict | None:
        """One reply within ``timeout_s`` (used while nodes start), else None."""
        sample = bus.poll(self._replies.try_recv, timeout_s)
        return None if sample is None else bus.decode_json(sample.payload.to_bytes())

    def start(self, order: list[str], progress: Progress, observed_missing: Callable[[], list[str]],
              tries: int = 100) -> None:
        """Publish every initial output; repeat until every route has delivered one.

        A zenoh route between two nodes exists only once both declarations
        have propagated through the router; a value sent earlier is lost, so
        producers re-send until every consumer confirms receipt.
        """
        def init(names):
            for name in names:
                self.command(name, "init")

        def check(names):  # over the tick key, so its routes are proven too
            self._tick_pub.put(bus.encode_json({"tick": -1, "t": 0.0, "check": True}))

        senders = list(order)
        for _ in range(tries):
            progress.busy(*senders)
            init(senders)
            self.gather(senders, -1, "init", resend=init)
            progress.busy(*order)
            check(order)
            replies = self.gather(order, -1, "check", resend=check)
            missing = {m.split(".")[0] for r in replies.values() for m in r["missing"]}
            missing.update(observed_missing())
            if not missing:
                return
            senders = [n for n in order if n in missing]
            time.sleep(0.02)
        raise RunError(senders[0], "its initial outputs never reached their consumers")

    def plan(self, n_steps: int, dt_s: float) -> None:
        self._n_steps, self._dt_s, self._sent = n_steps, dt_s, 0

    def step(self, tick: int, t: float, due: list[str], progress: Progress) -> None:
        """Send ticks up to ``LOOKAHEAD`` ahead, then wait for this tick's replies.

        Nodes step as soon as their inputs for a tick have arrived, so the
        plant can start tick k+1 the moment the coil driver's tick-k output
        reaches it, without a round trip through the scheduler; stamps keep
        the result identical to strict lockstep.
        """
        progress.busy(*due)
        while self._sent < min(tick + LOOKAHEAD, self._n_steps):
            self._tick_pub.put(bus.encode_json({"tick": self._sent, "t": self._sent * self._dt_s}))
            self._sent += 1
        self.gather(due, tick, None, progress)

    def close(self, hung: str | None) -> None:
        for name in self.names:
            if name not in self._dead:
                _close_quietly(name, lambda n=name: self.command(n, "stop"))
        for entity in (self._tick_pub, *self._cmd_pubs.values(), *self._wake_pubs.values(),
                       self._replies, self._alive):
            entity.undeclare()


def _close_quietly(name: str, close: Callable[[], None]) -> None:
    import sys

    try:
        close()
    except Exception as exc:  # closing must not hide the run's own outcome
        print(f"cosim: closing {name} failed: {exc}", file=sys.stderr)


class Scheduler:
    """Runs one scenario's lockstep loop over a group of components."""

    def __init__(self, scenario: Scenario, wiring: Wiring, group: LocalGroup | RemoteGroup,
                 cache: PortCache, observers: list[Observer]):
        self.scenario, self.wiring, self.group = scenario, wiring, group
        self.cache, self.observers = cache, observers
        self.timeouts = {n: scenario.components[n].timeout_s or scenario.timeout_s for n in wiring.order}
        self._observed = [(c, p.name, wiring.periods[c]) for c in wiring.order for p in wiring.outputs[c]]
        self.progress = Progress()
        self.loop_wall_s = 0.0  # wall time of the ticks alone (set-up and writing excluded)

    def run(self, on_progress: Callable[[int], None] | None = None) -> int:
        """Run all ticks; returns the number completed. Raises :class:`RunError` on a failure."""
        worker = threading.Thread(target=self._work, name="cosim-scheduler", daemon=True)
        worker.start()
        state = self.progress
        while not state.done:
            worker.join(timeout=0.05)
            if on_progress:
                on_progress(state.tick + 1)
            self._watch()
        faulted = isinstance(state.error, RunFault)  # its tick was recorded, as far as it went
        completed = state.tick + 1 if (faulted or not state.error) else state.tick
        for obs in self.observers:
            obs.finish(str(state.error) if state.error else None)
        if state.error:
            raise state.error
        return completed

    def _watch(self) -> None:
        """Stop the run when a step outlives its timeout or a node's process is gone."""
        state = self.progress
        if state.done:
            return
        for name in self.group.dead():
            return self._stop(name, f"its process ended unexpectedly (tick {max(state.tick, 0)})")
        pending = state.pending
        if pending:
            limit = self.timeouts.get(pending[0], self.scenario.timeout_s)  # the others wait on it
            if time.monotonic() - state.since > limit:
                t = max(state.tick, 0) * self.scenario.dt_s
                self._stop(pending[0], f"step at t = {t:.3f} s did not finish within {limit:g} s (hung)")

    def _stop(self, component: str, reason: str) -> None:
        state = self.progress
        state.error = RunError(component, reason)
        state.done = True
        self.group.interrupt(component, reason)

    def _observed_missing(self) -> list[str]:
        return [c for c, p, _ in self._observed if not self.cache.has(c, p, -1)]

    def _work(self) -> None:
        state, dt, order = self.progress, self.scenario.dt_s, self.wiring.order
        periods = self.wiring.periods
        try:
            self.group.start(order, state, self._observed_missing)
            self.group.plan(self.scenario.n_steps, dt)
            wall0 = time.perf_counter()
            for tick in range(self.scenario.n_steps):
                t = tick * dt
                state.tick = tick
                self.group.step(tick, t, [n for n in order if tick % periods[n] == 0], state)
                state.busy()
                self._observe(tick, t)
                self.loop_wall_s = time.perf_counter() - wall0
                if state.done:  # the watchdog gave up on us
                    return
        except PortTimeout as exc:
            self._fail(RunError(exc.component, f"its output {exc.port!r} for tick {exc.stamp} never arrived"))
        except RunFault as exc:  # a node's fault: record the tick as far as it went
            self._observe(state.tick, state.tick * dt, partial=True)
            self._fail(exc)
        except RunError as exc:
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

    def _observe(self, tick: int, t: float, partial: bool = False) -> None:
        """Give the observers every port's value at ``tick``; ``partial`` (a fault stopped the
        tick midway) gives what was published and leaves the rest out."""
        if partial:
            values = {(c, p): self.cache.get(c, p, s, 0.0) for c, p, per in self._observed
                      if self.cache.has(c, p, s := expected_stamp(tick, per, 0))}
        else:
            values = {(c, p): self.cache.get(c, p, expected_stamp(tick, per, 0), self.scenario.timeout_s)
                      for c, p, per in self._observed}
        for obs in self.observers:
            obs.on_tick(tick, t, values)

    def _fail(self, error: RunError) -> None:
        if self.progress.error is None:  # the watchdog's reason, if it spoke first, stands
            self.progress.error = error

"""The lockstep master: every component steps once per tick of its period.

Each tick ``k`` (``t = k * dt``) every component whose period divides ``k``
takes one step; its outputs go out on the bus and its consumers read them
from there, stamped with the tick that produced them, so the result does
not depend on where components run:

* :class:`LocalGroup`: components in this process, stepped one by one in
  the wiring's topological order;
* :class:`RemoteGroup`: each component in a ``cosim node`` process; credits
  let the nodes run up to ``WINDOW`` ticks ahead, each node steps a granted
  tick as soon as its inputs for it have arrived, and a tick ends when every
  due node has reported it; the reports carry the outputs, which the
  scheduler keeps for its observers.

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
import queue
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np
import zenoh

from cosim.contract.component import ComponentFault, InputEnded
from cosim.contract.errors import OutputWriteError, UserError
from cosim.runtime import bus
from cosim.runtime.pacing import Pacer
from cosim.runtime.placement import keep_thread_off
from cosim.runtime.portcache import PortStore, PortTimeout, expected_stamp
from cosim.runtime.security_log import SecurityLog
from cosim.runtime.stepper import Stepper
from cosim.runtime.wiring import Wiring
from cosim.scenario.schema import Scenario


class RunError(UserError):
    """A run stopped because a component failed, hung or vanished.

    ``tick``: the step that failed, when a node reported it (nodes may be
    ahead of the tick the scheduler was recording).
    """

    def __init__(self, component: str, message: str, tick: int | None = None):
        super().__init__(f"component {component!r}: {message}")
        self.component, self.tick = component, tick


class RunFault(RunError):
    """A component stopped the run on an unsafe condition (its outputs were made safe first)."""

    def __init__(self, component: str, message: str, tick: int | None = None):
        super().__init__(component, f"fault: {message}", tick)


class WriteError(RunError):
    """Writing the run's outputs failed (a full disk): the run stops, what was written is kept.
    ``phase``: "stepping" or "writing the outputs"."""

    def __init__(self, exc: OutputWriteError, phase: str, t_s: float | None = None):
        at = f" at t = {t_s:.3f} s" if t_s is not None else ""
        UserError.__init__(self, f"{exc} (the run stopped{at}, while {phase}; what was written before is kept)")
        self.component, self.tick, self.phase, self.path = "recording", None, phase, exc.path


class NodeInputEnded(InputEnded):
    """A node's component ran out of its replayed input at ``tick`` (the run ends with the ticks before)."""

    def __init__(self, component: str, message: str, tick: int):
        super().__init__(message)
        self.component, self.tick = component, tick


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


@dataclass
class Progress:
    """What the worker is doing, read by the watchdog."""

    tick: int = -1
    pending: tuple[str, ...] = ()
    since: float = field(default_factory=time.monotonic)
    error: BaseException | None = None
    done: bool = False
    hung: str | None = None  # the component whose step never returned

    def busy(self, *names: str) -> None:
        self.pending, self.since = names, time.monotonic()


class LocalGroup:
    """Components in the scheduler's process, stepped in wiring order."""

    def __init__(self, steppers: dict[str, Stepper]):
        self.steppers = steppers
        self.closed = False

    def start(self, order: list[str], progress: Progress, observed_ready: Callable[[], list[str]]) -> None:
        for name in order:
            progress.busy(name)
            self.steppers[name].publish_initial()

    def plan(self, n_steps: int, window: int) -> None:
        """Nothing to plan: local steps happen one at a time."""

    def step(self, tick: int, t: float, due: list[str], progress: Progress) -> None:
        for name in due:
            progress.busy(name)
            self.steppers[name].step(tick, t)

    def dead(self) -> list[str]:
        return []

    def flush(self, names: tuple[str, ...]) -> bool:
        """Local steps are never held back."""
        return False

    def interrupt(self, name: str, reason: str) -> None:
        """A stuck local step cannot be woken; the worker thread is abandoned."""

    def close(self, hung: str | None) -> dict[str, str]:
        """Close every component (once); returns ``{name: fault}`` of those that set a fault while closing."""
        if self.closed:
            return {}
        self.closed = True
        faults = {}
        for name, stepper in self.steppers.items():
            if name != hung:  # its thread is stuck inside step(); closing would block too
                fault = _close_quietly(name, stepper.close)
                if fault:
                    faults[name] = fault
        return faults


#: Ticks a node may run ahead of the tick the scheduler waits for; credits
#: for the next ``WINDOW`` ticks go out every ``WINDOW // 2`` ticks. Every
#: credit and report is a message a node handles besides its inputs: at 32,
#: 0.6 of them per tick in all (at 8: 2.5), which took ~20 % off a tick. At
#: 128 the nodes go on while the scheduler writes a second's recording (tens of
#: ms, during which a window of 32 ticks, ~25 ms of nodes' work, ran out).
WINDOW = 128
#: A gap this long [s] between two rounds of the watchdog (every 50 ms) means this process itself
#: did not run (stopped, starved of CPU); nodes that vanish within STALL_BLAME_S [s] after it
#: took the scheduler for gone, and the scheduler is the one named.
STALL_S = 2.0
STALL_BLAME_S = 30.0

#: Steps a node reports in one reply (sooner when it runs out of credit); a node that dies takes
#: up to this many unreported steps with it.
REPLY_BATCH = 16
#: How long a timed-out run waits for the nodes' unreported steps before naming the hung one.
FLUSH_GRACE_S = 0.25
#: How long the nodes' links and routes may take to deliver every initial output.
ROUTES_TIMEOUT_S = 30.0
#: How long closing waits for the nodes to confirm that their components are closed (a driver
#: of hardware ramps its outputs down and switches its supplies off, each of which may time out).
CLOSE_TIMEOUT_S = 15.0


class RemoteGroup:
    """Components each in a ``cosim node`` process, driven over zenoh (see :mod:`cosim.runtime.node`).

    Nodes report their steps in batches of up to ``REPLY_BATCH`` (one reply
    carries the outputs of each step). The worker waits on a queue fed by the
    reply subscriber; the watchdog wakes it by queueing a failure.
    """

    def __init__(self, session: zenoh.Session, run_id: str, wiring: Wiring, store: PortStore,
                 security: SecurityLog | None = None):
        self.names = names = wiring.order
        self.security = security or SecurityLog(None, "scheduler")
        self._store = store
        self._dead: set[str] = set()
        self._tick_pub = bus.publisher(session, bus.tick_key(run_id))
        self._cmd_pubs = {n: bus.publisher(session, bus.ctl_key(run_id, n, "cmd")) for n in names}
        # (header, payload) of every reply; a Python queue, as zenoh's own blocking recv polls
        self._inbox: queue.SimpleQueue[tuple[bytes, bytes]] = queue.SimpleQueue()
        self.security_events: list[str] = []  # replies dropped by _on_reply, the nodes' counts
        self.node_security_events = 0  # the events the nodes noted (reported when they close)
        self._replies = session.declare_subscriber(bus.ctl_key(run_id, "*", "reply"), self._on_reply)
        self._done = {n: -1 for n in names}  # the last tick each node has reported
        self._joined: set[str] = set()  # the nodes that said they were ready (set up, with the run's fingerprint)
        self._alive = session.liveliness().declare_subscriber(bus.alive_key(run_id), self._on_alive)
        # the nodes stop (their outputs made safe) when this token goes: this process ended
        self._token = session.liveliness().declare_token(bus.scheduler_alive_key(run_id))
        self.closed = False
        #: the node processes started on this machine, by component (set by the runner)
        self.processes: dict = {}

    def _on_reply(self, sample: zenoh.Sample) -> None:
        """Queue a node's reply; one whose header names another node than its key is dropped (a node
        speaks for itself only: with access control, its key is the only one it may publish on)."""
        header = sample.attachment.to_bytes() if sample.attachment is not None else b""
        sender = str(sample.key_expr).rsplit("/", 2)[-2]
        try:
            named = bus.decode_json(header).get("name")
        except Exception:
            named = None
        if named != sender or sender not in self._cmd_pubs:
            self.security.event(str(sample.key_expr), f"dropped a reply naming {named!r}, not its key's node",
                                sender=sender)
            if len(self.security_events) < 100:  # bounded: a flood must not fill the memory
                self.security_events.append(f"dropped a reply on {sample.key_expr} naming {named!r}")
            return
        self._inbox.put((header, sample.payload.to_bytes()))

    def _on_alive(self, sample: zenoh.Sample) -> None:
        name = str(sample.key_expr).rsplit("/", 1)[-1]
        if sample.kind == zenoh.SampleKind.DELETE and name in self._cmd_pubs:
            self._dead.add(name)

    def dead(self) -> list[str]:
        return sorted(self._dead)

    def gone_reason(self, name: str, tick: int) -> str:
        """Why node ``name``'s liveliness token went, as far as this machine can tell: a node process
        started here (:attr:`processes`) that still exists was paused or starved, not ended."""
        proc = self.processes.get(name)
        if proc is not None and proc.poll() is None:
            return (f"not answering: its process is still there but its link went silent for zenoh's lease "
                    f"(paused, or starved of CPU) (tick {tick})")
        if proc is not None:
            return f"its process ended unexpectedly with status {proc.returncode} (tick {tick})"
        return f"its node stopped answering: its process ended, or its machine or link went away (tick {tick})"

    def interrupt(self, name: str, reason: str) -> None:
        self._inbox.put((bus.encode_json({"name": name, "ok": False, "error": reason}), b""))

    def command(self, name: str, cmd: str) -> None:
        self._cmd_pubs[name].put(bus.encode_json({"cmd": cmd}))

    def flush(self, names: tuple[str, ...]) -> bool:
        """Ask ``names`` to report the steps they hold back (a hung node cannot)."""
        for name in names:
            self.command(name, "flush")
        return True

    def gather(self, names, tick: int, phase: str | None, progress: Progress | None = None,
               resend: Callable[[list[str]], None] | None = None) -> dict[str, dict]:
        """Wait until each of ``names`` has reported ``tick`` (``phase`` None: a step)
        or sent one reply of a set-up ``phase``.

        With ``resend`` (set-up only, where a message can precede its route),
        the request is sent again to those that have not answered within 0.5 s.
        """
        pending = {n for n in names if phase is not None or self._done[n] < tick}
        got: dict[str, dict] = {}

        def show() -> None:  # the first unfinished in wiring order is the one to blame
            if progress is not None:
                progress.pending = tuple(n for n in progress.pending if n in pending)

        def answered(name: str, reply: dict) -> None:
            pending.discard(name)
            got[name] = reply
            show()

        show()
        while pending:
            try:
                reply = self._decode(self._inbox.get(timeout=None if resend is None else 0.5))
            except queue.Empty:
                resend(sorted(pending))
                continue
            name = reply.get("name", "?")
            if not reply.get("ok", False):
                if phase is None and reply.get("input_ended") is not None and reply.get("tick") is not None:
                    self._settle(name)  # the others report the ticks before, which the run keeps
                    raise NodeInputEnded(name, reply["input_ended"], reply["tick"])
                kind = RunFault if reply.get("fault") else RunError
                error = kind(name, reply.get("fault") or reply.get("error", "failed"), reply.get("tick"))
                if phase is None and error.tick is not None:
                    self._settle(name)
                raise error
            if name not in pending:
                continue
            if phase is None and self._done[name] >= tick:
                answered(name, reply)
            elif phase is not None and reply.get("tick") == tick and reply.get("phase") == phase:
                answered(name, reply)
        return got

    def _settle(self, failed: str) -> None:
        """After ``failed`` failed: have the others report every step they finished
        (for the record), waiting at most ``FLUSH_GRACE_S`` for their answers."""
        waiting = {n for n in self.names if n != failed and n not in self._dead}
        self.flush(tuple(waiting))
        deadline = time.monotonic() + FLUSH_GRACE_S
        while waiting:
            try:
                reply = self._decode(self._inbox.get(timeout=max(deadline - time.monotonic(), 0.0)))
            except queue.Empty:
                return
            if reply.get("phase") == "flush":
                waiting.discard(reply.get("name"))

    def _decode(self, item: tuple[bytes, bytes]) -> dict:
        """A reply's header; the outputs it carries go to the store."""
        header, payload = item
        reply = bus.decode_json(header)
        if reply.get("phase") == "ready" and reply.get("ok"):
            self._joined.add(reply["name"])
        ticks = reply.get("ticks")
        if ticks:  # a batch of steps
            self._done[reply["name"]] = ticks[-1]
        if payload:  # a batch's outputs, or those of a fault's step or of init
            self._store.store_payload(reply["name"], ticks or [reply["tick"]], payload)
        return reply

    def poll_reply(self, timeout_s: float) -> dict | None:
        """One reply within ``timeout_s`` (used while nodes start), else None."""
        try:
            return self._decode(self._inbox.get(timeout=timeout_s))
        except queue.Empty:
            return None

    def start(self, order: list[str], progress: Progress, observed_missing: Callable[[], list[str]],
              timeout_s: float = ROUTES_TIMEOUT_S) -> None:
        """Publish every initial output; repeat until every route has delivered one (at most ``timeout_s``).

        A zenoh route between two nodes exists only once their link is up (a
        node may connect to one that started later, on another machine) and
        both declarations have reached both ends of it; a value sent earlier
        is lost, so producers re-send until every consumer confirms receipt.
        """
        def init(names):
            for name in names:
                self.command(name, "init")

        def check(names):  # over the tick key, so its routes are proven too
            self._tick_pub.put(bus.encode_json({"check": True}))

        senders = list(order)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
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

    def plan(self, n_steps: int | None, window: int) -> None:
        """``window``: ticks the nodes may run ahead (1 under real-time pacing); ``n_steps`` None: until stopped."""
        self._n_steps, self._granted, self._window = n_steps, 0, window

    def step(self, tick: int, t: float, due: list[str], progress: Progress) -> None:
        """Grant ticks up to ``WINDOW`` ahead, then wait for this tick's replies.

        Nodes step as soon as their inputs for a granted tick have arrived, so
        the plant starts tick k+1 the moment its actuator's tick-k output
        reaches it, without a round trip through the scheduler; stamps keep
        the result identical to strict lockstep.
        """
        progress.busy(*due)
        if self._granted - tick <= self._window // 2 and (self._n_steps is None or self._granted < self._n_steps):
            self._granted = tick + self._window if self._n_steps is None else min(tick + self._window, self._n_steps)
            self._tick_pub.put(bus.encode_json({"until": self._granted}))
        self.gather(due, tick, None, progress)

    def close(self, hung: str | None) -> dict[str, str]:
        """Stop every node (once) and wait until each that joined has closed its component (at most
        ``CLOSE_TIMEOUT_S``); returns ``{name: fault}`` of those that set a fault while closing."""
        if self.closed:
            return {}
        self.closed = True
        waiting = {n for n in self.names if n in self._joined and n not in self._dead and n != hung}
        for name in self.names:
            if name not in self._dead:
                _close_quietly(name, lambda n=name: self.command(n, "stop"))
        faults: dict[str, str] = {}
        deadline = time.monotonic() + CLOSE_TIMEOUT_S
        gone: dict[str, float] = {}  # when a node still awaited was seen dead (its close reply may follow)
        while waiting:
            now = time.monotonic()
            for name in waiting & self._dead:
                gone.setdefault(name, now)
            waiting -= {n for n, since in gone.items() if now - since > FLUSH_GRACE_S}
            if waiting and now > deadline:
                print(f"cosim: {', '.join(sorted(waiting))} did not confirm closing within {CLOSE_TIMEOUT_S:g} s",
                      file=sys.stderr)
                break
            try:
                reply = self._decode(self._inbox.get(timeout=0.05))
            except queue.Empty:
                continue
            if reply.get("phase") == "closed":
                if reply.get("security_events"):
                    self.node_security_events += reply["security_events"]
                    self.security_events.append(f"node {reply.get('name')} noted {reply['security_events']} "
                                                "security event(s): attempts refused by access control, samples "
                                                "replayed, repeated or malformed (security.jsonl)")
                waiting.discard(reply.get("name"))
                if reply.get("close_fault"):
                    faults[reply["name"]] = reply["close_fault"]
        for entity in (self._tick_pub, *self._cmd_pubs.values(), self._replies, self._alive):
            entity.undeclare()
        return faults


def _close_quietly(name: str, close: Callable[[], str | None]) -> str | None:
    try:
        return close()
    except Exception as exc:  # closing must not hide the run's own outcome
        print(f"cosim: closing {name} failed: {exc}", file=sys.stderr)
        return None


def with_close_faults(error: BaseException | None, faults: dict[str, str]) -> RunFault:
    """The run's outcome once components set ``faults`` while closing: a fault, naming each
    (and the failure or fault the run had before, if any)."""
    (name, fault), *others = faults.items()
    text = "; ".join([f"{fault} (while closing)", *(f"component {n!r}: {f} (while closing)" for n, f in others)])
    if error is not None:
        text += f"; the run had stopped on: {error}"
    return RunFault(name, text)


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

"""The groups of components a :class:`~cosim.runtime.scheduler.Scheduler` steps each tick.

* :class:`LocalGroup`: components in this process, stepped one by one in
  the wiring's topological order;
* :class:`RemoteGroup`: each component in a ``cosim node`` process; credits
  let the nodes run up to :data:`WINDOW` ticks ahead, each node steps a granted
  tick as soon as its inputs for it have arrived, and a tick ends when every
  due node has reported it; the reports carry the outputs, which the
  scheduler keeps for its observers.

Both close their components at the end (:func:`with_close_faults`: what a
component found while closing).
"""

from __future__ import annotations

import queue
import sys
import time
from dataclasses import dataclass, field
from typing import Callable

import zenoh

from cosim.contract.component import InputEnded
from cosim.contract.errors import RunError, RunFault
from cosim.runtime import bus
from cosim.runtime.portcache import PortStore
from cosim.runtime.security_log import SecurityLog
from cosim.runtime.stepper import Stepper
from cosim.runtime.wiring import Wiring


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


class NodeInputEnded(InputEnded):
    """A node's component ran out of its replayed input at ``tick`` (the run ends with the ticks before)."""

    def __init__(self, component: str, message: str, tick: int):
        super().__init__(message)
        self.component, self.tick = component, tick


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



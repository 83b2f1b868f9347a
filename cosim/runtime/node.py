"""``cosim node``: one component in a process of its own, driven over zenoh.

The node loads the same scenario file (same overrides) as the scheduler,
sets its component up identically (same parameters, same seeded RNG),
opens a zenoh peer session linked to the scheduler and to the other nodes,
declares its liveliness token and serves, right in its subscribers'
callbacks (one lock around them; the main thread only waits):

* port values from its producers: stored by their tick stamp;
* on ``cosim/{run}/ctl/tick``: a credit ``{"until": K}`` lets it step every
  tick ``k < K`` that is due for it (its period) as soon as its inputs
  stamped for ``k`` have arrived: step, publish the outputs; a ``check``
  (set-up) asks which inputs' initial values have not arrived yet;
* commands on ``cosim/{run}/ctl/{name}/cmd``: ``init`` (publish the initial
  outputs), ``flush`` (report the steps held back, even none), ``stop``
  (close the component and reply ``closed``, with the fault it set while
  closing as ``close_fault``).

The node also stops (closing its component, so a hardware driver makes its
outputs safe) when the scheduler's liveliness token goes (its process ended
or was killed), on SIGTERM and on Ctrl-C.

Replies go to ``cosim/{run}/ctl/{name}/reply``: a JSON attachment and the
outputs as the payload (see :func:`cosim.runtime.bus.encode_reply`). Steps are
reported ``REPLY_BATCH`` at a time, ``{"name", "ticks": [...], "ok": true}``
with each step's outputs in turn, and whenever the node runs out of credit;
set-up phases and failures as ``{"name", "tick", "phase", "ok"[, "error",
"fault", "input_ended"]}`` (a fault with the outputs of its step; ``input_ended``: the component's
replayed input ran out at that tick, which ends the run as it ends in one process).
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from pathlib import Path

import zenoh

from cosim.contract.component import ComponentFault, InputEnded
from cosim.runtime import bus
from cosim.runtime.fingerprint import Fingerprint, differences, fingerprint
from cosim.runtime.groups import REPLY_BATCH, WINDOW
from cosim.runtime.placement import parse_cpu_list, pin_this_process
from cosim.runtime.portcache import PortStore
from cosim.runtime.rights import access_control
from cosim.runtime.security_log import SecurityLog, ZenohDenials
from cosim.runtime.stepper import Stepper, setup_component
from cosim.runtime.wiring import Wiring
from cosim.scenario.schema import Scenario

IDLE_TIMEOUT_S = 120.0
#: How long a node waits for its route to the scheduler before it replies anyway.
ROUTE_WAIT_S = 30.0
#: How long a node that refuses to join waits for that route to say so.
REFUSAL_WAIT_S = 5.0


class _Node:
    """A set-up component's event handling. Handlers run under one lock, except
    ``stop`` and ``flush``, which must work past a hung step.

    ``edges``: ``(producer, port, producer's period, delay)`` of each input.
    """

    def __init__(self, stepper: Stepper, store: PortStore, edges: list[tuple[str, str, int, int]],
                 period: int, dt_s: float, reply, security: SecurityLog | None = None, run_id: str = ""):
        self.stepper, self.store, self.edges = stepper, store, edges
        self.period, self.dt_s, self.reply = period, dt_s, reply
        self.lock = threading.Lock()
        self.stopped = threading.Event()
        self.last_heard = time.monotonic()
        self.next_tick = 0  # the next tick to step (or skip, if not due)
        self.until = 0  # ticks below this are granted
        self.failed = False
        self.done_ticks: list[int] = []  # steps not reported yet, and their outputs
        self.done_values: list = []
        self.done_lock = threading.Lock()  # held briefly: a flush reports even past a hung step
        self.periods = {src: per for src, _, per, _ in edges}
        #: (rows kept of the producer, its period, the edge's delay) of each input: what a tick waits for
        self._needs = [(store.rows_of(src), per, delay) for src, _, per, delay in edges]
        self.accepted: dict[str, int] = {}  # per producer, the last tick whose outputs were accepted
        self.initial: dict[str, bytes] = {}  # per producer, the initial outputs accepted
        self.security_events = 0  # samples and commands dropped
        self.security = security or SecurityLog(None, "node")
        self.run_id = run_id

    def on_data(self, producer: str, sample: zenoh.Sample) -> None:
        """A step's outputs of ``producer``, accepted once per tick: a producer steps its ticks in order,
        so a stamp not past the last one accepted (a replay, a second sample for a tick), one off the
        producer's period, or a payload of the wrong size is dropped and reported as a security event.
        The initial outputs (tick -1) sent again, the same bytes, are not: set-up repeats them until
        every route has delivered one."""
        try:
            tick = bus.decode_tick(sample.attachment.to_bytes())
        except Exception:  # no or a malformed stamp
            tick = None
        payload = sample.payload.to_bytes()
        with self.lock:
            last = self.accepted.get(producer, -2)
            if tick == -1 == last and payload == self.initial.get(producer):
                return
            if tick is None or tick <= last or (tick != -1 and tick % self.periods.get(producer, 1)):
                self._rejected(producer, tick, "a stamp already accepted or out of order" if tick is not None
                               else "no tick stamp")
                return
            try:
                self.store.store_payload(producer, [tick], payload)
            except ValueError as exc:
                self._rejected(producer, tick, str(exc))
                return
            self.accepted[producer] = tick
            if tick == -1:
                self.initial[producer] = payload
            self._advance()

    def _rejected(self, producer: str, tick, why: str) -> None:
        self.security_events += 1
        self.security.event(bus.outputs_key(self.run_id, producer), f"dropped a sample for tick {tick}: {why}",
                            tick=tick)
        if self.security_events <= 10:  # bounded: a flood must not fill the log
            print(f"cosim node: security: dropped a sample of {producer}'s outputs for tick {tick}: {why}",
                  file=sys.stderr, flush=True)

    def on_tick(self, sample: zenoh.Sample) -> None:
        msg = bus.decode_json(sample.payload.to_bytes())
        with self.lock:
            self.last_heard = time.monotonic()
            if msg.get("check"):
                missing = [f"{s}.{p}" for s, p, _, _ in self.edges if not self.store.has(s, -1)]
                self.reply(-1, "check", missing=missing)
            else:
                self.until = max(self.until, msg["until"])
                self._advance()

    def on_cmd(self, sample: zenoh.Sample) -> None:
        try:
            cmd = bus.decode_json(sample.payload.to_bytes())["cmd"]
        except Exception:  # not a command at all
            cmd = None
        if cmd not in ("stop", "flush", "init"):
            self.security_events += 1
            self.security.event(str(sample.key_expr), "dropped a command that is none of stop, flush, init")
            return
        if cmd == "stop":  # stop and flush not under the lock: a hung step holds it
            self.stopped.set()
        elif cmd == "flush":
            self._report(phase="flush")
        elif cmd == "init":
            with self.lock:
                self.last_heard = time.monotonic()
                self.stepper.publish_initial()
                self.reply(-1, "init", values=self.stepper.last_outputs)

    def _inputs_ready(self, tick: int) -> bool:
        for rows, per, delay in self._needs:  # runs for every tick and hop: expected_stamp inlined
            k = tick - delay
            if (-1 if k < 0 else k - k % per) not in rows:
                return False
        return True

    def _report(self, phase: str | None = None) -> None:
        """Reply with the steps not reported yet (a ``flush`` reply even with none)."""
        with self.done_lock:
            if self.done_ticks or phase:
                self.reply(self.done_ticks[-1] if self.done_ticks else -1, phase, ticks=self.done_ticks,
                           values=self.done_values)
                self.done_ticks, self.done_values = [], []

    def _advance(self) -> None:
        """Step every granted tick whose inputs are in, in order; stop at the first that waits."""
        while self.next_tick < self.until and not (self.failed or self.stopped.is_set()):
            tick = self.next_tick
            if tick % self.period:
                self.next_tick += 1
                continue
            if not self._inputs_ready(tick):
                return
            self.next_tick += 1
            t = tick * self.dt_s
            try:
                self.stepper.step(tick, t)
            except InputEnded as exc:  # its replayed input ran out: the run ends with the ticks before this one
                self.failed = True
                self._report()
                self.reply(tick, error=f"input ended at t = {t:.3f} s: {exc}", input_ended=str(exc))
                return
            except ComponentFault as exc:  # its outputs (made safe) were published
                self.failed = True
                self._report()
                self.reply(tick, error=str(exc), fault=f"{exc} (t = {t:.3f} s)", values=self.stepper.last_outputs)
                return
            except Exception as exc:  # the component's failure goes to the scheduler with its text
                self.failed = True
                self._report()
                self.reply(tick, error=f"failed at t = {t:.3f} s: {type(exc).__name__}: {exc}")
                return
            with self.done_lock:
                self.done_ticks.append(tick)
                self.done_values.extend(self.stepper.last_outputs)
                full = len(self.done_ticks) >= REPLY_BATCH
            if full:
                self._report()
        if not self.failed:  # out of credit: the scheduler waits for these
            self._report()


def serve(scenario: Scenario, wiring: Wiring, name: str, run_id: str, connect: list[str],
          listen: list[str], cpus: str | None = None, run_dir: Path | None = None,
          expected: Fingerprint | None = None, tls: bus.TlsFiles | None = None,
          scenario_file: Path | None = None, rights=None) -> int:
    """Serve component ``name`` until told to stop; returns an exit status.

    ``connect``: the scheduler's endpoint and those of the nodes started
    before this one; ``listen``: where the nodes started after it connect;
    ``cpus``: where to step (see :mod:`cosim.runtime.placement`), once set up on any CPU;
    ``run_dir``: the run's output folder, for a component that writes files of its own;
    ``expected``: the run's fingerprint: with another of its own the node refuses to join
    (exit status 2); ``tls``: this host's files for mutual TLS with the run's other machines;
    ``scenario_file``: where the scenario was read (its plugin files count in the fingerprint);
    ``rights``: with ``tls``, the run's per-component rights (:class:`cosim.runtime.rights.Rights`), which this
    node's session enforces on what its peers send it.
    """
    if cpus is not None:
        parse_cpu_list(cpus)  # a bad list fails before anything starts
    if tls is not None:
        tls.check(f"cosim node {name}")
    mine = fingerprint(scenario, scenario_file or Path("."))
    access = denials = None
    security = SecurityLog(run_dir, f"node {name}")
    if rights is not None:
        access = access_control(run_id, wiring, rights)
        denials = ZenohDenials(security)  # what access control refuses here goes to the run's security.jsonl
    try:
        return _serve(scenario, wiring, name, run_id, connect, listen, cpus, run_dir, expected, tls, access,
                      security, mine)
    finally:
        if denials is not None:
            denials.close()


class _SchedulerLink:
    """This node's replies to the scheduler (``cosim/RUN/ctl/NAME/reply``)."""

    def __init__(self, session: zenoh.Session, run_id: str, name: str):
        self.name = name
        self.publisher = bus.publisher(session, bus.ctl_key(run_id, name, "reply"))

    def reply(self, tick: int, phase: str | None = None, error: str | None = None, values=(), **extra) -> None:
        """Send one reply: ``tick``'s ``phase`` ("ready", "closed", ...), ok unless ``error``."""
        msg = {"name": self.name, "tick": tick, "phase": phase, "ok": error is None, **extra}
        if error:
            msg["error"] = error
        payload, attachment = bus.encode_reply(msg, values)
        self.publisher.put(payload, attachment=attachment)

    def routed(self, timeout_s: float) -> bool:
        """Whether the scheduler's reply subscriber is known here within ``timeout_s`` [s]: a link to
        another machine, with its TLS handshake, can take longer than setting up, and a reply sent
        before would be lost."""
        return bool(bus.poll(lambda: self.publisher.matching_status.matching or None, timeout_s))


def _serve(scenario: Scenario, wiring: Wiring, name: str, run_id: str, connect: list[str], listen: list[str],
           cpus: str | None, run_dir: Path | None, expected: Fingerprint | None, tls: bus.TlsFiles | None,
           access: dict | None, security: SecurityLog, mine: Fingerprint) -> int:
    """:func:`serve` once its security log is set up (``access``: zenoh's access control, or None): join
    (or refuse to), set up, subscribe, step until stopped, close."""
    session = bus.open_session(listen=listen, connect=connect, tls=tls, access=access)
    link = _SchedulerLink(session, run_id, name)
    if expected is not None and mine != expected:
        return _refuse(session, link, run_id, "; ".join(differences(mine, expected)))
    if not link.routed(ROUTE_WAIT_S):  # the scheduler is gone (or was never there)
        print(f"cosim node {name}: no scheduler of run {run_id} reachable at {', '.join(connect)} within "
              f"{ROUTE_WAIT_S:g} s; exiting", file=sys.stderr)
        session.close()
        return 1
    try:
        component = setup_component(scenario, wiring, name, run_dir)
        if cpus is not None:  # the threads started from here on (subscribers') inherit it
            pin_this_process(cpus)
    except Exception as exc:  # reported to the scheduler, which names us
        link.reply(-1, "ready", f"set-up failed: {exc}")
        session.close()
        return 1
    edges = [(e.src, e.src_port, wiring.periods[e.src], e.delay) for e in wiring.edges_into(name)]
    timeout_s = scenario.components[name].timeout_s or scenario.timeout_s
    producers = {src: wiring.outputs[src] for src, _, _, _ in edges}
    store = PortStore(producers, keep=WINDOW + 1 + max(wiring.max_delay(name), 1))
    stepper = Stepper(name, component, session, run_id, wiring, store, timeout_s)
    node = _Node(stepper, store, edges, wiring.periods[name], scenario.dt_s, link.reply, security, run_id)
    gone: list[str] = []  # why the node stops on its own
    subs = _subscribe(session, run_id, name, node, producers, gone)
    token = session.liveliness().declare_token(bus.alive_key(run_id, name))
    _stop_on_signals(node, gone)
    link.reply(-1, "ready", fingerprint=mine.as_dict())
    try:
        return _wait_until_stopped(node, name, gone)
    finally:
        node.stopped.set()
        for sub in subs:
            sub.undeclare()
        if node.lock.acquire(timeout=2.0):  # else a step is hung inside the component: leave it
            link.reply(-1, "closed", close_fault=stepper.close(), security_events=security.count)
        token.undeclare()  # after the reply: the scheduler waits for it while the node lives
        session.close()


def _refuse(session: zenoh.Session, link: _SchedulerLink, run_id: str, why: str) -> int:
    """Tell the scheduler this node runs another experiment (``why``: the differing fingerprint parts);
    exit status 2."""
    print(f"cosim node {link.name}: refusing to join run {run_id}: this node runs another experiment: {why}",
          file=sys.stderr)
    link.routed(REFUSAL_WAIT_S)
    link.reply(-1, "ready", f"refused to join: its node runs another experiment than the run's: {why}")
    time.sleep(0.5)  # let the reply leave before the session closes
    session.close()
    return 2


def _subscribe(session: zenoh.Session, run_id: str, name: str, node: "_Node", producers: dict,
               gone: list[str]) -> list:
    """The node's subscribers: its producers' outputs, the ticks granted, its commands, and the
    scheduler's liveliness (its end stops the node, noted in ``gone``)."""
    subs = [session.declare_subscriber(bus.outputs_key(run_id, src), lambda s, src=src: node.on_data(src, s))
            for src in producers]
    subs.append(session.declare_subscriber(bus.tick_key(run_id), node.on_tick))
    subs.append(session.declare_subscriber(bus.ctl_key(run_id, name, "cmd"), node.on_cmd))

    def on_scheduler(sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.DELETE and not node.stopped.is_set():
            gone.append("the scheduler's process ended")
            node.stopped.set()

    subs.append(session.liveliness().declare_subscriber(bus.scheduler_alive_key(run_id), on_scheduler))
    return subs


def _stop_on_signals(node: "_Node", gone: list[str]) -> None:
    """SIGTERM and SIGINT stop the node (their name noted in ``gone``); outside the main thread, nothing."""
    if threading.current_thread() is not threading.main_thread():
        return

    def on_term(signum, frame):
        if not node.stopped.is_set():
            gone.append(signal.Signals(signum).name)
        node.stopped.set()

    signal.signal(signal.SIGTERM, on_term)
    signal.signal(signal.SIGINT, on_term)


def _wait_until_stopped(node: "_Node", name: str, gone: list[str]) -> int:
    """Wait while the node steps (its subscribers' threads): 0 once the scheduler stopped it, 1 when
    nothing came from the scheduler for :data:`IDLE_TIMEOUT_S` or it stopped on its own (``gone``)."""
    while not node.stopped.wait(1.0):
        if time.monotonic() - node.last_heard > IDLE_TIMEOUT_S:
            print(f"cosim node {name}: nothing from the scheduler for {IDLE_TIMEOUT_S:g} s, exiting",
                  file=sys.stderr)
            return 1
    if gone:
        print(f"cosim node {name}: stopping ({gone[0]}); component closed", file=sys.stderr)
        return 1
    return 0

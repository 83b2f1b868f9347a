"""``cosim node``: one component in a process of its own, driven over zenoh.

The node loads the same scenario file (same overrides) as the scheduler,
sets its component up identically (same parameters, same seeded RNG),
connects to the scheduler's endpoint as a zenoh client, declares its
liveliness token and serves, from one event queue fed by its subscribers:

* ticks on ``cosim/{run}/ctl/tick``: when the tick is due for it (its
  period) and its inputs stamped for that tick have arrived: step, publish
  the outputs, reply; a ``check`` tick (set-up) asks which inputs' initial
  values have not arrived yet;
* commands on ``cosim/{run}/ctl/{name}/cmd``: ``init`` (publish the initial
  outputs), ``stop``.

Replies go to ``cosim/{run}/ctl/{name}/reply`` as
``{"name", "tick", "phase", "ok"[, "error"]}``.
"""

from __future__ import annotations

import queue
import sys
from collections import deque

from cosim import bus
from cosim.component import ComponentFault
from cosim.portcache import PortStore, expected_stamp
from cosim.scenario import Scenario
from cosim.stepper import Stepper, setup_component
from cosim.wiring import Wiring

IDLE_TIMEOUT_S = 120.0


def serve(scenario: Scenario, wiring: Wiring, name: str, run_id: str, connect: list[str]) -> int:
    """Serve component ``name`` until told to stop; returns an exit status."""
    session = bus.open_session(connect=connect, mode="client")
    reply_pub = bus.publisher(session, bus.ctl_key(run_id, name, "reply"))
    events: queue.SimpleQueue = queue.SimpleQueue()
    edges = [(e.src, e.src_port, wiring.periods[e.src], e.delay) for e in wiring.edges_into(name)]
    store = PortStore([(src, port) for src, port, _, _ in edges])

    def on_data(sample, key):
        events.put(("data", key, *bus.decode_array(sample.payload.to_bytes(), sample.attachment.to_bytes())))

    subs = [session.declare_subscriber(bus.port_key(run_id, src, port), lambda s, k=(src, port): on_data(s, k))
            for src, port, _, _ in edges]
    subs.append(session.declare_subscriber(bus.tick_key(run_id),
                                           lambda s: events.put(("tick", bus.decode_json(s.payload.to_bytes())))))
    subs.append(session.declare_subscriber(bus.ctl_key(run_id, name, "cmd"),
                                           lambda s: events.put(("cmd", bus.decode_json(s.payload.to_bytes())))))

    def reply(tick: int, phase: str | None = None, error: str | None = None, **extra) -> None:
        msg = {"name": name, "tick": tick, "phase": phase, "ok": error is None, **extra}
        if error:
            msg["error"] = error
        reply_pub.put(bus.encode_json(msg))

    try:
        component = setup_component(scenario, wiring, name)
    except Exception as exc:  # reported to the scheduler, which names us
        reply(-1, "ready", f"set-up failed: {exc}")
        session.close()
        return 1
    timeout_s = scenario.components[name].timeout_s or scenario.timeout_s
    stepper = Stepper(name, component, session, run_id, wiring, store, timeout_s)
    token = session.liveliness().declare_token(bus.alive_key(run_id, name))
    period = wiring.periods[name]
    reply(-1, "ready")

    def inputs_ready(tick: int) -> bool:
        return all(store.has(src, port, expected_stamp(tick, per, delay)) for src, port, per, delay in edges)

    waiting: deque = deque()
    status = 0
    try:
        while True:
            try:
                event = events.get(timeout=IDLE_TIMEOUT_S)
            except queue.Empty:
                print(f"cosim node {name}: nothing from the scheduler for {IDLE_TIMEOUT_S:g} s, exiting",
                      file=sys.stderr)
                status = 1
                break
            kind = event[0]
            if kind == "data":
                store.store(event[1], event[2], event[3])
            elif kind == "tick":
                if event[1].get("check"):
                    missing = [f"{s}.{p}" for s, p, _, _ in edges if not store.has(s, p, -1)]
                    reply(-1, "check", missing=missing)
                elif event[1]["tick"] % period == 0:
                    waiting.append(event[1])
            else:
                cmd = event[1]["cmd"]
                if cmd == "stop":
                    break
                if cmd == "init":
                    stepper.publish_initial()
                    reply(-1, "init")
            while waiting and inputs_ready(waiting[0]["tick"]):
                msg = waiting.popleft()
                try:
                    stepper.step(msg["tick"], msg["t"])
                    reply(msg["tick"])
                except ComponentFault as exc:
                    reply(msg["tick"], error=str(exc), fault=f"{exc} (t = {msg['t']:.3f} s)")
                except Exception as exc:  # the component's failure goes to the scheduler with its text
                    reply(msg["tick"], error=f"failed at t = {msg['t']:.3f} s: {type(exc).__name__}: {exc}")
    finally:
        token.undeclare()
        for sub in subs:
            sub.undeclare()
        stepper.close()
        session.close()
    return status

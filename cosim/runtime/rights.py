"""Per-component rights on the bus of a run over machines: zenoh access control by certificate name.

In a ``--hosts`` run every link is mutual TLS with certificates of the run's CA
(``cosim certs``): one per host, whose common name is the host's name in the
hosts file, and one per component placed under ``components:``, named
``component@host``, which that component's node links with. Every process of the
run (scheduler and nodes) filters what reaches it by the certificate of the peer
it came from (zenoh's ``access_control``, default deny). An identity (a
certificate name) may

* publish the outputs and the replies of its components, and declare
  their liveliness tokens;
* subscribe to the outputs its components take as inputs, to the scheduler's
  tick key and to its components' command keys, and watch the scheduler's
  liveliness;
* the scheduler's host alone publishes ticks and commands and declares the
  scheduler's token; it subscribes to every reply and watches the nodes' tokens.

A placed component's identity has that one component: a holder of a sensor's
certificate can publish that sensor's outputs and replies and nothing else, even
when the actuator's driver runs on the same host; a put it makes on another key is
dropped by every process it reaches (and logged there, see
:mod:`cosim.runtime.security_log`). A host's own certificate carries no component
of its own, except the scheduler's host, whose certificate the components not
placed under ``components:`` share with the scheduler (they run on its machine).

The rights travel to each node as ``--rights`` text (:func:`format_rights`):
``SCHEDULER_HOST;IDENTITY=COMP,COMP;IDENTITY=COMP`` (names are single key chunks and
certificate names, so they hold no ``;``, ``=`` or ``,``).
"""

from __future__ import annotations

from dataclasses import dataclass

from cosim.contract.errors import UserError
from cosim.runtime import bus

ALL_MESSAGES = ("put", "delete", "declare_subscriber", "query", "declare_queryable", "reply", "liveliness_token",
                "declare_liveliness_subscriber", "liveliness_query")


@dataclass(frozen=True)
class Rights:
    """Which host runs the scheduler, and the components of each identity (certificate common name)."""

    scheduler_host: str
    identities: dict[str, tuple[str, ...]]


def format_rights(rights: Rights) -> str:
    """The rights as one command-line word: ``SCHEDULER_HOST;IDENTITY=COMP,COMP;...`` (see :func:`parse_rights`)."""
    return ";".join([rights.scheduler_host, *(f"{h}={','.join(cs)}" for h, cs in rights.identities.items())])


def parse_rights(text: str) -> Rights:
    """The inverse of :func:`format_rights`; malformed text is a UserError quoting it."""
    parts = text.split(";")
    hosts: dict[str, tuple[str, ...]] = {}
    for part in parts[1:]:
        host, eq, comps = part.partition("=")
        if not eq or not host:
            raise UserError(f"--rights {text!r}: expected SCHEDULER_HOST;IDENTITY=COMP,COMP;..., not {part!r}")
        hosts[host] = tuple(c for c in comps.split(",") if c)
    if not parts[0]:
        raise UserError(f"--rights {text!r}: the scheduler's host is missing (first field)")
    return Rights(parts[0], hosts)


def access_control(run_id: str, wiring, rights: Rights) -> dict:
    """zenoh's ``access_control`` section for every process of run ``run_id`` (see the module doc)."""
    base = f"{bus.ROOT}/{run_id}"
    rules, subjects, policies = [], [], []

    def rule(rid: str, messages, keys, flows=("ingress",)) -> str:
        rules.append({"id": rid, "permission": "allow", "flows": list(flows), "messages": list(messages),
                      "key_exprs": sorted(set(keys))})
        return rid

    for i, (host, comps) in enumerate(rights.identities.items()):
        own = [f"h{i}-egress"]
        rule(own[0], ALL_MESSAGES, [f"{base}/**"], flows=("egress",))
        inputs = {e.src for c in comps for e in wiring.edges_into(c)}
        subscribe = [bus.outputs_key(run_id, src) for src in inputs] + [bus.tick_key(run_id)]
        subscribe += [bus.ctl_key(run_id, c, "cmd") for c in comps]
        if comps:
            own.append(rule(f"h{i}-publish", ("put",), [k for c in comps for k in
                                                        (bus.outputs_key(run_id, c), bus.ctl_key(run_id, c, "reply"))]))
            own.append(rule(f"h{i}-alive", ("liveliness_token",), [bus.alive_key(run_id, c) for c in comps]))
            own.append(rule(f"h{i}-subscribe", ("declare_subscriber",), subscribe))
            own.append(rule(f"h{i}-watch", ("declare_liveliness_subscriber", "liveliness_query"),
                            [bus.scheduler_alive_key(run_id)]))
        if host == rights.scheduler_host:
            own.append(rule(f"h{i}-command", ("put",), [bus.tick_key(run_id), bus.ctl_key(run_id, "*", "cmd")]))
            own.append(rule(f"h{i}-scheduler-alive", ("liveliness_token",), [bus.scheduler_alive_key(run_id)]))
            own.append(rule(f"h{i}-replies", ("declare_subscriber",), [bus.ctl_key(run_id, "*", "reply"),
                                                                      f"{base}/*/outputs"]))
            own.append(rule(f"h{i}-watch-nodes", ("declare_liveliness_subscriber", "liveliness_query"),
                            [bus.alive_key(run_id)]))
        subjects.append({"id": f"host-{i}", "cert_common_names": [host]})
        policies.append({"id": f"host-{i}", "rules": own, "subjects": [f"host-{i}"]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
            "policies": policies}


def rights_of(plan) -> Rights:
    """The rights of a hosts plan (:class:`cosim.runtime.hosts.HostsPlan`): each node's component under
    the identity it links with (its own certificate's, or the scheduler host's)."""
    identities: dict[str, list[str]] = {plan.scheduler_host: []}
    for name, place in plan.nodes.items():
        identities.setdefault(place.identity or place.host, []).append(name)
    return Rights(plan.scheduler_host, {h: tuple(cs) for h, cs in identities.items()})

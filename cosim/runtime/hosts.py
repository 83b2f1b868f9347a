"""HOSTS.yaml: where each component of a run over machines runs, and how its node starts.

``cosim run SCENARIO --processes --hosts HOSTS.yaml`` reads it::

    launch: manual            # how nodes on other machines start: manual (default) or ssh
    wait_s: 600               # how long the run waits for every node to join [s]
    tls: {ca: certs/ca.pem}   # the run's CA certificate; `cosim certs HOSTS.yaml` makes it and the hosts'
    scheduler: {host: sim, listen: tls/10.0.0.1:7447}
    hosts:
      sim: {address: 10.0.0.1, cert: certs/sim.pem, key: certs/sim.key}
      lab:
        address: 10.0.0.2           # where the host is reached; its certificate names it
        launch: ssh                 # this host's own mode (local: it is this machine)
        ssh: lab@lab-pc             # ssh's destination (default: the address)
        workdir: /home/lab/cosim    # the folder there that matches the one `cosim run` runs in
        python: .venv/bin/python    # the interpreter there with cosim installed (relative to workdir)
        cert: certs/lab.pem
        key: certs/lab.key
    components:
      driver: {host: lab, listen: tls/10.0.0.2:7450, cpus: "1"}

Paths (certificates) are relative to the file's folder. The scheduler's host
is this machine; a component not listed runs here too, on a free port. A
run whose components are on more than one host must use ``tls/`` endpoints
with the run's certificates (mutual TLS), so no other host on the network
can join it or publish to its keys; a ``tcp/`` endpoint is refused beyond
loopback. With TLS every component placed under ``components:`` has a
certificate of its own (``cosim certs`` writes ``certs/lab.driver.pem`` and
``.key`` beside its host's ``certs/lab.pem``, named ``driver@lab``), and every
process enforces each certificate's rights by its name
(:mod:`cosim.runtime.rights`): a component's own keys only. The components not
placed there run on the scheduler's machine under its certificate. Errors name
the file, the field and its line.
"""

from __future__ import annotations

import os
import re
import socket
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from cosim.contract.errors import HostsError
from cosim.runtime.bus import TlsFiles
from cosim.scenario.schema import Scenario, error_lines, line_of, load_document

ENDPOINT = re.compile(r"^(tcp|tls)/(\[[^\]]+\]|[^:/\s\[\]]+):(\d{1,5})$")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class TlsSpec(_Strict):
    """The hosts file's ``tls``: the run's CA certificate."""
    ca: str = Field(description="the run's CA certificate (PEM), relative to the hosts file")


class HostSpec(_Strict):
    """One machine of a hosts file: how to reach it and start its nodes there."""
    address: str = Field(description="IP address or DNS name the host is reached at (its certificate names it)")
    launch: Literal["local", "ssh", "manual"] | None = Field(None, description="how its nodes start")
    ssh: str | None = Field(None, description="ssh destination (default: the address)")
    workdir: str | None = Field(None, description="the folder there matching the one `cosim run` runs in")
    python: str = Field(".venv/bin/python", description="interpreter there with cosim installed")
    cert: str | None = Field(None, description="this host's certificate (PEM), relative to the hosts file")
    key: str | None = Field(None, description="this host's private key (PEM), relative to the hosts file")


class PlacementSpec(_Strict):
    """Where one component runs: its host, endpoint and CPUs."""
    host: str
    listen: str | None = Field(None, description="endpoint the node listens on, e.g. tls/10.0.0.2:7450")
    cpus: str | None = Field(None, description="CPUs the node runs on there, e.g. 1 or 0,2-3")


class SchedulerSpec(_Strict):
    """Where the scheduler runs and listens."""
    host: str
    listen: str | None = None


class HostsFile(_Strict):
    """A hosts file (HOSTS.yaml): the scheduler, the machines and the components placed on them."""
    launch: Literal["ssh", "manual"] = "manual"
    wait_s: float = Field(600.0, gt=0)
    tls: TlsSpec | None = None
    scheduler: SchedulerSpec
    hosts: dict[str, HostSpec]
    components: dict[str, PlacementSpec] = Field(default_factory=dict)


@dataclass(frozen=True)
class NodePlace:
    """Where one component's node runs and how it starts; ``identity``: the common name of the
    certificate its node links with (``component@host``, or the scheduler's host for a component
    not placed under ``components:``)."""

    component: str
    host: str
    listen: str
    cpus: str | None
    launch: str  # local | ssh | manual
    tls: TlsFiles | None
    ssh: str
    workdir: str
    python: str
    identity: str = ""


def component_identity(component: str, host: str) -> str:
    """The common name of a placed component's own certificate: ``component@host``."""
    return f"{component}@{host}"


def component_files(host_cert: Path, host_key: Path, component: str) -> tuple[Path, Path]:
    """A placed component's own certificate and key: beside its host's, ``HOSTCERT.COMPONENT.pem``
    and ``HOSTKEY.COMPONENT.key`` (``certs/lab.pem`` -> ``certs/lab.driver.pem``)."""
    host_cert, host_key = Path(host_cert), Path(host_key)
    return (host_cert.with_name(f"{host_cert.stem}.{component}{host_cert.suffix}"),
            host_key.with_name(f"{host_key.stem}.{component}{host_key.suffix}"))


@dataclass(frozen=True)
class HostsPlan:
    """A hosts file resolved for one run: the scheduler's endpoint and TLS files, each node's place."""
    path: Path
    scheduler_host: str
    scheduler_listen: str
    scheduler_tls: TlsFiles | None
    nodes: dict[str, NodePlace]
    wait_s: float


def load_hosts(path: Path, scenario: Scenario) -> HostsPlan:
    """Read and check ``path`` against ``scenario``'s components; returns the placement of every node."""
    path = Path(path)
    data, node = load_document(path, "hosts file")
    try:
        spec = HostsFile.model_validate(data)
    except ValidationError as exc:
        raise HostsError(f"{path}: invalid hosts file\n" + "\n".join(error_lines(exc, node))) from None
    check = _HostsCheck(path, node, spec, scenario)
    check.names()
    scheduler_listen = check.endpoint(("scheduler", "listen"), spec.scheduler.listen, check.here)
    nodes = check.nodes()
    check.local_files(nodes)
    return HostsPlan(path, check.here, scheduler_listen,
                     check.tls_of(check.here) if scheduler_listen.startswith("tls/") else None, nodes, spec.wait_s)


class _HostsCheck:
    """The stages of :func:`load_hosts` on a validated hosts file: its names, endpoints, placements
    and certificate files; every error a :class:`HostsError` naming the field and its line."""

    def __init__(self, path: Path, node, spec: HostsFile, scenario: Scenario):
        self.path, self.node, self.spec, self.scenario = path, node, spec, scenario
        self.here = spec.scheduler.host  # this machine: it runs the scheduler
        self.used = {self.here, *(spec.components[c].host for c in spec.components)}
        self.base = path.parent

    def fail(self, loc: tuple, message: str):
        """Raise the :class:`HostsError` of the field at ``loc``."""
        line = line_of(self.node, loc)
        raise HostsError(f"{self.path}: {'.'.join(map(str, loc))}{f' (line {line})' if line else ''}: {message}")

    def names(self) -> None:
        """Every host named is under ``hosts``, every component placed is the scenario's, and the
        scheduler's host is this machine."""
        spec = self.spec
        for loc, host in [(("scheduler", "host"), spec.scheduler.host),
                          *((("components", c, "host"), p.host) for c, p in spec.components.items())]:
            if host not in spec.hosts:
                self.fail(loc, f"no host {host!r} under hosts (have: {', '.join(spec.hosts)})")
        for name in spec.components:
            if name not in self.scenario.components:
                self.fail(("components", name), f"the scenario has no component {name!r} "
                                                f"(have: {', '.join(self.scenario.components)})")
        if spec.hosts[self.here].launch not in (None, "local"):
            self.fail(("hosts", self.here, "launch"),
                      f"{self.here} runs the scheduler: it is this machine (launch: local)")

    def tls_of(self, host: str, component: str | None = None) -> TlsFiles | None:
        """The host's files, or with ``component`` the component's own certificate and key."""
        spec, h = self.spec, self.spec.hosts[host]
        if spec.tls is None or h.cert is None or h.key is None:
            return None
        if component is None:
            return TlsFiles(self.base / spec.tls.ca, self.base / h.cert, self.base / h.key)
        return TlsFiles(self.base / spec.tls.ca, *component_files(self.base / h.cert, self.base / h.key, component))

    def launch_of(self, host: str) -> str:
        """How ``host``'s nodes start: ``local`` on this machine, else its own or the file's ``launch``."""
        return "local" if host == self.here else self.spec.hosts[host].launch or self.spec.launch

    def endpoint(self, loc: tuple, text: str | None, host: str) -> str:
        """The checked endpoint, or a free port on the host's address (this machine only)."""
        address = self.spec.hosts[host].address
        several = len(self.used) > 1
        if text is None:
            if self.launch_of(host) != "local":
                self.fail(loc, f"needs an endpoint (e.g. tls/{address}:7450): host {host} is another machine")
            text = f"{'tls' if several else 'tcp'}/{address}:{_free_port(address)}"
        match = ENDPOINT.match(text)
        if not match:
            self.fail(loc, f"{text!r} is not an endpoint: expected tcp/ADDRESS:PORT or tls/ADDRESS:PORT")
        if match[2].strip("[]") != address:
            self.fail(loc, f"{text} is not at host {host}'s address {address} (its certificate names that address)")
        if several and match[1] != "tls":
            self.fail(loc, f"{text}: a run over more than one host links its machines with mutual TLS: use a "
                           f"tls/ endpoint (and the run's certificates, see cosim certs)")
        if match[1] == "tcp" and not _is_loopback(address):
            where = f"tls/{address}:{match[3]}" if address not in ("0.0.0.0", "::", "[::]") else \
                "a tls/ endpoint at the host's own address"
            self.fail(loc, f"{text}: plain TCP beyond loopback lets anyone on the network join the run and drive "
                           f"its hardware: use {where} with the run's certificates (cosim certs)")
        if match[1] == "tls":
            self.need_tls(loc, host)
        return text

    def need_tls(self, loc: tuple, host: str) -> None:
        """A tls/ endpoint at ``loc`` needs the run's CA and ``host``'s certificate and key."""
        if self.spec.tls is None:
            self.fail(("tls",), f"missing: {'.'.join(map(str, loc))} is a tls/ endpoint, which needs the run's CA "
                                "certificate (tls: {ca: certs/ca.pem}; cosim certs HOSTS.yaml makes it)")
        for field in ("cert", "key"):
            if getattr(self.spec.hosts[host], field) is None:
                self.fail(("hosts", host), f"missing {field}: host {host} has a tls/ endpoint "
                                           "(cosim certs HOSTS.yaml makes the run's certificates)")

    def nodes(self) -> dict[str, NodePlace]:
        """Where each of the scenario's components runs (unplaced ones: on this machine)."""
        nodes = {}
        for name in self.scenario.components:
            placed = self.spec.components.get(name)
            place = placed or PlacementSpec(host=self.here)
            h = self.spec.hosts[place.host]
            listen = self.endpoint(("components", name, "listen"), place.listen, place.host)
            tls = None
            if listen.startswith("tls/"):  # a placed component links with a certificate of its own
                tls = self.tls_of(place.host, name if placed else None)
            identity = component_identity(name, place.host) if placed else self.here
            nodes[name] = NodePlace(name, place.host, listen, place.cpus, self.launch_of(place.host), tls,
                                    h.ssh or h.address, h.workdir or os.getcwd(), h.python, identity)
        return nodes

    def local_files(self, nodes: dict[str, NodePlace]) -> None:
        """The certificate files this machine's processes link with exist (on other machines the node
        checks its own)."""
        checks = []  # (field, file)
        for host in sorted(self.used):
            files = self.tls_of(host)
            if files is not None and self.launch_of(host) == "local":
                checks += [(("tls", "ca"), files.ca), (("hosts", host, "cert"), files.cert),
                           (("hosts", host, "key"), files.key)]
        for name, place in nodes.items():
            if name in self.spec.components and place.tls is not None and place.launch == "local":
                checks += [(("components", name), place.tls.cert), (("components", name), place.tls.key)]
        for loc, file in checks:
            if not file.is_file():
                self.fail(loc, f"{file} does not exist (cosim certs {self.path} makes the run's certificates: one "
                               "per host and one per component placed under components:)")


def read_hosts_file(path: Path) -> tuple[HostsFile, Path]:
    """The validated hosts file alone (no scenario), and its folder: for ``cosim certs``."""
    data, node = load_document(path, "hosts file")
    try:
        return HostsFile.model_validate(data), Path(path).parent
    except ValidationError as exc:
        raise HostsError(f"{path}: invalid hosts file\n" + "\n".join(error_lines(exc, node))) from None


def _is_loopback(address: str) -> bool:
    """Whether ``address`` (an IP address or a name) is this machine's loopback (127.0.0.0/8, ::1, localhost)."""
    import ipaddress

    if address == "localhost":
        return True
    try:
        return ipaddress.ip_address(address.strip("[]")).is_loopback
    except ValueError:
        return False


def _free_port(address: str) -> int:
    family = socket.AF_INET6 if ":" in address else socket.AF_INET
    with socket.socket(family) as s:
        try:
            s.bind((address.strip("[]"), 0))
        except OSError as exc:
            raise HostsError(f"cannot listen on {address} here ({exc.strerror}): is it this machine's address?") \
                from None
        return s.getsockname()[1]

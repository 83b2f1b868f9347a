"""Starting the ``cosim node`` processes of a run spread over processes, here or on other machines.

Every node listens on an endpoint of its own and connects to the
scheduler's and to those of the nodes started before it: a full mesh, so a
port value goes straight from producer to consumer. A node starts

* ``local``: as a child process of ``cosim run`` on this machine (all of them
  without ``--hosts``);
* ``ssh``: through ``ssh DESTINATION 'cd WORKDIR && exec PYTHON -m cosim.cli node ...'``
  (key-based login: ssh runs with ``BatchMode``);
* ``manual``: its command is printed, per host, for someone to start there.

Every node gets the run's fingerprint (:mod:`cosim.runtime.fingerprint`) and refuses
to join when its own differs; the scheduler checks the one each node reports
when it is ready too. A node that exits, refuses or fails to set up before
it is ready stops the run with its name.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from cosim.contract.errors import RunError
from cosim.runtime.fingerprint import Fingerprint, differences
from cosim.runtime.groups import RemoteGroup
from cosim.runtime.hosts import HostsPlan
from cosim.runtime.scheduler import StopRequest

#: How long nodes this machine starts itself have to be ready.
NODE_START_TIMEOUT_S = 120.0


@dataclass
class NodeCommand:
    """One node to start: its component, where, how, and ``cosim node``'s arguments."""

    component: str
    host: str | None  # None: this machine, no hosts file
    launch: str  # local | ssh | manual
    args: list[str]  # after ``python -m cosim.cli``
    ssh: str = ""
    workdir: str = ""
    python: str = ""

    def local_argv(self) -> list[str]:
        return [sys.executable, "-m", "cosim.cli", *self.args]

    def remote_shell(self) -> str:
        """The command line to run on the node's host, from its working folder."""
        return f"cd {shlex.quote(self.workdir)} && exec {shlex.join([self.python, '-m', 'cosim.cli', *self.args])}"


def node_commands(scenario_file: Path, overrides: list[str], order: list[str], run_id: str, scheduler: str,
                  run_dir: Path, fingerprint: Fingerprint, cpus: str | None, free_endpoint,
                  hosts: HostsPlan | None, rights: str | None = None) -> list[NodeCommand]:
    """A command per component in ``order``: without ``hosts``, every node on this machine listening on
    ``free_endpoint(name)`` (a unix socket of the run's private folder) and running on ``cpus``; with
    them, as placed there (a node started here without CPUs of its own runs on ``cpus``); ``rights``:
    the run's per-component rights (:mod:`cosim.runtime.rights`), given to every node that links with TLS."""
    commands, earlier = [], [scheduler]
    for name in order:
        place = hosts.nodes[name] if hosts else None
        listen = place.listen if place else free_endpoint(name)
        remote = place is not None and place.launch != "local"
        path = (lambda p: _relative(p)) if remote else (lambda p: str(Path(p).resolve()))
        args = ["node", name, path(scenario_file), "--run-id", run_id, "--listen", listen,
                "--run-dir", path(run_dir), "--fingerprint", fingerprint.encode()]
        for other in earlier:
            args += ["--connect", other]
        earlier.append(listen)
        node_cpus = place.cpus if place and place.cpus else None if remote else cpus  # here: --node-cpus
        if node_cpus:
            args += ["--cpus", node_cpus]
        if place and place.tls:
            args += ["--tls-ca", path(place.tls.ca), "--tls-cert", path(place.tls.cert),
                     "--tls-key", path(place.tls.key)]
            if rights:
                args += ["--rights", rights]
        for item in overrides:
            args += ["--set", item]
        if os.environ.get("COSIM_TRUST_MODEL_CODE") == "1":  # `cosim run --trust-model-code`: every node too
            args.append("--trust-model-code")
        if place is None:
            commands.append(NodeCommand(name, None, "local", args))
        else:
            commands.append(NodeCommand(name, place.host, place.launch, args, place.ssh, place.workdir, place.python))
    return commands


def _relative(path: Path) -> str:
    """A path as given to a node on another machine: relative to the folder ``cosim run`` runs in,
    which is the node's working folder there."""
    return os.path.relpath(Path(path).resolve(), Path.cwd()) if Path(path).is_absolute() else str(path)


def start_nodes(commands: list[NodeCommand], group: RemoteGroup, expected: Fingerprint, started: list,
                wait_s: float = NODE_START_TIMEOUT_S, stop: StopRequest | None = None, out=sys.stdout) -> None:
    """Start the nodes (appending the processes started here to ``started``) and wait until each
    is ready with the run's fingerprint; a node that fails, refuses, exits or stays away, or a
    ``stop`` meanwhile, is a :class:`RunError` naming it."""
    procs: dict[str, subprocess.Popen] = {}
    for cmd in commands:
        if cmd.launch == "manual":
            continue
        argv = cmd.local_argv() if cmd.launch == "local" else \
            ["ssh", "-o", "BatchMode=yes", cmd.ssh, cmd.remote_shell()]
        # a session of their own: a Ctrl-C at the terminal reaches the scheduler only, which stops them
        procs[cmd.component] = subprocess.Popen(argv, stdin=subprocess.DEVNULL, start_new_session=True)
        started.append(procs[cmd.component])
    manual = [cmd for cmd in commands if cmd.launch == "manual"]
    if manual:
        _print_manual(manual, wait_s, out)
    hosts = {cmd.component: cmd.host for cmd in commands}
    pending = {cmd.component for cmd in commands}
    deadline = time.monotonic() + (wait_s if manual else NODE_START_TIMEOUT_S)
    while pending:
        reply = group.poll_reply(0.05)
        if reply is not None:
            name = reply.get("name", "?")
            if not reply.get("ok", False):
                raise RunError(name, reply.get("error", "failed to start"))
            if reply.get("phase") == "ready":
                theirs = Fingerprint.from_dict(reply.get("fingerprint") or {})
                if theirs != expected:
                    raise RunError(name, f"refused: its node{_on(hosts[name])} runs another experiment than this "
                                         f"run: " + "; ".join(differences(expected, theirs)))
                pending.discard(name)
                if manual:
                    print(f"cosim run: {name} joined{_on(hosts[name])}", file=out, flush=True)
            continue
        for name in sorted(pending & set(procs)):
            if procs[name].poll() is not None:
                raise RunError(name, f"its node process{_on(hosts[name])} exited with status "
                                     f"{procs[name].returncode} before it was ready")
        if stop is not None and stop.event.is_set():
            first = sorted(pending)[0]
            raise RunError(first, f"{stop.reason} while waiting for its node{_on(hosts[first])} to join")
        if time.monotonic() > deadline:
            waited = wait_s if manual else NODE_START_TIMEOUT_S
            raise RunError(sorted(pending)[0], f"its node{_on(hosts[sorted(pending)[0]])} was not ready within "
                                               f"{waited:g} s")


def _on(host: str | None) -> str:
    return f" on host {host}" if host else ""


def _print_manual(commands: list[NodeCommand], wait_s: float, out) -> None:
    by_host: dict[str, list[NodeCommand]] = {}
    for cmd in commands:
        by_host.setdefault(cmd.host or "?", []).append(cmd)
    lines = [f"cosim run: start these nodes on their hosts (waiting up to {wait_s:g} s for them to join):"]
    for host, cmds in by_host.items():
        lines.append(f"  on {host}:")
        lines += [f"    {cmd.remote_shell()}" for cmd in cmds]
    print("\n".join(lines), file=out, flush=True)

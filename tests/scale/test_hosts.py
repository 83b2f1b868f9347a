"""One run over two hosts (``cosim run --processes --hosts HOSTS.yaml``), two loopback addresses
standing in for two machines: the remote nodes started by hand from the printed commands; the log
byte-identical to one process; a node of another experiment refused; the hosts file's errors named."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from sweep_checks import TOY

from cosim.api import RunRequest, run
from cosim.cli import main

REMOTE = ("camera", "estimator")  # on host two; plant and controller run here


def write_hosts(folder: Path, reserved, launch: str = "manual") -> Path:
    """A hosts file for two loopback "hosts"; ``reserved``: the test's port reservation (see ports.py)."""
    ports = [reserved.port("127.0.0.1"), reserved.port("127.0.0.2"), reserved.port("127.0.0.2")]
    hosts = folder / "hosts.yaml"
    hosts.write_text(f"""
launch: {launch}
wait_s: 60
tls: {{ca: certs/ca.pem}}
scheduler: {{host: one, listen: tls/127.0.0.1:{ports[0]}}}
hosts:
  one: {{address: 127.0.0.1, cert: certs/one.pem, key: certs/one.key}}
  two: {{address: 127.0.0.2, python: {sys.executable}, cert: certs/two.pem, key: certs/two.key}}
components:
  camera: {{host: two, listen: tls/127.0.0.2:{ports[1]}}}
  estimator: {{host: two, listen: tls/127.0.0.2:{ports[2]}}}
""")
    assert main(["certs", str(hosts)]) == 0
    return hosts


def start_run(folder: Path, hosts: Path) -> tuple[subprocess.Popen, list[str]]:
    """``cosim run`` over the hosts (in ``folder``) and the node commands it prints for host two."""
    run_proc = subprocess.Popen([sys.executable, "-m", "cosim.cli", "run", str(TOY), "--processes", "--hosts",
                                 str(hosts), "--out", "run", "--quiet"], cwd=folder, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
    commands = []
    for line in run_proc.stdout:
        if "cosim.cli node" in line:
            commands.append(line.strip())
        if len(commands) == len(REMOTE):
            return run_proc, commands
    raise AssertionError(f"cosim run printed no node commands: {run_proc.stderr.read()}")


def finish(run_proc: subprocess.Popen) -> tuple[int, str]:
    try:
        _, err = run_proc.communicate(timeout=90)
    except subprocess.TimeoutExpired:
        run_proc.kill()
        raise
    return run_proc.returncode, err


def test_a_run_over_two_hosts_logs_the_bytes_of_one_process(tmp_path, ports):
    hosts = write_hosts(tmp_path, ports)
    run_proc, commands = start_run(tmp_path, hosts)
    assert [re.search(r"node (\w+)", c)[1] for c in commands] == list(REMOTE)
    assert all(c.startswith(f"cd {tmp_path} && exec ") for c in commands)
    # each node links with its component's own certificate (the rights go by its name), not its host's
    assert all(f"--tls-cert certs/two.{name}.pem --tls-key certs/two.{name}.key" in c
               for name, c in zip(REMOTE, commands))
    nodes = [subprocess.Popen(["bash", "-c", c]) for c in commands]  # as someone would on host two
    code, err = finish(run_proc)
    assert code == 0, err
    assert all(node.wait(timeout=30) == 0 for node in nodes)
    one = run(RunRequest(TOY, tmp_path / "one", progress=False))
    assert one["status"] == "ok"
    assert (tmp_path / "run" / "log.csv").read_bytes() == (tmp_path / "one" / "log.csv").read_bytes()


@pytest.mark.parametrize("who_checks", ["node", "scheduler"])
def test_a_node_of_another_experiment_is_refused(tmp_path, who_checks, ports):
    hosts = write_hosts(tmp_path, ports)
    run_proc, commands = start_run(tmp_path, hosts)
    other = [c + " --set seed=5" for c in commands]  # another seed: another scenario
    if who_checks == "scheduler":  # a node started without the run's fingerprint: the scheduler compares
        other = [re.sub(r" --fingerprint \S+", "", c) for c in other]
    nodes = [subprocess.Popen(["bash", "-c", c], stderr=subprocess.PIPE, text=True) for c in other]
    code, err = finish(run_proc)
    assert code == 2
    assert re.search(r"component '(camera|estimator)': refused", err), err
    assert "another experiment" in err and "the scenario with its overrides" in err
    if who_checks == "node":
        node_err = nodes[0].communicate(timeout=30)[1]
        assert nodes[0].returncode == 2 and "refusing to join run" in node_err
    for node in nodes:  # a node that did not refuse by itself is stopped as someone on host two would
        if node.poll() is None:
            node.terminate()
        node.communicate(timeout=30)


def test_hosts_file_errors_name_the_file_the_field_and_the_line(tmp_path, capsys):
    hosts = tmp_path / "hosts.yaml"
    common = ["run", str(TOY), "--processes", "--hosts", str(hosts), "--out", str(tmp_path / "run")]
    hosts.write_text("scheduler: {host: one}\nhosts:\n  one: {address: 127.0.0.1, port: 3}\n")
    assert main(common) == 2
    assert f"{hosts}: invalid hosts file\n  hosts.one.port (line 3): unknown field" in capsys.readouterr().err
    hosts.write_text("scheduler: {host: one, listen: tcp/127.0.0.1:7447}\nhosts:\n  one: {address: 127.0.0.1}\n"
                     "  two: {address: 127.0.0.2}\ncomponents:\n  camera: {host: two, listen: tcp/127.0.0.2:7450}\n")
    assert main(common) == 2
    assert (f"{hosts}: scheduler.listen (line 1): tcp/127.0.0.1:7447: a run over more than one host "
            "links its machines with mutual TLS") in capsys.readouterr().err
    hosts.write_text("tls: {ca: certs/ca.pem}\nscheduler: {host: one, listen: tls/127.0.0.1:7447}\nhosts:\n"
                     "  one: {address: 127.0.0.1, cert: certs/one.pem, key: certs/one.key}\n")
    assert main(common) == 2
    assert f"{hosts}: tls.ca (line 1): {tmp_path}/certs/ca.pem does not exist" in capsys.readouterr().err
    hosts.write_text("scheduler: {host: one}\nhosts:\n  one: {address: 127.0.0.1}\n"
                     "components:\n  camera: {host: lab}\n")
    assert main(common) == 2
    assert f"{hosts}: components.camera.host (line 5): no host 'lab' under hosts (have: one)" in capsys.readouterr().err
    assert main(["run", str(TOY), "--hosts", str(hosts), "--out", str(tmp_path / "run")]) == 2
    assert "only applies with --processes" in capsys.readouterr().err


def test_ssh_launch_starts_the_remote_nodes_in_their_workdir(tmp_path, ports):
    hosts = write_hosts(tmp_path, ports, launch="ssh")
    hosts.write_text(hosts.read_text().replace("address: 127.0.0.2,", "address: 127.0.0.2, ssh: lab@two,"))
    bin_dir = tmp_path / "bin"  # an ssh that runs the remote command here, and notes what it was given
    bin_dir.mkdir()
    (bin_dir / "ssh").write_text('#!/bin/bash\necho "$@" >> "$(dirname "$0")/calls"\n'
                                 'while [ "$1" = -o ]; do shift 2; done\nshift\nexec bash -c "$1"\n')
    (bin_dir / "ssh").chmod(0o755)
    env = {**os.environ, "PATH": f"{bin_dir}:{os.environ['PATH']}"}
    done = subprocess.run([sys.executable, "-m", "cosim.cli", "run", str(TOY), "--processes", "--hosts", str(hosts),
                           "--out", "run", "--quiet"], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    calls = (bin_dir / "calls").read_text().splitlines()
    assert len(calls) == 2 and all(c.startswith(f"-o BatchMode=yes lab@two cd {tmp_path} && exec ") for c in calls)
    run(RunRequest(TOY, tmp_path / "one", progress=False))
    assert (tmp_path / "run" / "log.csv").read_bytes() == (tmp_path / "one" / "log.csv").read_bytes()

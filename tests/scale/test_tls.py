"""Only the run's nodes on its bus: between machines every link is mutual TLS with the run's
certificates, so a peer without one signed by the run's CA can neither join nor publish."""

from __future__ import annotations

import time
from pathlib import Path

from cosim.cli import main
from cosim.runtime import bus
from cosim.runtime.bus import TlsFiles

KEY = "cosim/run1/coil_driver/coil_voltage_amp"


def certificates(folder: Path, hosts: dict[str, str]) -> dict[str, TlsFiles]:
    """``cosim certs`` for ``hosts`` ({name: address}) under ``folder``: each host's TLS files."""
    folder.mkdir()
    lines = ["tls: {ca: ca.pem}", f"scheduler: {{host: {next(iter(hosts))}}}", "hosts:"]
    lines += [f"  {name}: {{address: {address}, cert: {name}.pem, key: {name}.key}}" for name, address in hosts.items()]
    (folder / "hosts.yaml").write_text("\n".join(lines) + "\n")
    assert main(["certs", str(folder / "hosts.yaml")]) == 0
    return {name: TlsFiles(folder / "ca.pem", folder / f"{name}.pem", folder / f"{name}.key") for name in hosts}


def test_a_peer_without_the_runs_certificate_cannot_join_or_publish(tmp_path, ports):
    ours = certificates(tmp_path / "run", {"one": "127.0.0.1", "two": "127.0.0.2"})
    theirs = certificates(tmp_path / "other", {"evil": "127.0.0.2"})["evil"]  # another CA, same address
    port = ports.port("127.0.0.1")  # held until the node's listener takes it
    endpoint = f"tls/127.0.0.1:{port}"
    node = bus.open_session(listen=[endpoint], tls=ours["one"])
    got: list[bytes] = []
    sub = node.declare_subscriber("cosim/**", lambda sample: got.append(sample.payload.to_bytes()))
    peers = {
        "member": bus.open_session(connect=[endpoint], tls=ours["two"]),
        "foreign": bus.open_session(connect=[endpoint], tls=theirs),
        # trusts the run's CA (its certificate is public) but has no certificate of it
        "impostor": bus.open_session(connect=[endpoint], tls=TlsFiles(ours["two"].ca, theirs.cert, theirs.key)),
        "plain": bus.open_session(connect=[f"tcp/127.0.0.1:{port}"]),
    }
    heard: list[bytes] = []  # what a foreign peer could read of the run
    foreign_sub = peers["foreign"].declare_subscriber("cosim/**",
                                                      lambda sample: heard.append(sample.payload.to_bytes()))
    deadline = time.monotonic() + 10
    while not list(peers["member"].info.peers_zid()) and time.monotonic() < deadline:
        time.sleep(0.05)
    for _ in range(20):  # 1 s of puts from everyone, and from the node
        for name, session in peers.items():
            session.put(KEY, name.encode())
        node.put(KEY, b"node")
        time.sleep(0.05)
    assert set(got) == {b"node", b"member"}  # the member's puts arrive (and the node's own), no one else's
    assert set(heard) == {b"foreign"}  # its own puts only: nothing of the run reaches it
    assert [str(z) for z in node.info.peers_zid()] == [str(peers["member"].info.zid())]
    for name in ("foreign", "impostor", "plain"):
        assert list(peers[name].info.peers_zid()) == []
    foreign_sub.undeclare()
    sub.undeclare()
    for session in (*peers.values(), node):
        session.close()


def test_a_missing_certificate_file_is_named(tmp_path, capsys):
    code = main(["node", "camera", str(Path(__file__).parents[1] / "core" / "data" / "toy.yaml"), "--run-id", "x",
                 "--connect", "tls/127.0.0.1:9", "--tls-ca", str(tmp_path / "ca.pem"), "--tls-cert",
                 str(tmp_path / "two.pem"), "--tls-key", str(tmp_path / "two.key")])
    assert code == 2
    assert f"cosim node camera: the CA certificate {tmp_path / 'ca.pem'} does not exist" in capsys.readouterr().err

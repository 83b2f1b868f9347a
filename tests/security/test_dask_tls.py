"""A sweep on a Dask scheduler over mutual TLS with ``cosim certs``-made certificates
(``--executor dask://tls://HOST:PORT``); a client without the run's certificate is not let in; plain TCP
to a scheduler beyond loopback is refused."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.cli import main

pytest.importorskip("distributed", reason="the cluster extra (dask[distributed]) is not installed")

ROOT = Path(__file__).resolve().parents[2]
TOY = ROOT / "tests" / "core" / "data" / "toy.yaml"
DASK = str(Path(sys.executable).with_name("dask"))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_sweep_runs_on_a_tls_dask_scheduler_and_a_client_without_certificate_is_refused(tmp_path):
    hosts = tmp_path / "hosts.yaml"
    hosts.write_text("tls: {ca: certs/ca.pem}\nscheduler: {host: sched}\nhosts:\n"
                     + "".join(f"  {h}: {{address: 127.0.0.1, cert: certs/{h}.pem, key: certs/{h}.key}}\n"
                               for h in ("sched", "worker", "client")))
    assert main(["certs", str(hosts)]) == 0
    c = tmp_path / "certs"

    def tls(h):
        return ["--tls-ca-file", str(c / "ca.pem"), "--tls-cert", str(c / f"{h}.pem"), "--tls-key", str(c / f"{h}.key")]

    port = _free_port()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    procs = [subprocess.Popen([DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--protocol", "tls",
                               "--no-dashboard", *tls("sched")], env=env, stderr=subprocess.DEVNULL, cwd=tmp_path)]
    try:
        procs.append(subprocess.Popen([DASK, "worker", f"tls://127.0.0.1:{port}", "--nworkers", "1", "--nthreads", "1",
                                       "--no-dashboard", "--host", "127.0.0.1", *tls("worker")],
                                      env=env, stderr=subprocess.DEVNULL, cwd=tmp_path))
        sweep = 'sweep={"components.camera.params.interval_s": [0.02, 0.04]}'
        code = main(["run", str(TOY), "--out", str(tmp_path / "out"), "--set", sweep, "--set", "duration_s=1",
                     "--quiet", "--executor", f"dask://tls://127.0.0.1:{port}", "--tls-ca", str(c / "ca.pem"),
                     "--tls-cert", str(c / "client.pem"), "--tls-key", str(c / "client.key")])
        assert code == 0
        assert len(list((tmp_path / "out" / "runs").glob("*/log.csv"))) == 2
        # no certificate of the run: the TLS handshake fails (plain TCP, or TLS with a certificate of its own)
        probe = subprocess.run([sys.executable, "-c",
                                "import sys; from distributed import Client\n"
                                "try:\n    Client(sys.argv[1], timeout=3); print('JOINED')\n"
                                "except Exception as e:\n    print('REFUSED', type(e).__name__)\n",
                                f"tcp://127.0.0.1:{port}"], capture_output=True, text=True, timeout=60, env=env)
        assert probe.stdout.startswith("REFUSED"), probe.stdout + probe.stderr
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def test_tls_needs_certificates_and_plain_tcp_beyond_loopback_is_refused(tmp_path, capsys):
    common = ["run", str(TOY), "--out", str(tmp_path), "--set", 'sweep={"seed": [1, 2]}']
    assert main([*common, "--executor", "dask://tls://127.0.0.1:8786"]) == 2
    assert "a TLS scheduler needs the run's certificates: --tls-ca, --tls-cert and --tls-key" in capsys.readouterr().err
    assert main([*common, "--executor", "dask://10.0.0.5:8786"]) == 2
    assert "use dask://tls://10.0.0.5:8786 with the run's certificates" in capsys.readouterr().err

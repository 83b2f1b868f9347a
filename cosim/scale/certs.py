"""``cosim certs HOSTS.yaml``: a run's certificate authority, one certificate per host and one per
placed component (openssl).

Writes the files the hosts file names (paths relative to it): the CA
certificate ``tls.ca`` with its private key beside it (same name, ``.key``),
and for every host with ``cert`` and ``key`` a P-256 key and a certificate
signed by that CA, named after the host, naming the host's ``address`` (an IP
address or a DNS name: zenoh checks it when a peer connects there) and good
for both ends of a link (server and client authentication: mutual TLS). Every
component placed under ``components:`` on such a host gets a key and a
certificate of its own beside the host's (``certs/lab.driver.pem``, named
``driver@lab``, same address), which its node links with: the run's rights
go by that name (:mod:`cosim.runtime.rights`). The CA exists only for this run's
machines, so a certificate it signed admits a peer to this run and to nothing
else. Private keys are written readable by their owner only.
"""

from __future__ import annotations

import ipaddress
import secrets
import shutil
import subprocess
import tempfile
from pathlib import Path

from cosim.contract.errors import UserError
from cosim.runtime.hosts import component_files, component_identity, read_hosts_file


def _san(address: str) -> str:
    try:
        return f"IP:{ipaddress.ip_address(address.strip('[]'))}"
    except ValueError:
        return f"DNS:{address}"


def _openssl(*args: str) -> None:
    done = subprocess.run(["openssl", *args], capture_output=True, text=True)
    if done.returncode != 0:
        raise UserError(f"openssl {args[0]} failed (exit status {done.returncode}): {done.stderr.strip()}")


def make_certificates(hosts_file: Path, days: int = 365, force: bool = False) -> list[Path]:
    """Write the run's CA and the hosts' keys and certificates; returns the files written."""
    spec, base = read_hosts_file(hosts_file)
    if spec.tls is None:
        raise UserError(f"{hosts_file}: tls: missing: name the run's CA certificate, e.g. tls: {{ca: certs/ca.pem}}")
    hosts = {name: h for name, h in spec.hosts.items() if h.cert and h.key}
    if not hosts:
        raise UserError(f"{hosts_file}: no host names a cert and a key (hosts.NAME.cert, hosts.NAME.key)")
    if shutil.which("openssl") is None:
        raise UserError("openssl is not installed (apt-get install openssl): cosim certs calls it")
    ca = base / spec.tls.ca
    ca_key = ca.with_suffix(".key")
    #: (common name, address, certificate, key) of every certificate to make: the hosts', then the components'
    issued = [(name, h.address, base / h.cert, base / h.key) for name, h in hosts.items()]
    issued += [(component_identity(comp, p.host), hosts[p.host].address,
                *component_files(base / hosts[p.host].cert, base / hosts[p.host].key, comp))
               for comp, p in spec.components.items() if p.host in hosts]
    files = [ca, ca_key, *(f for _, _, cert, key in issued for f in (cert, key))]
    existing = [str(f) for f in files if f.exists()]
    if existing and not force:
        raise UserError(f"would overwrite {', '.join(existing)} (--force replaces them, and every host then "
                        "needs the new files)")
    for f in files:
        f.parent.mkdir(parents=True, exist_ok=True)
    curve = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes"]
    _openssl("req", "-x509", *curve, "-keyout", str(ca_key), "-out", str(ca), "-days", str(days),
             "-subj", f"/CN=cosim run CA ({hosts_file.name})",
             "-addext", "basicConstraints=critical,CA:TRUE", "-addext", "keyUsage=critical,keyCertSign,cRLSign")
    with tempfile.TemporaryDirectory() as tmp:
        for i, (name, address, cert, key) in enumerate(issued):
            csr, ext = Path(tmp) / f"{i}.csr", Path(tmp) / f"{i}.ext"
            _openssl("req", "-new", *curve, "-keyout", str(key), "-out", str(csr), "-subj", f"/CN={name}")
            ext.write_text("basicConstraints=critical,CA:FALSE\nkeyUsage=critical,digitalSignature\n"
                           f"extendedKeyUsage=serverAuth,clientAuth\nsubjectAltName={_san(address)}\n")
            _openssl("x509", "-req", "-in", str(csr), "-CA", str(ca), "-CAkey", str(ca_key),
                     "-set_serial", str(secrets.randbits(63)), "-days", str(days), "-out", str(cert),
                     "-extfile", str(ext))
    for f in (ca_key, *(key for _, _, _, key in issued)):
        f.chmod(0o600)
    return files

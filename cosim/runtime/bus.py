"""The zenoh bus: session factory, key expressions and the array codec.

Keys (``run_id`` and component names are single key chunks):

* ``cosim/{run_id}/{component}/outputs``: the values of all the
  component's output ports, published once per step it takes (one message:
  a step's outputs are consumed together, and a message costs far more
  than its bytes);
* ``cosim/{run_id}/alive/{component}``: liveliness token of a running node;
* ``cosim/{run_id}/ctl/tick``: the scheduler's credits (the ticks nodes may
  step) and set-up checks, to every node;
* ``cosim/{run_id}/ctl/{component}/cmd|reply``: commands to one node and every
  node's replies (see :mod:`cosim.runtime.node`); replies report steps with their
  outputs, so the scheduler records a distributed run without subscribing
  to every port.

Values travel as raw little-endian float64 bytes, the ports one after
another in the component's declared order and shapes (producer and consumer
know the wiring, and every node checked the run's fingerprint; see
:class:`cosim.runtime.portcache.PortStore`); the attachment carries the tick index (int64, little-endian),
so a consumer knows which step produced the values. No pickle anywhere.
"""

from __future__ import annotations

import json
import struct
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, TypeVar

import numpy as np
import zenoh

from cosim.contract.errors import UserError

ROOT = "cosim"

#: zenoh's retry of a link that is not up yet (default: from 1 s up to 4 s between tries)
CONNECT_RETRY = {"period_init_ms": 100, "period_max_ms": 1000, "period_increase_factor": 2}

_F64 = np.dtype("<f8")
_T = TypeVar("_T")
_POLL_MAX_S = 5e-4


def poll(fetch: Callable[[], _T | None], timeout_s: float) -> _T | None:
    """Call ``fetch`` until it returns something or ``timeout_s`` passes (then None).

    Waiting threads never block inside zenoh (a thread blocked in a zenoh
    ``recv`` can neither be woken by undeclaring nor survive interpreter
    exit), so they poll FIFO channels with ``try_recv``, backing off from
    20 us to 0.5 ms. Local puts land synchronously, so in one process the
    first call succeeds.
    """
    value = fetch()
    if value is not None:
        return value
    deadline = time.monotonic() + timeout_s
    delay = 2e-5
    while time.monotonic() < deadline:
        time.sleep(delay)
        value = fetch()
        if value is not None:
            return value
        delay = min(delay * 2, _POLL_MAX_S)
    return None


@dataclass(frozen=True)
class TlsFiles:
    """The PEM files of mutual TLS between the machines of a run: the run's CA certificate, and this
    host's certificate (signed by that CA, naming the host's address) and private key."""

    ca: Path
    cert: Path
    key: Path

    def check(self, where: str) -> None:
        """A missing file is a :class:`UserError` naming it and ``where`` it was given."""
        for what, path in (("CA certificate", self.ca), ("certificate", self.cert), ("private key", self.key)):
            if not Path(path).is_file():
                raise UserError(f"{where}: the {what} {path} does not exist (cosim certs HOSTS.yaml makes a "
                                "run's certificates)")


def _insert_tls(conf: zenoh.Config, tls: TlsFiles) -> None:
    """Every tls/ link both ways with this host's certificate, and only with a peer whose certificate
    the run's CA signed (mutual TLS); a peer's certificate must name the address it is reached at."""
    base = "transport/link/tls/"
    for key, path in (("root_ca_certificate", tls.ca), ("listen_certificate", tls.cert),
                      ("listen_private_key", tls.key), ("connect_certificate", tls.cert),
                      ("connect_private_key", tls.key)):
        conf.insert_json5(base + key, json.dumps(str(Path(path).resolve())))
    conf.insert_json5(base + "enable_mtls", "true")
    conf.insert_json5(base + "verify_name_on_connect", "true")


def open_session(listen: list[str] | None = None, connect: list[str] | None = None,
                 tls: TlsFiles | None = None, access: dict | None = None) -> zenoh.Session:
    """Open a zenoh session.

    With no endpoints this is the embedded default: an in-process peer with
    multicast scouting off, so nothing leaves the process and no router is
    needed. For a run spread over processes every process opens a ``"peer"``
    session that listens on an endpoint of its own (e.g.
    ``"tcp/127.0.0.1:7447"``) and connects to the endpoints of the processes
    started before it: a full mesh, so a port value goes straight from its
    producer's process to its consumer's. Peers forward nothing for others and
    gossip is off, so the links are exactly the ones given. They use zenoh's
    low-latency transport (no QoS priorities, no batching): every message is a
    step someone waits for. With ``tls`` (a run over machines, ``tls/``
    endpoints) every link is mutual TLS with the run's certificates: a peer
    without a certificate of the run's CA can neither connect nor publish. ``access``: zenoh's
    ``access_control`` section (:func:`cosim.runtime.rights.access_control`): what each peer, known by
    its certificate's name, may publish and subscribe to here.
    """
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    for what, endpoints in (("listen", listen), ("connect", connect)):
        try:
            conf.insert_json5(f"{what}/endpoints", json.dumps(list(endpoints or [])))
        except zenoh.ZError:
            raise UserError(f"bad zenoh endpoint in --{what} {' '.join(endpoints or [])}: "
                            "expected <protocol>/<address>, e.g. tcp/127.0.0.1:7447") from None
    if listen or connect:  # every process of a run must agree on the transport
        conf.insert_json5("scouting/gossip/enabled", "false")
        # a node may connect to one that is not up yet (started later, on another machine): retry often
        conf.insert_json5("connect/retry", json.dumps(CONNECT_RETRY))
        conf.insert_json5("transport/unicast/lowlatency", "true")
        conf.insert_json5("transport/unicast/qos/enabled", "false")
    if tls is not None:
        _insert_tls(conf, tls)
    if access is not None:
        conf.insert_json5("access_control", json.dumps(access))
    try:
        return zenoh.open(conf)
    except zenoh.ZError as exc:  # e.g. a certificate or key zenoh cannot read
        where = " (with the TLS files " + ", ".join(map(str, (tls.ca, tls.cert, tls.key))) + ")" if tls else ""
        raise UserError(f"cannot open the zenoh session listening on {list(listen or [])}{where}: {exc}") from None


def publisher(session: zenoh.Session, key: str) -> zenoh.Publisher:
    """A publisher for lockstep traffic: reliable, blocking instead of dropping under
    congestion (zenoh's default drops), and express: every message is a step some
    consumer waits for, so it leaves at once instead of waiting to be batched."""
    return session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK,
                                     reliability=zenoh.Reliability.RELIABLE, express=True)


def outputs_key(run_id: str, component: str) -> str:
    """The zenoh key a component publishes its outputs on."""
    return f"{ROOT}/{run_id}/{component}/outputs"


def alive_key(run_id: str, component: str = "*") -> str:
    """The zenoh liveliness key of a component's node (``*``: every node of the run)."""
    return f"{ROOT}/{run_id}/alive/{component}"


def scheduler_alive_key(run_id: str) -> str:
    """The scheduler's liveliness token: its nodes stop when it goes."""
    return f"{ROOT}/{run_id}/ctl/scheduler-alive"


def ctl_key(run_id: str, component: str, what: str) -> str:
    """The zenoh key of a control message ``what`` to a component."""
    return f"{ROOT}/{run_id}/ctl/{component}/{what}"


def tick_key(run_id: str) -> str:
    """The zenoh key the scheduler grants ticks on."""
    return f"{ROOT}/{run_id}/ctl/tick"


_TICK = struct.Struct("<q")


def encode_tick(tick: int) -> bytes:
    """The attachment that stamps a step's outputs with the tick they were produced at."""
    return _TICK.pack(tick)


def decode_tick(attachment: bytes) -> int:
    """The tick stamped in a message's attachment."""
    return _TICK.unpack_from(attachment)[0]


def _pack(values) -> bytes:
    return b"".join(np.asarray(v, dtype=_F64).tobytes() for v in values)


def encode_reply(header: dict, values: list[np.ndarray] = ()) -> tuple[bytes, bytes]:
    """``(payload, attachment)`` of a node's reply: the raw float64 bytes of
    ``values`` one after another (rows of its outputs, see
    :meth:`cosim.runtime.portcache.PortStore.store_payload`), and ``header`` as JSON."""
    return _pack(values), encode_json(header)


def encode_json(obj) -> bytes:
    """``obj`` as compact JSON bytes."""
    return json.dumps(obj, separators=(",", ":")).encode()


def decode_json(payload: bytes):
    """The object a JSON payload holds."""
    return json.loads(bytes(payload))

"""The zenoh bus: session factory, key expressions and the array codec.

Keys (``run_id`` and component names are single key chunks):

* ``cosim/{run_id}/{component}/{port}``: a port value, published by its
  component once per step it takes;
* ``cosim/{run_id}/alive/{component}``: liveliness token of a running node;
* ``cosim/{run_id}/ctl/tick``: the scheduler's lockstep tick, to every node;
* ``cosim/{run_id}/ctl/{component}/cmd|reply``: set-up commands to one node
  and every node's replies (see :mod:`cosim.node`).

Arrays travel as raw little-endian float64 bytes; the attachment carries the
tick index (int64, little-endian) and the shape (int32 each), so a consumer
knows which step produced the value. No pickle anywhere.
"""

from __future__ import annotations

import json
import struct
import time
from typing import Callable, TypeVar

import numpy as np
import zenoh

ROOT = "cosim"
RESERVED_NAMES = ("alive", "ctl")

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


def open_session(listen: list[str] | None = None, connect: list[str] | None = None,
                 mode: str = "peer") -> zenoh.Session:
    """Open a zenoh session.

    With no endpoints this is the embedded default: an in-process peer with
    multicast scouting off, so nothing leaves the process and no router is
    needed. For a run spread over processes the scheduler opens a
    ``"router"`` session listening on an explicit endpoint (e.g.
    ``"tcp/127.0.0.1:7447"``) and each node a ``"client"`` session connecting
    to it; the router forwards between nodes.
    """
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("listen/endpoints", json.dumps(list(listen or [])))
    conf.insert_json5("connect/endpoints", json.dumps(list(connect or [])))
    return zenoh.open(conf)


def publisher(session: zenoh.Session, key: str) -> zenoh.Publisher:
    """A publisher for lockstep traffic: reliable, blocking instead of dropping under
    congestion (zenoh's default drops), and express: every message is a step some
    consumer waits for, so it leaves at once instead of waiting to be batched."""
    return session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK,
                                     reliability=zenoh.Reliability.RELIABLE, express=True)


def port_key(run_id: str, component: str, port: str) -> str:
    return f"{ROOT}/{run_id}/{component}/{port}"


def alive_key(run_id: str, component: str = "*") -> str:
    return f"{ROOT}/{run_id}/alive/{component}"


def ctl_key(run_id: str, component: str, what: str) -> str:
    return f"{ROOT}/{run_id}/ctl/{component}/{what}"


def tick_key(run_id: str) -> str:
    return f"{ROOT}/{run_id}/ctl/tick"


_HEAD = struct.Struct("<qB")


def encode_array(value: np.ndarray, tick: int) -> tuple[bytes, bytes]:
    """``(payload, attachment)`` for an array produced at ``tick``."""
    arr = np.asarray(value, dtype=_F64)
    return arr.tobytes(), _HEAD.pack(tick, arr.ndim) + struct.pack(f"<{arr.ndim}i", *arr.shape)


def decode_array(payload: bytes, attachment: bytes) -> tuple[int, np.ndarray]:
    """Inverse of :func:`encode_array`: ``(tick, array)``; the array is read-only."""
    tick, ndim = _HEAD.unpack_from(attachment)
    shape = struct.unpack_from(f"<{ndim}i", attachment, _HEAD.size)
    return tick, np.frombuffer(payload, dtype=_F64).reshape(shape)


def encode_json(obj) -> bytes:
    return json.dumps(obj, separators=(",", ":")).encode()


def decode_json(payload: bytes):
    return json.loads(bytes(payload))

"""Port values received from the bus, keyed by component and tick stamp.

A component's outputs travel as one message per tick (see
:meth:`cosim.runtime.stepper.Stepper.step`), and are kept so: per producing
component, its few most recent rows, each the flat float64 array of the
message (a row costs one store; a port's value is a view into it, made
when a consumer reads it, see :func:`port_slots`). :class:`PortStore` keeps them; a consumer over a delayed edge
reads the previous tick's row even after the producer published a newer one.
:class:`PortCache` fills a store from zenoh FIFO channels, one per producing
component (no Python callback thread: a local put lands in the channel
before ``put`` returns), and waits, polling, for a stamp that has not arrived
yet. Nodes fill a plain store from their subscribers' callbacks instead.
"""

from __future__ import annotations

import numpy as np
import zenoh

from cosim.contract.errors import PortTimeout
from cosim.runtime import bus


class PortStore:
    """Rows of the components in ``outputs`` (a wiring's ``{component: [Port, ...]}``).

    ``keep``: rows kept per component; enough for a delayed edge in lockstep, more where
    producers may run ahead of their consumers (a distributed run's window).
    """

    def __init__(self, outputs: dict, keep: int = 3):
        #: per component and port, (start, end, shape or None for a vector) in the component's rows
        slots = {c: port_slots(ports) for c, ports in outputs.items()}
        self._slots = {c: {p.name: slot for p, slot in zip(ports, slots[c])} for c, ports in outputs.items()}
        self._sizes = {c: s[-1][1] if s else 0 for c, s in slots.items()}  # the last port's end
        self._rows: dict[str, dict[int, np.ndarray]] = {c: {} for c in outputs}
        self._keep = keep

    def slot(self, comp: str, port: str) -> tuple[int, int, tuple | None]:
        """Where ``comp.port`` lies in ``comp``'s rows (see :func:`port_slots`)."""
        return self._slots[comp][port]

    def store_payload(self, comp: str, ticks: list[int], payload: bytes) -> None:
        """Keep ``comp``'s rows of ``ticks``, laid end to end in ``payload``."""
        flat, size = np.frombuffer(payload, dtype="<f8"), self._sizes[comp]
        if flat.size != len(ticks) * size:
            raise ValueError(f"{comp}: payload holds {flat.size} values, expected {len(ticks)} x {size}")
        if len(ticks) == 1:  # a node's input, every hop: the row is the payload
            self.store(comp, ticks[0], flat)
            return
        for i, tick in enumerate(ticks):
            self.store(comp, tick, flat[i * size:(i + 1) * size])

    def store(self, comp: str, tick: int, row: np.ndarray) -> None:
        """Keep ``comp``'s row produced at ``tick``; a producer's ticks come in increasing order,
        so the oldest row is the first one stored."""
        rows = self._rows[comp]
        rows[tick] = row
        if len(rows) > self._keep:
            del rows[next(iter(rows))]

    def has(self, comp: str, stamp: int) -> bool:
        return stamp in self._rows[comp]

    def rows_of(self, comp: str) -> dict[int, np.ndarray]:
        """``comp``'s rows by tick stamp, the store's own dict (read it, never change it): a test of a stamp
        in it is what :meth:`has` does, without the call (a plain store; a :class:`PortCache` fills it
        only when asked)."""
        return self._rows[comp]

    def row(self, comp: str, stamp: int, timeout_s: float = 0.0) -> np.ndarray:
        """``comp``'s outputs produced at tick ``stamp``, flat (a plain store does not wait)."""
        try:
            return self._rows[comp][stamp]
        except KeyError:
            raise PortTimeout(comp, None, stamp) from None


class PortCache(PortStore):
    """A store subscribed to the outputs of the components in ``outputs`` of run ``run_id``
    through FIFO channels."""

    def __init__(self, session: zenoh.Session, run_id: str, outputs: dict, keep: int = 3):
        super().__init__(outputs, keep)
        self._subs = {c: session.declare_subscriber(bus.outputs_key(run_id, c))
                      for c, ports in outputs.items() if ports}

    def _drain(self, comp: str) -> None:
        """Move what has arrived from one component into the store."""
        sub = self._subs[comp]
        while (sample := sub.try_recv()) is not None:
            self.store(comp, bus.decode_tick(sample.attachment.to_bytes()),
                       np.frombuffer(sample.payload.to_bytes(), dtype="<f8"))

    def has(self, comp: str, stamp: int) -> bool:
        if stamp not in self._rows[comp]:
            self._drain(comp)
        return stamp in self._rows[comp]

    def row(self, comp: str, stamp: int, timeout_s: float = 0.0) -> np.ndarray:
        """Waits up to ``timeout_s`` for the row (see :func:`cosim.runtime.bus.poll`)."""
        rows = self._rows[comp]
        found = rows.get(stamp)
        if found is None:
            self._drain(comp)
            found = rows.get(stamp)
            if found is None:

                def fetch():
                    self._drain(comp)
                    return rows.get(stamp)

                found = bus.poll(fetch, timeout_s)
                if found is None:
                    raise PortTimeout(comp, None, stamp)
        return found

    def close(self) -> None:
        for sub in self._subs.values():
            sub.undeclare()
        self._subs = {}


def expected_stamp(tick: int, period: int, delay: int) -> int:
    """Tick at which a producer with ``period`` last updated, as seen over an edge with ``delay``.

    -1 means its initial outputs.
    """
    k = tick - delay
    return -1 if k < 0 else (k // period) * period


def port_slots(ports) -> list[tuple[int, int, tuple | None]]:
    """``(start, end, shape)`` of each of ``ports`` (declared order) in its component's flat row:
    ``row[start:end]`` is a vector port's value as it is (shape None), else reshaped to ``shape``."""
    out, start = [], 0
    for port in ports:
        size = int(np.prod(port.shape))
        out.append((start, start + size, None if len(port.shape) == 1 else port.shape))
        start += size
    return out

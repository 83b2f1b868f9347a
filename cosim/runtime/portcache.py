"""Port values received from the bus, keyed by (component, port) and tick stamp.

:class:`PortStore` keeps, per port, its few most recent values so a
consumer over a delayed edge can read the previous tick's value even after
the producer published a newer one. :class:`PortCache` fills a store from
zenoh FIFO channels, one per producing component (no Python callback
thread: a local put lands in the channel before ``put`` returns), and
waits, polling, for a stamp that has not arrived yet. Nodes fill a plain
store from their subscribers' callbacks instead.
"""

from __future__ import annotations

import numpy as np
import zenoh

from cosim.runtime import bus


class PortTimeout(RuntimeError):
    def __init__(self, component: str, port: str, stamp: int):
        super().__init__(f"no value of {component}.{port} for tick {stamp}")
        self.component, self.port, self.stamp = component, port, stamp


class PortStore:
    """``keep``: values kept per port; enough for a delayed edge in lockstep, more where
    producers may run ahead of their consumers (a distributed run's window)."""

    def __init__(self, ports: list[tuple[str, str]], keep: int = 3):
        self._values: dict[tuple[str, str], dict[int, np.ndarray]] = {p: {} for p in ports}
        self._keep = keep

    def store(self, key: tuple[str, str], tick: int, value: np.ndarray) -> None:
        """Keep ``value`` of ``key`` produced at ``tick``; a producer's ticks come in
        increasing order, so the oldest value is the first one stored."""
        values = self._values[key]
        values[tick] = value
        if len(values) > self._keep:
            del values[next(iter(values))]

    def has(self, comp: str, port: str, stamp: int) -> bool:
        return stamp in self._values[(comp, port)]

    def get(self, comp: str, port: str, stamp: int, timeout_s: float) -> np.ndarray:
        """The value of ``comp.port`` produced at tick ``stamp`` (a plain store does not wait)."""
        try:
            return self._values[(comp, port)][stamp]
        except KeyError:
            raise PortTimeout(comp, port, stamp) from None


class PortCache(PortStore):
    """A store subscribed to the outputs of the components in ``outputs`` (a wiring's
    ``{component: [Port, ...]}``) of run ``run_id`` through FIFO channels."""

    def __init__(self, session: zenoh.Session, run_id: str, outputs: dict):
        super().__init__([(c, p.name) for c, ports in outputs.items() for p in ports])
        self._layouts = bus.output_layouts(outputs)
        self._subs = {c: session.declare_subscriber(bus.outputs_key(run_id, c))
                      for c, ports in outputs.items() if ports}

    def _drain(self, comp: str) -> None:
        """Move what has arrived from one component into the store."""
        sub, (names, layout) = self._subs[comp], self._layouts[comp]
        while (sample := sub.try_recv()) is not None:
            tick = bus.decode_tick(sample.attachment.to_bytes())
            for name, value in zip(names, layout.split(sample.payload.to_bytes())[0]):
                self.store((comp, name), tick, value)

    def has(self, comp: str, port: str, stamp: int) -> bool:
        self._drain(comp)
        return super().has(comp, port, stamp)

    def get(self, comp: str, port: str, stamp: int, timeout_s: float) -> np.ndarray:
        """Waits up to ``timeout_s`` for the value (see :func:`cosim.runtime.bus.poll`)."""
        key = (comp, port)
        values = self._values[key]
        if stamp not in values:
            self._drain(comp)
        if stamp not in values:

            def fetch():
                self._drain(comp)
                return values.get(stamp)

            if bus.poll(fetch, timeout_s) is None:
                raise PortTimeout(comp, port, stamp)
        return values[stamp]

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

"""Steps one component on the bus: gather its inputs for a tick, step, publish.

Used alike by the scheduler for components in its own process and by
``cosim node`` for a component in a process of its own, so both paths read
and write exactly the same bytes.
"""

from __future__ import annotations

import zlib
from pathlib import Path
from typing import Any

import numpy as np
import zenoh

from cosim.contract.component import Component, ComponentError, ComponentFault
from cosim.contract.errors import PortTimeout
from cosim.runtime import bus
from cosim.runtime.portcache import PortStore, port_slots
from cosim.runtime.wiring import Wiring
from cosim.scenario.paths import make_path
from cosim.scenario.schema import Scenario


def component_rng(seed: int, name: str) -> np.random.Generator:
    """A generator private to one component, the same in every process layout."""
    return np.random.default_rng([seed, zlib.crc32(name.encode())])


def setup_component(scenario: Scenario, wiring: Wiring, name: str, run_dir: Path | None = None) -> Component:
    """Instantiate and set up component ``name`` with its params, ``dt`` and (if asked) the path
    and the run's output folder ``run_dir`` with the recording's id (see :class:`Component`)."""
    spec = scenario.components[name]
    component = wiring.classes[name]()
    params: dict[str, Any] = {"dt": scenario.dt_s, **spec.params}
    if getattr(component, "uses_path", False):
        if scenario.path is None:
            raise ComponentError(f"component {name!r} ({spec.plugin}) needs a path; the scenario has none")
        params["path"] = make_path(scenario.path.plugin, scenario.path.params)
    if getattr(component, "uses_run_dir", False):
        params["run_dir"] = None if run_dir is None else Path(run_dir)
        params["recording_id"] = scenario.recording_id
        params["name"] = name
    try:
        component.setup(params, component_rng(scenario.seed, name))
    except ComponentError as exc:
        raise ComponentError(f"components.{name} ({spec.plugin}): {exc}") from None
    return component


class Stepper:
    """Holds one set-up component and its bus endpoints."""

    def __init__(self, name: str, component: Component, session: zenoh.Session, run_id: str,
                 wiring: Wiring, cache: PortStore, timeout_s: float):
        self.name = name
        self.component = component
        self.cache = cache
        self.timeout_s = timeout_s
        self.period = wiring.periods[name]
        #: (input port, producer, its port, its slot in the producer's rows, period, delay) of each input
        self._inputs = [(e.dst_port, e.src, e.src_port, cache.slot(e.src, e.src_port), wiring.periods[e.src], e.delay)
                        for e in wiring.edges_into(name)]
        self._ports = {p.name: p.shape for p in wiring.outputs[name]}
        #: (port, shape, start, end) of each output in the published row
        ports = wiring.outputs[name]
        self._slots = [(p.name, p.shape, start, end) for p, (start, end, _) in zip(ports, port_slots(ports))]
        self._size = self._slots[-1][3] if self._slots else 0
        # a component without outputs (a scope, a logger) publishes nothing
        self._pub = bus.publisher(session, bus.outputs_key(run_id, name)) if self._ports else None
        #: the row last published: [every output, flat, in the declared port order] (or [] before any)
        self.last_outputs: list[np.ndarray] = []

    def publish_initial(self) -> None:
        self._publish(-1, self.component.initial_outputs())

    def step(self, tick: int, t: float) -> None:
        row, timeout = self.cache.row, self.timeout_s
        inputs = {}
        for dst, src, port, (start, end, shape), period, delay in self._inputs:
            k = tick - delay  # expected_stamp(tick, period, delay), inlined: this runs for every input and tick
            try:
                value = row(src, -1 if k < 0 else k - k % period, timeout)[start:end]
            except PortTimeout as exc:
                raise PortTimeout(src, port, exc.stamp) from None
            inputs[dst] = value if shape is None else value.reshape(shape)
        self._publish(tick, self.component.step(t, inputs))
        if self.component.fault:
            raise ComponentFault(self.component.fault)

    def _publish(self, tick: int, outputs: dict[str, np.ndarray]) -> None:
        if outputs is None or outputs.keys() != self._ports.keys():
            got = sorted(outputs or {})
            raise ComponentError(f"returned ports {got}, expected {sorted(self._ports)}")
        row = np.empty(self._size)
        for port, shape, start, end in self._slots:  # every step of every component: no call it can spare
            value = outputs[port]
            if type(value) is float and not shape:  # a scalar port's Python float, as it comes
                row[start] = value
                continue
            if type(value) is not np.ndarray or value.dtype != np.float64:
                value = np.asarray(value, dtype=float)
            if value.shape != shape:
                raise ComponentError(f"output {port!r} has shape {value.shape}, declared {shape}")
            row[start:end] = value if value.ndim < 2 else value.reshape(-1)
        self.last_outputs = [row]
        if self._pub is not None:
            self._pub.put(row.tobytes(), attachment=bus.encode_tick(tick))

    def close(self) -> str | None:
        """Close the component; returns the fault it set while closing (see :class:`Component`), if any."""
        if self._pub is not None:
            self._pub.undeclare()
        before = self.component.fault
        self.component.close()
        after = self.component.fault
        return after if after and after != before else None

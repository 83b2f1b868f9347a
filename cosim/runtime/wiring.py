"""The wiring: components, ports and edges of a scenario, checked and ordered.

Built from a :class:`~cosim.scenario.schema.Scenario` and the registered component
classes (ports are class attributes, so nothing is instantiated). The step
order is a topological sort over the undelayed edges; a cycle is rejected
unless one of its edges is marked ``delay: 1``. :func:`connection_table`
prints the wiring like python-control's ``interconnect``.
"""

from __future__ import annotations

from dataclasses import dataclass

from cosim.contract.component import Port
from cosim.contract.errors import UserError, WiringError
from cosim.contract.plugins import lookup
from cosim.scenario.schema import Scenario


@dataclass(frozen=True)
class Edge:
    """One wire: ``src.src_port`` feeds ``dst.dst_port``, ``delay`` (0 or 1) ticks late."""
    src: str
    src_port: str
    dst: str
    dst_port: str
    delay: int

    def label(self) -> str:
        delay = f" (delay {self.delay})" if self.delay else ""
        return f"{self.src}.{self.src_port} -> {self.dst}.{self.dst_port}{delay}"


@dataclass
class Wiring:
    """A scenario's components wired: their classes, ports, edges, step order and update periods."""
    classes: dict[str, type]
    inputs: dict[str, tuple[Port, ...]]
    outputs: dict[str, tuple[Port, ...]]
    edges: list[Edge]
    order: list[str]
    periods: dict[str, int]

    def edges_into(self, component: str) -> list[Edge]:
        return [e for e in self.edges if e.dst == component]

    def max_delay(self, consumer: str | None = None) -> int:
        """The longest delay [ticks] of the edges (into ``consumer`` only, if given); 0 without any."""
        return max((e.delay for e in self.edges if consumer is None or e.dst == consumer), default=0)

    def unused_outputs(self) -> list[str]:
        used = {(e.src, e.src_port) for e in self.edges}
        return [f"{c}.{p.name}" for c in self.order for p in self.outputs[c] if (c, p.name) not in used]


def build_wiring(scenario: Scenario) -> Wiring:
    """Wire the scenario's components: ports checked by name, shape and unit, parameters validated, step order."""
    classes = {name: lookup("component", spec.plugin) for name, spec in scenario.components.items()}
    inputs = {name: tuple(cls.inputs) for name, cls in classes.items()}
    outputs = {name: tuple(cls.outputs) for name, cls in classes.items()}
    edges: list[Edge] = []
    for dst, spec in scenario.components.items():
        in_ports = {p.name: p for p in inputs[dst]}
        for port_name, wire in spec.inputs.items():
            if port_name not in in_ports:
                raise WiringError(
                    f"components.{dst}.inputs.{port_name}: {spec.plugin} has no input {port_name!r} "
                    f"(inputs: {', '.join(in_ports) or 'none'})"
                )
            src_ports = {p.name: p for p in outputs[wire.component]}
            if wire.port not in src_ports:
                raise WiringError(
                    f"components.{dst}.inputs.{port_name}: {wire.component} has no output {wire.port!r} "
                    f"(outputs: {', '.join(src_ports) or 'none'})"
                )
            a, b = src_ports[wire.port], in_ports[port_name]
            if a.shape != b.shape or a.unit != b.unit:
                raise WiringError(
                    f"components.{dst}.inputs.{port_name}: {wire.source} is {a.shape} [{a.unit}] "
                    f"but {dst}.{port_name} expects {b.shape} [{b.unit}]"
                )
            edges.append(Edge(wire.component, wire.port, dst, port_name, wire.delay))
        missing = [p.name for p in inputs[dst] if p.name not in spec.inputs]
        if missing:
            raise WiringError(f"components.{dst}.inputs: not wired: {', '.join(missing)}")
    for name, spec in scenario.components.items():
        try:
            classes[name].validate_params({"dt": scenario.dt_s, **spec.params})
        except UserError as exc:
            raise WiringError(f"components.{name}.params ({spec.plugin}): {exc}") from None
    order = _topological_order(list(scenario.components), edges)
    periods = {name: spec.period for name, spec in scenario.components.items()}
    return Wiring(classes, inputs, outputs, edges, order, periods)


def _topological_order(names: list[str], edges: list[Edge]) -> list[str]:
    """Kahn's algorithm over undelayed edges; ties keep the scenario's order (deterministic)."""
    deps = {n: {e.src for e in edges if e.dst == n and not e.delay and e.src != n} for n in names}
    self_loops = [e for e in edges if e.src == e.dst and not e.delay]
    if self_loops:
        raise WiringError(f"{self_loops[0].label()}: a component feeding itself needs delay: 1")
    order: list[str] = []
    remaining = list(names)
    while remaining:
        ready = [n for n in remaining if deps[n] <= set(order)]
        if not ready:
            cycle = [e.label() for e in edges if e.dst in remaining and e.src in remaining and not e.delay]
            raise WiringError("cycle without a delayed edge (mark one edge delay: 1): " + "; ".join(cycle))
        order.append(ready[0])
        remaining.remove(ready[0])
    return order


def connection_table(scenario: Scenario, wiring: Wiring) -> str:
    """Printable wiring: one row per input signal, then the step order and unused outputs."""
    rows = [("signal", "from", "shape", "unit", "delay")]
    for comp in wiring.order:
        for edge in wiring.edges_into(comp):
            port = next(p for p in wiring.inputs[comp] if p.name == edge.dst_port)
            rows.append((f"{comp}.{edge.dst_port}", f"{edge.src}.{edge.src_port}",
                         str(port.shape), port.unit, str(edge.delay)))
    widths = [max(len(r[i]) for r in rows) for i in range(5)]
    lines = [f"scenario {scenario.name}: {len(wiring.order)} components, dt {scenario.dt_s * 1e3:g} ms, "
             + (f"{scenario.n_steps} steps" if scenario.n_steps is not None else "until stopped")]
    for i, row in enumerate(rows):
        lines.append("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip())
        if i == 0:
            lines.append("  ".join("-" * w for w in widths))
    lines.append("")
    lines.append("step order: " + " -> ".join(
        f"{c}" + (f" (every {wiring.periods[c]} steps)" if wiring.periods[c] > 1 else "") for c in wiring.order))
    unused = wiring.unused_outputs()
    lines.append("unused outputs: " + (", ".join(unused) if unused else "none"))
    return "\n".join(lines)

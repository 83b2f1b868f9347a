"""Reading a component's parameters: defaults, types, bounds, clear errors.

Components declare their parameters as a mapping ``name -> Param`` and call
:func:`read_params`; an unknown name, a wrong type or a value out of bounds
raises :class:`~cosim.contract.component.ComponentError` naming the parameter.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from cosim.contract.errors import ComponentError

#: Parameters every component receives from the scheduler.
CONTEXT_KEYS = ("dt", "path", "run_dir", "recording_id", "name")


@dataclass(frozen=True)
class Param:
    """One component parameter: its default (whose type the value must have), what it is, and bounds for a number."""
    default: Any
    doc: str = ""
    lo: float | None = None
    hi: float | None = None


class Profile(dict):
    """A profile's values, ``{plugin name: {param: value}}``, with ``doc``: what it stands for (one
    sentence first, as ``cosim plugins`` lists it)."""

    def __init__(self, values: Mapping[str, Mapping[str, Any]], doc: str = ""):
        super().__init__(values)
        self.doc = doc


#: The profile every scenario runs on unless it names another: no values of its own.
IDEAL = Profile({}, "every component with the parameters its scenario gives, none changed "
                    "(the default; an emulation without the rig's imperfections)")


def read_params(given: Mapping[str, Any], spec: Mapping[str, Param]) -> dict[str, Any]:
    """``spec`` defaults overridden by ``given``; numbers checked against bounds."""
    unknown = sorted(set(given) - set(spec) - set(CONTEXT_KEYS))
    if unknown:
        raise ComponentError(f"unknown parameter(s) {', '.join(unknown)}; valid: {', '.join(sorted(spec))}")
    out = {k: p.default for k, p in spec.items()}
    for key, value in given.items():
        if key not in spec:
            continue
        default = spec[key].default
        if isinstance(default, bool):
            if not isinstance(value, bool):
                raise ComponentError(f"parameter {key}={value!r}: expected true or false")
        elif isinstance(default, (int, float)):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ComponentError(f"parameter {key}={value!r}: expected a number")
            lo, hi = spec[key].lo, spec[key].hi
            if (lo is not None and value < lo) or (hi is not None and value > hi):
                raise ComponentError(f"parameter {key}={value!r} out of range [{lo}, {hi}]")
            value = float(value) if isinstance(default, float) else value
        out[key] = value
    return out


def whole_ticks(value_s: float, dt_s: float, name: str) -> int:
    """``value_s`` [s] in steps of ``dt_s`` [s]; a value off the step grid raises
    :class:`~cosim.contract.component.ComponentError` naming the parameter ``name``."""
    n = value_s / dt_s
    if abs(n - round(n)) > 1e-6:
        raise ComponentError(f"{name}={value_s} s is not a multiple of the step dt={dt_s} s")
    return int(round(n))

"""``twin.effect``: apply force effects to the plant FMU from the plant's state and the command.

Each step it evaluates the effects (see :mod:`.sources`: library effects by name, a
user's effect file loaded through the scenario's ``plugins``, or every force effect
of a saved model) at the plant's position and velocity and the controller's command,
and outputs the force for the plant component ``plant.fmu_forced``, which adds it to
the swimmer's forces inside its integration. Units: the ports are SI (m, m/s, rad/s,
N); the effects are evaluated in mm, mm/s, Hz and uN and converted at this edge
(:mod:`.units`).

Coupling (``coupling``): ``"held"`` sends the force at the step's start, held over the
co-simulation step; ``"linear"`` (default) also sends its derivatives with respect to
the position and the velocity, so the FMU evaluates the force's linear part at each of
its internal steps (a drag that depends on the velocity follows the velocity within
the step instead of lagging one step). Wire the plant's inputs with ``delay: 1``: the
force computed at t acts over [t, t + dt), as the coil command does.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from cosim import Component, Port
from cosim.contract.component import ComponentError
from cosim.contract.errors import UserError
from cosim.contract.params import Param, read_params

COUPLINGS = ("linear", "held")

PARAMS = {
    "effects": Param([], "effect names (the library's, or a user's effect file listed in the scenario's plugins); "
                         "with model: only these of the model's force effects"),
    "model": Param("", "a saved physical model (.npz): apply all its force effects with their fitted parameters "
                       "and its k, Cd0, Cd1... (code it carries runs only with --trust-model-code)"),
    "effect_params": Param({}, "effect parameters by effect, e.g. {background_flow: {w_x: 2.0}} [the effect's "
                               "units]; override the model's or the effect's initial values"),
    "host": Param({}, "host model parameters the effects reuse (k [uN/Hz], Cd0, Cd1, Cl0 [uN s/mm], Fvs, Fmax "
                      "[uN]); default: the model's, else those the FMU's default parameters imply"),
    "plant_params": Param({}, "FMU parameters of the plant (by FMI name, e.g. drag_axial) from which the default "
                              "host parameters are derived, when they differ from the FMU's defaults"),
    "coupling": Param("linear", "'linear': force and its derivatives in p and v, evaluated at the FMU's internal "
                                "steps; 'held': the force at the step's start, held over the step"),
}


def _read(params: Mapping[str, Any]) -> dict:
    p = read_params(params, PARAMS)
    if isinstance(p["effects"], str):
        p["effects"] = [n.strip() for n in p["effects"].split(",") if n.strip()]
    if not isinstance(p["effects"], list) or not all(isinstance(n, str) for n in p["effects"]):
        raise ComponentError(f"parameter effects={p['effects']!r}: expected a list of effect names")
    p["effect_params"] = _qualified(p["effect_params"])
    for key in ("host", "plant_params"):
        if not isinstance(p[key], Mapping) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in p[key].values()):
            raise ComponentError(f"parameter {key}={p[key]!r}: expected a mapping of names to numbers")
    if p["coupling"] not in COUPLINGS:
        raise ComponentError(f"parameter coupling={p['coupling']!r}: expected one of {', '.join(COUPLINGS)}")
    if not p["effects"] and not p["model"]:
        raise ComponentError("give the effects to apply: effects (names) or model (a saved physical model)")
    return p


def _qualified(nested) -> dict:
    """``{effect: {param: value}}`` -> ``{"effect.param": value}``; anything else raises a ComponentError."""
    if not isinstance(nested, Mapping):
        raise ComponentError(f"parameter effect_params={nested!r}: expected {{effect: {{param: value}}}}")
    out = {}
    for effect, values in nested.items():
        if not isinstance(values, Mapping):
            raise ComponentError(f"parameter effect_params.{effect}={values!r}: expected {{param: value}}")
        for name, value in values.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ComponentError(f"parameter effect_params.{effect}.{name}={value!r}: expected a number")
            out[f"{effect}.{name}"] = float(value)
    return out


def build_applied(p: Mapping[str, Any]):
    """The :class:`~.applied.AppliedEffects` that read parameters ``p`` (as :func:`_read` returns) describe."""
    from cosim_plugins.twin.applied import AppliedEffects
    from cosim_plugins.twin.sources import effects_by_name, effects_of_model
    from cosim_plugins.twin.units import HOST_UNITS, fmu_defaults, host_params_from_fmu

    try:
        src = effects_of_model(p["model"], p["effects"]) if p["model"] else effects_by_name(p["effects"])
        unknown = sorted(set(p["host"]) - set(HOST_UNITS))
        if unknown:
            raise UserError(f"host: unknown parameter(s) {', '.join(unknown)}; valid: {', '.join(HOST_UNITS)}")
        bad = sorted(set(p["plant_params"]) - set(fmu_defaults()))
        if bad:
            raise UserError(f"plant_params: {', '.join(bad)} are not parameters of the plant FMU")
        host = {**(src.host or host_params_from_fmu(p["plant_params"])), **p["host"]}
        return AppliedEffects(src.effects, {**src.values, **p["effect_params"]}, host)
    except UserError as exc:
        raise ComponentError(str(exc)) from exc


class EffectInjector(Component):
    """Force effects applied to the plant FMU through its external force input; see the module docstring."""

    inputs = (
        Port("position", (3,), "m", "the plant's position (wire from the plant, no delay)"),
        Port("velocity", (3,), "m/s", "the plant's velocity (wire from the plant, no delay)"),
        Port("omega", (3,), "rad/s", "the command the plant follows over the next step (the controller's)"),
    )
    outputs = (
        Port("force", (3,), "N", "the effects' force at the plant's state, tank frame"),
        Port("force_dp", (9,), "N/m", "dF_a/dp_b, row-major (a, b); zero with coupling: held"),
        Port("force_dv", (9,), "N s/m", "dF_a/dv_b, row-major (a, b); zero with coupling: held"),
    )
    params_spec = PARAMS

    @classmethod
    def validate_params(cls, params: Mapping[str, Any]) -> None:
        build_applied(_read(params))

    @classmethod
    def artifacts(cls, params: Mapping[str, Any]) -> list:
        model = _read(params)["model"]
        return [model] if model else []

    def setup(self, params: Mapping[str, Any], rng: np.random.Generator) -> None:
        p = _read(params)
        self.applied = build_applied(p)
        self.linear = p["coupling"] == "linear"
        self._zero9 = np.zeros(9)

    def step(self, t: float, inputs: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        p, v, w = (np.asarray(inputs[k], dtype=float) for k in ("position", "velocity", "omega"))
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(v)) and np.all(np.isfinite(w))):
            raise ComponentError(f"t={t:g} s: non-finite plant state or command (position {p}, velocity {v}, "
                                 f"omega {w})")
        f, dfdp, dfdv = self.applied.force_si(p, v, w)
        if not np.all(np.isfinite(f)):
            raise ComponentError(f"t={t:g} s: the effects returned a non-finite force {f} [N]")
        if not self.linear:
            return {"force": f, "force_dp": self._zero9, "force_dv": self._zero9}
        return {"force": f, "force_dp": dfdp.reshape(9), "force_dv": dfdv.reshape(9)}



#: The command [rad/s] the effects see along the plant's axis when the controller commands none: the axis
#: must keep a direction for an axis-dependent law (fmu_laws), and an effect of the command's size sees ~0.
AXIS_ONLY_RAD_S = 1e-9
AXIS_AT = ("midpoint", "start")
AXIS_PARAMS = {"axis_at": Param("midpoint", "the plant's axis the effects see over a step: 'midpoint' (extrapolated "
                                            "by half its last step's turn), 'start' (at the step's start)")}


class EffectOnPlantAxis(EffectInjector):
    """``twin.effect_on_axis``: :class:`EffectInjector` whose effects see the command turned onto the plant's
    real long axis, u = s |omega| a (a the plant's axis, s the sign of a . omega; a zero omega gives
    ``AXIS_ONLY_RAD_S`` a). For laws that act through the body's axis (the FMU's anisotropic drag,
    :mod:`.fmu_laws`) when the axis lags the command (the FMU's heading dynamics on); the command's size
    is kept, its direction is the body's.

    The axis turns within the step (the FMU integrates at 1 ms), and the force's coefficients sent to the
    FMU cannot follow it; ``axis_at: midpoint`` (default) evaluates the effects at the axis half a step on,
    extrapolated from the axis's turn over the last step, a_mid = (a + (a - a_prev) / 2) / |...| (the
    first step: a), which removes most of that lag (docs/twin.md); ``start`` at the axis at the step's
    start. Wire ``axis`` from ``plant.axis`` with no delay."""

    inputs = (*EffectInjector.inputs,
              Port("axis", (3,), "1", "the plant's long axis, unit vector (wire from plant.axis, no delay)"))
    params_spec = {**PARAMS, **AXIS_PARAMS}

    @staticmethod
    def _split(params: Mapping[str, Any]) -> tuple[dict, str]:
        """(the base component's params, axis_at); a bad axis_at raises a ComponentError."""
        axis_at = read_params({k: v for k, v in params.items() if k in AXIS_PARAMS}, AXIS_PARAMS)["axis_at"]
        if axis_at not in AXIS_AT:
            raise ComponentError(f"parameter axis_at={axis_at!r}: expected one of {', '.join(AXIS_AT)}")
        return {k: v for k, v in params.items() if k not in AXIS_PARAMS}, axis_at

    @classmethod
    def validate_params(cls, params: Mapping[str, Any]) -> None:
        base, _ = cls._split(params)
        super().validate_params(base)

    @classmethod
    def artifacts(cls, params: Mapping[str, Any]) -> list:
        return super().artifacts(cls._split(params)[0])

    def setup(self, params: Mapping[str, Any], rng: np.random.Generator) -> None:
        base, self.axis_at = self._split(params)
        super().setup(base, rng)
        self._prev: np.ndarray | None = None

    def step(self, t: float, inputs: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        a, w = np.asarray(inputs["axis"], dtype=float), np.asarray(inputs["omega"], dtype=float)
        size = float(np.sqrt(a @ a))
        if not (np.isfinite(size) and abs(size - 1.0) < 1e-6):
            raise ComponentError(f"t={t:g} s: the plant's axis {a} is not a unit vector")
        seen = a
        if self.axis_at == "midpoint" and self._prev is not None:
            ahead = a + 0.5 * (a - self._prev)
            seen = ahead / np.sqrt(ahead @ ahead)
        self._prev = a.copy()
        sign = -1.0 if float(seen @ w) < 0.0 else 1.0
        return super().step(t, {**inputs, "omega": sign * max(float(np.sqrt(w @ w)), AXIS_ONLY_RAD_S) * seen})

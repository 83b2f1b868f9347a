"""The plant FMU's own laws of its built-in wall drag and background flow, as force effects.

The library's ``wall_drag`` (a 1/d law) and ``background_flow`` (the host model's drag
and lift on the velocity relative to the water) are the host model's forms, not the
FMU's (``plant.c``: ``wall_factor`` and ``derivatives``). These two effects are the
FMU's laws, so that ``twin.effect`` can inject exactly what the FMU's switches
``wall_drag_on`` and ``background_flow_on`` add:

``fmu_wall_drag``
    -(fw - 1) D(a) v, with fw - 1 = gain sum over the six walls of exp(-gap_k / length),
    gap_k = max(half - margin -+ p_k, 0) [mm], the FMU's wall factor less its 1;
``fmu_background_flow``
    +D(a) w, w = (w_x, w_y, w_z) [mm/s]: the FMU's drag -D(a) (v - w) less its -D(a) v;

D(a) = c_ax a a^T + c_perp (1 - a a^T) the FMU's drag tensor about the long axis a,
c_ax = ``drag_axial``, c_perp = ``anisotropy_ratio`` c_ax (ratio 1: isotropic, as
with ``anisotropic_drag_on`` false). The axis is the direction of the command u
(the effect contract gives p, v and u only); with ``twin.effect_on_axis`` u is
turned onto the plant's real axis (``plant.axis``), which lags the command when
the FMU's heading dynamics are on. A zero u leaves the axis unknown: the drag is
then c_ax (isotropic). With both switches on, the FMU also multiplies the flow's
drag by the wall factor; the two effects together lack that cross term.

Units: p [mm], v [mm/s], u [Hz], drag [uN s/mm], force [uN]. Not in the effect
library (a diagnosis never ranks them): :func:`twin_effects` is what
``twin.effect`` resolves names against besides the library's.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from cosim_plugins.identify.effect import Effect, EffectParam
from cosim_plugins.twin.units import MM_PER_M, N_PER_UN_PER_MM, fmu_defaults

WALL_DRAG = "fmu_wall_drag"
BACKGROUND_FLOW = "fmu_background_flow"


def drag_tensor_times(u: np.ndarray, x: np.ndarray, c_ax: float, ratio: float) -> np.ndarray:
    """D(a) x [uN] for rows x (n, 3) [mm/s], a = u / |u| from u (n, 3) [Hz] (a zero row: isotropic c_ax);
    c_ax [uN s/mm] along a, ratio c_ax across it."""
    u, x = np.asarray(u, dtype=float), np.asarray(x, dtype=float)
    n = np.sqrt(np.sum(u * u, axis=1))[:, None]
    a = np.where(n > 0.0, u / np.where(n > 0.0, n, 1.0), 0.0)
    along = np.sum(a * x, axis=1)[:, None] * a
    return c_ax * along + ratio * c_ax * (x - along)


def wall_sum(p_mm: np.ndarray, half_mm: float, margin_mm: float, length_mm: float) -> np.ndarray:
    """(n,) sum over the six walls of exp(-gap / length), gap = max(half - margin -+ p_k, 0) [mm], at p (n, 3)
    [mm]: the FMU's wall factor less 1, over its gain."""
    lim = half_mm - margin_mm
    p = np.asarray(p_mm, dtype=float)
    return (np.exp(-np.maximum(lim - p, 0.0) / length_mm) + np.exp(-np.maximum(lim + p, 0.0) / length_mm)).sum(axis=1)


def _wall_drag(p, v, u, prm):
    extra = prm["gain"] * wall_sum(p, prm["half"], prm["margin"], prm["length"])
    return -extra[:, None] * drag_tensor_times(u, v, prm["drag_axial"], prm["anisotropy_ratio"])


def _background_flow(p, v, u, prm):
    w = np.broadcast_to(np.array([prm["w_x"], prm["w_y"], prm["w_z"]]), np.shape(v))
    return drag_tensor_times(u, w, prm["drag_axial"], prm["anisotropy_ratio"])


def fmu_law_values(fmu_params: Mapping[str, float] | None = None) -> dict[str, float]:
    """The FMU parameters the two laws read, in the effects' units (mm, uN s/mm), at the FMU's defaults
    overridden by ``fmu_params`` (by FMI name, SI). ``anisotropy_ratio`` is 1 when ``anisotropic_drag_on`` is 0."""
    p = {**fmu_defaults(), **(fmu_params or {})}
    return {"drag_axial": p["drag_axial"] / N_PER_UN_PER_MM,
            "anisotropy_ratio": p["anisotropy_ratio"] if p["anisotropic_drag_on"] else 1.0,
            "gain": p["wall_drag_gain"], "length": p["wall_drag_length"] * MM_PER_M,
            "margin": p["wall_margin"] * MM_PER_M, "half": p["tank_half"] * MM_PER_M,
            "w_x": p["flow_x"] * MM_PER_M, "w_y": p["flow_y"] * MM_PER_M, "w_z": p["flow_z"] * MM_PER_M}


def effect_params(fmu_params: Mapping[str, float] | None = None) -> dict[str, dict[str, float]]:
    """``twin.effect``'s ``effect_params`` that make both effects the FMU's laws at these FMU parameters
    (by FMI name, SI; default the FMU's defaults): ``{fmu_wall_drag: {...}, fmu_background_flow: {...}}``."""
    v = fmu_law_values(fmu_params)
    drag = {k: v[k] for k in ("drag_axial", "anisotropy_ratio")}
    return {WALL_DRAG: {**drag, **{k: v[k] for k in ("gain", "length", "margin", "half")}},
            BACKGROUND_FLOW: {**drag, **{k: v[k] for k in ("w_x", "w_y", "w_z")}}}


def _drag_params(v: Mapping[str, float]) -> tuple[EffectParam, ...]:
    return (EffectParam("drag_axial", v["drag_axial"], 0.0, 10.0, "uN s/mm", 0.01),
            EffectParam("anisotropy_ratio", v["anisotropy_ratio"], 0.1, 10.0, "1", 0.1))


def twin_effects() -> dict[str, Effect]:
    """The FMU-law effects by name, their parameters starting at the FMU's defaults."""
    v = fmu_law_values()
    wall = Effect(
        name=WALL_DRAG,
        params=(EffectParam("gain", v["gain"], 0.0, 100.0, "1", 0.1),
                EffectParam("length", v["length"], 0.01, 100.0, "mm", 0.5),
                EffectParam("margin", v["margin"], 0.0, 50.0, "mm", 0.5),
                EffectParam("half", v["half"], 1.0, 1000.0, "mm", 1.0), *_drag_params(v)),
        force=_wall_drag,
        doc="The plant FMU's wall drag: -(gain sum_walls exp(-gap / length)) D(a) v, gap = the distance to each of "
            "the six walls less margin [mm], D(a) the FMU's drag tensor about the axis a (u's direction) [uN].")
    flow = Effect(
        name=BACKGROUND_FLOW,
        params=(EffectParam("w_x", v["w_x"], -50.0, 50.0, "mm/s", 1.0),
                EffectParam("w_y", v["w_y"], -50.0, 50.0, "mm/s", 1.0),
                EffectParam("w_z", v["w_z"], -50.0, 50.0, "mm/s", 1.0), *_drag_params(v)),
        force=_background_flow,
        doc="The plant FMU's background flow: +D(a) w through its anisotropic drag tensor D(a) about the axis a "
            "(u's direction), w = (w_x, w_y, w_z) [mm/s] [uN].")
    return {wall.name: wall, flow.name: flow}

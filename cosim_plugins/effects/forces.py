"""Force effects: extra forces [uN] added to the physical model and fitted jointly.

Arguments of every force: p (n, 3) position [mm], v (n, 3) velocity [mm/s],
u (n, 3) command omega [Hz], ``params`` (the effect's parameters by short
name plus the host model's: ``k`` [uN/Hz], ``Cd0``, ``Cd1`` [uN s/mm]...).
Returns (n, 3) [uN]. The tank is a cube of half-size :data:`TANK_HALF_MM`
centred at the origin (the paper's 150 mm tank).
"""

from __future__ import annotations

import math

import numpy as np

from cosim.contract.errors import UserError
from cosim_plugins.identify.effect import Effect, EffectParam
from cosim_plugins.models.physical import flow_force

#: Half the tank's edge [mm]: walls at +-75 mm on every axis.
TANK_HALF_MM = 75.0


# The forces run at every step of every rollout, mostly on a few hundred rows: few numpy calls, not einsum.


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n,) row-wise dot products of a and b (n, 3)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def _norm(a: np.ndarray) -> np.ndarray:
    """(n, 1) Euclidean norms of the rows of a (n, 3)."""
    return np.sqrt(_dot(a, a))[:, None]


def _safe(n: np.ndarray) -> np.ndarray:
    """Norms n with those <= 1e-12 replaced by 1 (a divisor that leaves a zero row zero)."""
    return np.where(n > 1e-12, n, 1.0)


def _unit(a: np.ndarray) -> np.ndarray:
    """Rows of a (n, 3) normalised; zero rows stay zero."""
    return a / _safe(_norm(a))


def through_water(v: np.ndarray, prm, p: np.ndarray | None = None) -> np.ndarray:
    """(n, 3) velocity [mm/s] relative to the water: v (n, 3) less the water's velocity that the flows in the
    model set: a uniform one (``prm["water_x"]``, ``prm["water_y"]``) and one varying with position at p (n, 3)
    [mm] (``prm["water_at"]``: a discovered shear or swirl); still water without a flow. Every drag acts on it."""
    if "water_x" in prm:
        v = v - np.array([prm["water_x"], prm["water_y"], 0.0])
    if "water_at" in prm:
        if p is None:
            raise UserError("a flow in the model varies with position: a drag's through_water(v, params, p) needs "
                            "the position p")
        v = v - prm["water_at"](p)
    return v


def wall_distance_mm(p: np.ndarray) -> np.ndarray:
    """(n,) distance from p (n, 3) [mm] to the nearest tank wall [mm], >= 0."""
    return np.maximum(TANK_HALF_MM - np.max(np.abs(p), axis=1), 0.0)


# ---------------------------------------------------------------- background flow


def _background_flow(p, v, u, prm):
    return flow_force(v, np.array([prm["w_x"], prm["w_y"], 0.0]), u, prm)


BACKGROUND_FLOW = Effect(
    name="background_flow",
    params=(EffectParam("w_x", 0.0, -50.0, 50.0, "mm/s", 1.0), EffectParam("w_y", 0.0, -50.0, 50.0, "mm/s", 1.0)),
    force=_background_flow,
    water=("w_x", "w_y"),
    doc="A uniform drift of the water (residual circulation, a slow pump): drag and lift act on the velocity "
        "relative to the water, so the extra force is H(v - w) - H(v), H the model's own drag and lift (Eq. 2-5: "
        "-(Cd0 sin(alpha) + Cd1) v + Cl0 sin(2 alpha) |v| v_perp, alpha taken against the relative velocity). "
        "w = (w_x, w_y, 0) [mm/s]; a vertical drift is not fitted because it is indistinguishable from the "
        "net weight F_vs already in the model. The extra drags of a model that holds it (wall, anisotropic, "
        "quadratic) act on the velocity relative to the water too.",
)


# ---------------------------------------------------------------- wall drag


def _wall_drag(p, v, u, prm):
    ell = prm["ell"]
    gain = ell / (wall_distance_mm(p) + ell)
    return -(prm["c"] * gain)[:, None] * through_water(v, prm, p)


WALL_DRAG = Effect(
    name="wall_drag",
    params=(EffectParam("c", 0.0, 0.0, 5.0, "uN s/mm", 0.05), EffectParam("ell", 5.0, 0.5, 40.0, "mm", 5.0)),
    force=_wall_drag,
    doc="Extra drag near a wall (lubrication and image-flow effects; Faxen and Brenner give a drag rise "
        "~ a/h at a distance h from a plane wall): -c ell / (d + ell) v with d the distance from the "
        "centre to the nearest wall of the 150 mm tank [mm], so the drag grows as 1/d away from the wall "
        "and saturates at c [uN s/mm] at contact; ell [mm] is the fitted length scale. v is the velocity "
        "through the water (relative to a background_flow's).",
    starts=({"c": 0.05, "ell": 2.0}, {"c": 0.05, "ell": 8.0}, {"c": 0.05, "ell": 25.0}),
)


# ---------------------------------------------------------------- step-out


def _step_out(p, v, u, prm):
    f = _norm(u)
    fso = prm["f_so"]
    slip = np.sqrt(np.maximum(f * f - fso * fso, 0.0))  # the mean spin is f - slip (Adler)
    return (-prm.get("k", 0.0) * slip / _safe(f)) * u


def _step_out_starts(u, dt_s):
    """f_so spread over the commanded band: percentiles of |u| [Hz] from the 20th to the 95th, closer together at
    the top. Just below the band's top only the fastest commands slip, and the slip sqrt(f^2 - f_so^2) grows
    steeply there: a start 1 Hz off lets the brief refinement of the start trade the thrust against the drag
    instead (a step-out at 15.5 Hz in a 4-17 Hz band was missed with starts at the 70th and 95th only)."""
    f = np.linalg.norm(u[np.all(np.isfinite(u), axis=1)], axis=1)
    f = f[f > 0.05]
    if len(f) < 10:
        return []
    return [{"f_so": float(q)} for q in np.percentile(f, [20, 45, 70, 80, 88, 95])]


STEP_OUT = Effect(
    name="step_out",
    params=(EffectParam("f_so", 100.0, 1.0, 100.0, "Hz", 5.0),),
    force=_step_out,
    doc="Step-out: above f_so = m B / (2 pi c_rot) the magnet cannot follow the field and slips; its mean "
        "spin is f - sqrt(f^2 - f_so^2) instead of f, so the propulsion k omega loses "
        "-k sqrt(|u|^2 - f_so^2) u_hat. f_so [Hz] is fitted (100 Hz = never steps out).",
    starts=({"f_so": 30.0},),
    data_starts=_step_out_starts,
)


# ---------------------------------------------------------------- gradient force

_PAIR = ("b_x", "b_y", "b_z")
#: Phases of the field over half a turn at which m grad|B| is averaged when the field's curvature counts
#: (F(t + pi) = F(t)); 8 are within 2e-6 of 64 where |B| changes by 64 % at 40 mm from the centre, 0.2 % at 160 %.
GRADIENT_PHASES = 8


def _gradient_force(p, v, u, prm):
    f = _norm(u)
    a = u / _safe(f)
    b = np.array([prm[n] for n in _PAIR])
    curv = prm.get("curv", 0.0)  # a model saved before the curvature was a parameter: the near-centre law
    if curv == 0.0:
        return (f > 0.05) * _gradient_near_centre(p, a, b)  # the field is on when a spin is commanded
    return (f > 0.05) * _gradient_curved(p, a, b, curv)


def _gradient_near_centre(p, a, b):
    """(n, 3) [uN]: the turn-averaged force to first order in the pairs' curvature (|B| ~ 1 there)."""
    # pair k: (1 - a_k^2) b_k (2 x_k e_k - x_j e_j - x_l e_l); with s_k = (1 - a_k^2) b_k the force along i is
    # x_i (2 s_i - (s_j + s_l)) = x_i (3 s_i - sum(s))
    s = (1.0 - a * a) * b
    pair = p * (3.0 * s - s.sum(axis=1, keepdims=True))
    # pairs j, k together: a_j a_k (b_j + b_k) (x_k e_j + x_j e_k); along i, a_i sum_{k != i} (b_i + b_k) q_k with
    # q = a x, which is a_i (b_i (sum(q) - 2 q_i) + sum(b q))
    q = a * p
    t = b * (q.sum(axis=1, keepdims=True) - 2.0 * q) + (q * b).sum(axis=1, keepdims=True)
    return pair + a * t


def _gradient_curved(p, a, b, curv):
    """(n, 3) [uN]: m grad|B| averaged over the turn, |B| as it is: far from the centre the field's strength
    changes by a share comparable to one, and the force is no longer linear in position.

    Pair k's field per unit centre field is B_k = e_k + beta_k g_k with g_k = e_k (2.5 x_k^2 - |x|^2 / 2) - x_k x
    (axisymmetric, curl- and divergence-free to second order); with the unit current c = cos(t) e1 + sin(t) e2
    (e1, e2 normal to the rotation axis a) and m B0 beta_k = 2 b_k (averaged over the turn, c c^T is half the
    projection off a: the near-centre law's b is half m B0 beta), B = c + curv G, G = sum_k 2 c_k b_k g_k
    [uN mm], curv = 1 / (m B0). The field's gradient J is symmetric and linear in the beta_k: the force
    m B0 J B / |B| is J(2 c b) B / |B|, J(w) B = 5 w B x - x (w . B) - w (x . B) - B (w . x) [uN]."""
    ref = np.where(np.abs(a[:, 2:3]) < 0.9, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    e1 = _unit(ref - _dot(ref, a)[:, None] * a)
    e2 = np.cross(a, e1)
    th = (np.arange(GRADIENT_PHASES) + 0.5) * (np.pi / GRADIENT_PHASES)
    c = np.cos(th)[:, None, None] * e1 + np.sin(th)[:, None, None] * e2  # (phases, n, 3)
    cb = 2.0 * c * b
    cbx = (cb * p).sum(axis=2, keepdims=True)
    field = c + curv * (cb * (2.5 * p * p - 0.5 * (p * p).sum(axis=1, keepdims=True)) - p * cbx)
    jb = (5.0 * cb * field * p - p * (cb * field).sum(axis=2, keepdims=True)
          - cb * (p * field).sum(axis=2, keepdims=True) - field * cbx)
    return (jb / np.sqrt((field * field).sum(axis=2, keepdims=True))).mean(axis=0)


GRADIENT_FORCE = Effect(
    name="gradient_force",
    params=(*(EffectParam(n, 0.0, -1.0, 1.0, "uN/mm", 3e-3) for n in _PAIR),
            EffectParam("curv", 0.0, 0.0, 1.0, "1/(uN mm)", 1e-2)),
    force=_gradient_force,
    doc="The magnetic gradient force (m . grad) B of three orthogonal coil pairs: a magnet locked to the "
        "rotating field feels, averaged over a turn, m grad |B|. "
        "Pair k's field is axisymmetric (Laplace), so |B_k| ~ 1 + beta_k (x_k^2 - r^2 / 2) near the centre; a "
        "field rotating about u_hat gives pair k the share 1 - u_k^2 and pairs j, k together the cross term "
        "u_j u_k: near the centre F = sum_k (1 - u_k^2) b_k (2 x_k e_k - x_j e_j - x_l e_l) + sum_{j<k} u_j u_k "
        "(b_j + b_k) (x_k e_j + x_j e_k), b [uN/mm] one gradient per pair, while the field is on (|u| > 0.05 "
        "Hz). The cross terms' b_j + b_k is no free coefficient: fitted free to the plant FMU's coil fields "
        "(three pairs at different spacings, turn-averaged m grad|B| near the centre) they come out that sum. "
        "Farther out the field's strength changes by a share comparable to one (coils of 100 mm radius: tens "
        "of per cent at 40 mm) and the force bends away from that line: curv = 1 / (m B0) [1/(uN mm)] sets the "
        "pairs' curvature m B0 beta_k = 2 b_k, and the force is then m grad|B| averaged over the turn as it is "
        "(the line again at curv = 0).",
)


# ---------------------------------------------------------------- anisotropic drag


def _anisotropic_drag(p, v, u, prm):
    a = _unit(u)
    vr = through_water(v, prm, p)
    v_perp = vr - _dot(vr, a)[:, None] * a
    return -prm["c"] * v_perp


ANISOTROPIC_DRAG = Effect(
    name="anisotropic_drag",
    params=(EffectParam("c", 0.0, 0.0, 2.0, "uN s/mm", 0.02),),
    force=_anisotropic_drag,
    doc="Anisotropic drag of an elongated body: moving broadside costs more than moving along its axis "
        "(slender-body ratio up to 2). With the long axis along the command u, the extra force is "
        "-c (v - (v . u_hat) u_hat), c [uN s/mm]. For small angles of attack the paper's lift "
        "Cl0 sin(2 alpha) |v| v_perp is the same force with c = 2 Cl0, so the model absorbs most of it: only "
        "broadside motion (sinking across the axis, sharp turns) tells the two apart. c >= 0: a body cheaper to "
        "move broadside than along its axis is not this effect (a lift of either sign is the model's Cl0). v is "
        "the velocity through the water (relative to a background_flow's).",
)


# ---------------------------------------------------------------- quadratic drag


def _quadratic_drag(p, v, u, prm):
    vr = through_water(v, prm, p)
    return -prm["c"] * _norm(vr) * vr


QUADRATIC_DRAG = Effect(
    name="quadratic_drag",
    params=(EffectParam("c", 0.0, 0.0, math.inf, "uN s^2/mm^2", 2e-3),),
    force=_quadratic_drag,
    doc="Form drag at Reynolds numbers of 25-300: -c |v| v with c = rho Cd A / 2 [uN s^2/mm^2] "
        "(water, Cd ~ 1, A ~ 5-15 mm^2 gives 2.5e-3-7.5e-3), on top of the model's linear drag; v is the "
        "velocity through the water (relative to a background_flow's).",
    # from c = 0, at its bound, a fit whose linear drag already took the slowing stays there: starts spread over
    # the form-drag range (x4 apart), each held while the model's drag adapts to it
    starts=({"c": 1e-3}, {"c": 4e-3}, {"c": 1.6e-2}),
)

FORCE_EFFECTS = (BACKGROUND_FLOW, WALL_DRAG, STEP_OUT, GRADIENT_FORCE, ANISOTROPIC_DRAG, QUADRATIC_DRAG)

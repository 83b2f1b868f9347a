"""Blind bench simulator: an independent swimmer plant, closed loop and camera, with hidden effects.

It judges ``cosim diagnose`` on logs from code that shares nothing with it:
only numpy and the standard library are imported (the word ``cosim`` below
appears only inside the generated effect-file sources).

Plant (paper Sec. II-A, Eq. 1-7, in continuous time; units mm, mm/s, Hz, uN,
s; m = 12.4 mg, so a [mm/s^2] = 1000 F [uN] / m [mg]): thrust k omega along
the spin axis; drag -(Cd0 sin(alpha) + Cd1) v_r and lift Cl0 sin(2 alpha)
|v_r| v_perp on the velocity v_r relative to the water (v_perp: the unit
normal to v_r in the (axis, v_r) plane, towards the axis); net weight
Fvs z_hat; Fmax sin(pi |p| / |P_b|) (-p_hat), P_b = [70, 70, 70] mm. The tank
is a cube with walls at +-75 mm, origin at its centre, z up; the swimmer is
stopped at +-73.75 mm (rare).

Integration: a control period is split into M substeps of ~2 ms. On each
substep the drag rate lambda = 1000 Cd / m and the other acceleration a are
held at the substep's midpoint state, and v' = -lambda v + a, p' = v is
solved exactly (exponential integrator, stable for any drag). The period is
iterated to a fixed point (Picard; 1-3 passes, all substeps and logs at
once), so the scheme is second order: replaying a log's commands, positions
agree with a 16x finer, fully converged run to ~1e-3 mm over 1 s. Effect
states (field lag, body axis, magnet phase) follow their exact solutions for
the piecewise-constant command. Forces that depend on position only and vary
slowly (Eq. 6, the gradient force) are held at the period's predicted
midpoint.

Closed loop: pure pursuit on the last usable measured position (look-ahead
5-12 mm along the path); spin rate from a piecewise-constant random schedule
in the case's band; command noise (part of the logged command). Camera: one
noisy position per period, lost detections, reflections.

Hidden effects: nine from the project's library (:data:`LIBRARY`), four
outside it (:data:`OUTSIDE`), or none (:func:`draw_cases`); two at once
(:func:`draw_multi_cases`: two library effects, or one library and one
outside); or one of the look-alike family (:data:`LOOKALIKE`) in regimes
where its members mimic each other (:func:`draw_lookalike_cases`); or nothing
hidden while a parameter of the plant (drag, thrust, net weight) drifts from
log to log or slowly within logs (:func:`draw_drift_cases`, with steady
controls, some of them with a camera that gives a frame only every few rows).
A case
holds at most one thrust-shaping effect (:data:`THRUST_SHAPING`) and at most
one water flow (:data:`FLOWS`); every drag acts on the velocity relative to
the water. Each hidden effect with a true form carries the source of an
effect file (the project's plugin contract) registering ``true_<effect>``:
the simulator's law with its parameters free and initialised at the truth.
The functions of the "Laws" section are copied verbatim into those files.

    cases = draw_cases(60, seed=1)
    files = simulate(cases[0], "out/case_00")   # out/case_00/log_00.csv, ...
    extra = simulate_experiment(cases[0], "experiment_excitation.csv", "out/case_00/experiment")

Random streams: ``draw_cases`` [seed, 0], ``draw_multi_cases`` [seed, 3],
``draw_lookalike_cases`` [seed, 5], ``draw_drift_cases`` [seed, 7]; per case: its draw [case seed, 1], the
look-alike regime [case seed, 6], the drift [case seed, 8], its logs [case seed, 2], an experiment's
log [case seed, 4].
"""

from __future__ import annotations

import inspect
import math
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np

MASS_MG = 12.4
ACC = 1000.0 / MASS_MG  # acceleration [mm/s^2] per force [uN]
TANK_HALF_MM, CLAMP_MM = 75.0, 73.75
PB_NORM_MM = 70.0 * math.sqrt(3.0)
PATH_LIMIT_MM = 62.0  # paths stay within this, except the near-wall ones (extreme at 63-71 mm)
PATH_DS_MM = 0.5  # spacing of the path polylines
SUBSTEP_S = 0.002
PICARD_TOL_MM, PICARD_MAX = 3e-4, 8  # contraction ~0.1 per pass: results ~1e-5 mm from the fixed point
GRADIENT_PHASES = 6  # quadrature points over half a turn of the field

LIBRARY = ("background_flow", "wall_drag", "step_out", "gradient_force", "anisotropic_drag",
           "quadratic_drag", "actuation_lag", "heading_lag", "sensor_latency")
OUTSIDE = ("rotating_flow", "thrust_nonuniform", "shear_flow", "periodic")
THRUST_SHAPING = ("actuation_lag", "heading_lag", "step_out")  # at most one of these per case
FLOWS = ("background_flow", "rotating_flow", "shear_flow")  # at most one of these per case
LOOKALIKE = ("actuation_lag", "sensor_latency", "heading_lag")  # mimic each other when the spin rate varies slowly
DRIFT_PARAMS = ("drag", "thrust", "weight")  # what drifts in a drift case (drag: Cd0, Cd1 and Cl0 together)
DRIFT_KINDS = ("between", "within")  # from log to log, or slowly within each log
LOOKALIKE_QUADRATIC_EVERY = 7  # draw_lookalike_cases: one case in this many hides a quadratic drag instead
EXPERIMENT_RADIUS_MM = 25.0  # simulate_experiment's circle
WALL_LAWS = ("1/d", "exp", "1/d^2")
PATH_KINDS = ("circle", "racetrack", "helix", "figure8")
HEADER = "t_ms,omega_x,omega_y,omega_z,p_x,p_y,p_z"


@dataclass
class Case:
    """One bench case; every field is JSON-able (see :func:`draw_case` for the keys of truth and regime).

    The hidden effects are ``effects`` with ``laws``, ``truths``, ``true_forms`` and ``true_form_names``
    aligned to them (empty lists for "none"). With one hidden effect (or none) ``effect``, ``law``, ``truth``,
    ``true_form`` and ``true_form_name`` are that effect's; with several, ``effect`` is their names joined by
    "+", ``law`` is "", ``truth`` is {effect: truth} and ``true_form`` / ``true_form_name`` are None.
    """

    index: int
    seed: int
    group: str  # "library" | "none" | "outside" | "multi" | "lookalike" | "drift"
    effect: str | None  # library name, outside name, None, or "a+b" (several)
    law: str  # "1/d" | "exp" | "1/d^2" (wall drag), "inside" | "top" (step-out), else ""
    truth: dict  # the effect's drawn parameters, human units
    regime: dict  # plant, camera, band, controller, logs and paths
    true_form: str | None  # effect-file source registering true_<effect>; None for "none" and "periodic"
    true_form_name: str | None
    effects: list | None = None  # every hidden effect (filled from ``effect`` when None)
    laws: list | None = None
    truths: list | None = None
    true_forms: list | None = None  # per effect: effect-file source or None
    true_form_names: list | None = None

    def __post_init__(self):
        if self.effects is None:  # one effect or none, given the single way
            one = self.effect is not None
            self.effects = [self.effect] if one else []
            self.laws = [self.law] if one else []
            self.truths = [self.truth] if one else []
            self.true_forms = [self.true_form] if one else []
            self.true_form_names = [self.true_form_name] if one else []
        sizes = {len(x) for x in (self.effects, self.laws, self.truths, self.true_forms, self.true_form_names)}
        if len(sizes) != 1:
            raise ValueError(f"case {self.index}: effects, laws, truths, true_forms and true_form_names differ "
                             "in length")
        check_compatible(self.effects)

    def hidden(self, effect: str):
        """(law, truth) of a hidden effect; KeyError when it is not hidden."""
        return dict(zip(self.effects, zip(self.laws, self.truths)))[effect]


def check_compatible(effects) -> None:
    """ValueError unless the effects are known, distinct, with at most one thrust-shaping effect and one flow."""
    unknown = [e for e in effects if e not in LIBRARY + OUTSIDE]
    if unknown:
        raise ValueError(f"unknown effect(s) {', '.join(map(str, unknown))}; known: {', '.join(LIBRARY + OUTSIDE)}")
    if len(set(effects)) != len(effects):
        raise ValueError(f"effects {'+'.join(effects)}: an effect hidden twice")
    for family, what in ((THRUST_SHAPING, "thrust-shaping effect"), (FLOWS, "flow")):
        both = [e for e in effects if e in family]
        if len(both) > 1:
            raise ValueError(f"effects {'+'.join(effects)}: at most one {what} ({', '.join(family)}) per case")


# ====================================================================== laws
# Numpy only, any leading dimensions (...); copied verbatim into the effect files.


def unit(a):
    """a (..., 3) normalised along the last axis; zero vectors stay zero."""
    return a / np.maximum(np.sqrt((a * a).sum(-1, keepdims=True)), 1e-300)


def hydro_terms(vr, axis, Cd0, Cd1, Cl0):
    """Drag coefficient (...,) [uN s/mm] and lift (..., 3) [uN] at velocity vr (..., 3) [mm/s] relative to the water.

    Cd = Cd0 sin(alpha) + Cd1, lift = Cl0 sin(2 alpha) |vr| v_perp = 2 Cl0 cos(alpha) (|vr| axis -
    cos(alpha) vr), alpha the angle between the unit spin axis (..., 3) and vr (90 deg if either is 0).
    """
    speed = np.sqrt((vr * vr).sum(-1))
    cos = (vr * axis).sum(-1) / np.maximum(speed, 1e-12)
    cd = Cd0 * np.sqrt(np.maximum(1.0 - cos * cos, 0.0)) + Cd1
    lift = (2.0 * Cl0 * cos)[..., None] * (speed[..., None] * axis - cos[..., None] * vr)
    return cd, lift


def flow_force(v, u, w, prm):
    """Change [uN] of the hydrodynamic force H(v) = -Cd v + lift when the water moves at w (..., 3) [mm/s].

    H(v - w) - H(v), with the host model's Cd0, Cd1, Cl0 from ``prm``; u (..., 3) the command [Hz].
    """
    axis = unit(u)
    cd_r, lift_r = hydro_terms(v - w, axis, prm["Cd0"], prm["Cd1"], prm["Cl0"])
    cd, lift = hydro_terms(v, axis, prm["Cd0"], prm["Cd1"], prm["Cl0"])
    return -cd_r[..., None] * (v - w) + lift_r + cd[..., None] * v - lift


def rotating_flow(p, x0, y0, omega):
    """Water velocity [mm/s] at p (..., 3) [mm]: solid-body rotation at omega [rad/s] about the vertical at (x0, y0)."""
    w = np.zeros(np.shape(p))
    w[..., 0] = -omega * (p[..., 1] - y0)
    w[..., 1] = omega * (p[..., 0] - x0)
    return w


def shear_flow(p, gamma_x, gamma_y):
    """Water velocity [mm/s] at p (..., 3) [mm]: horizontal, growing linearly with height, z (gamma_x, gamma_y, 0)."""
    w = np.zeros(np.shape(p))
    w[..., 0] = gamma_x * p[..., 2]
    w[..., 1] = gamma_y * p[..., 2]
    return w


def wall_distance(p):
    """Distance [mm] from the swimmer's centre p (..., 3) [mm] to the nearest wall of the tank, >= 0."""
    return np.maximum(TANK_HALF_MM - np.max(np.abs(p), axis=-1), 0.0)


def wall_gain(d, law, ell):
    """Wall-drag profile (1 at contact) at wall distance d [mm], length ell [mm]: law '1/d', 'exp' or '1/d^2'."""
    if law == "exp":
        return np.exp(-d / ell)
    g = ell / (d + ell)
    return g if law == "1/d" else g * g


def gradient_force(p, axis, b, mB):
    """Turn-averaged gradient force m grad|B| [uN] on a magnet locked to a field rotating about axis (..., 3).

    Coil pair k alone makes the axisymmetric, curl- and divergence-free field (per unit centre field)
    e_k (1 + beta_k (x_k^2 - r_k^2 / 2)) - beta_k x_k (x - x_k e_k), r_k the distance from its axis, so
    |B_k| is quadratic near the centre. The pairs carry currents I = cos(t) e1 + sin(t) e2 (e1, e2 normal
    to the axis) and the moment follows the local field: F = m B0 grad|B| = mB J B / |B| (J the field
    gradient), averaged over GRADIENT_PHASES phases of half a turn (F(t + pi) = F(t)).
    p (..., 3) [mm]; b (3,) = mB beta [uN/mm]; mB = m B0 [uN mm].
    """
    beta = np.asarray(b, dtype=float) / mB
    ref = np.where(np.abs(axis[..., 2:3]) < 0.9, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    e1 = unit(ref - (ref * axis).sum(-1, keepdims=True) * axis)
    i, j = [1, 2, 0], [2, 0, 1]
    e2 = axis[..., i] * e1[..., j] - axis[..., j] * e1[..., i]  # axis x e1
    th = (np.arange(GRADIENT_PHASES) + 0.5) * (np.pi / GRADIENT_PHASES)
    shape = (-1,) + (1,) * e1.ndim
    cur = np.cos(th).reshape(shape) * e1 + np.sin(th).reshape(shape) * e2  # (phases, ..., 3)
    c = cur * beta
    cx = (c * p).sum(-1, keepdims=True)
    field = cur + c * (2.5 * p * p - 0.5 * (p * p).sum(-1, keepdims=True)) - p * cx
    jb = (5.0 * c * field * p - p * (c * field).sum(-1, keepdims=True)
          - c * (p * field).sum(-1, keepdims=True) - field * cx)  # J B
    mag = np.sqrt((field * field).sum(-1, keepdims=True))
    return mB * np.mean(jb / np.maximum(mag, 1e-300), axis=0)


def adler_mean_spin(f, f_so):
    """Mean spin [Hz] of a magnet driven at f [Hz] (Adler): f up to the step-out f_so, f - sqrt(f^2 - f_so^2) above."""
    return f - np.sqrt(np.maximum(f * f - f_so * f_so, 0.0))


def step_out_loss(u, k, f_so):
    """Thrust lost [uN] to step-out: -k (f - mean spin) u_hat, f = |u| [Hz], k [uN/Hz]."""
    f = np.sqrt((u * u).sum(-1, keepdims=True))
    return -k * (f - adler_mean_spin(f, f_so)) * unit(u)


def lag_mean(u, dt_s, tau):
    """Mean over each period of y' = (u - y) / tau for piecewise-constant u (n, 3), y(0) = u[0] (a doubling scan)."""
    if tau <= 1e-9 or len(u) == 0:
        return np.array(u, dtype=float)
    a = float(np.exp(-dt_s / tau))
    y = (1.0 - a) * u  # becomes y at the end of each period: y_{i+1} = a y_i + (1 - a) u_i
    y[0] = y[0] + a * u[0]
    shift, f = 1, a
    while shift < len(y) and f > 1e-18:
        y[shift:] = y[shift:] + f * y[:-shift]
        shift, f = 2 * shift, f * f
    start = np.concatenate([u[:1], y[:-1]])
    return u + (start - u) * ((tau / dt_s) * (1.0 - a))


def heading_mean(u, dt_s, tau):
    """Mean over each period of f b(t), the body axis b relaxing on the sphere towards u_hat, u (n, 3) [Hz].

    b' = (u_hat - (u_hat . b) b) / tau, tau [s], f = |u|, b(0) = u_hat[0]. In the plane (b, u_hat) the angle
    obeys theta' = -sin(theta) / tau, so s = tan(theta / 2) decays as exp(-t / tau): the means of cos and
    sin theta over a period are exact.
    """
    f = np.sqrt((u * u).sum(-1))
    uh = unit(u)
    a = float(np.exp(-dt_s / tau)) if tau > 1e-9 else 0.0
    s0, perp = np.zeros(len(u)), np.zeros((len(u), 3))
    b = uh[0].tolist() if len(u) else [0.0, 0.0, 1.0]
    for i, (x, y, z) in enumerate(uh.tolist()):  # sequential: plain floats
        c = b[0] * x + b[1] * y + b[2] * z
        q = [b[0] - c * x, b[1] - c * y, b[2] - c * z]
        sn = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) ** 0.5
        if x * x + y * y + z * z < 0.25 or (sn < 1e-12 and c > 0):
            continue  # no command, or aligned
        if sn < 1e-12:  # opposite: turn about any normal
            q = [-y, x, 0.0] if abs(z) < 0.9 else [0.0, -z, y]
            sn = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) ** 0.5
        e = [q[0] / sn, q[1] / sn, q[2] / sn]
        s0[i], perp[i] = (sn / (1.0 + c) if 1.0 + c > 1e-12 else 1e6), e
        s1 = s0[i] * a
        cs, sn1 = (1.0 - s1 * s1) / (1.0 + s1 * s1), 2.0 * s1 / (1.0 + s1 * s1)
        b = [cs * x + sn1 * e[0], cs * y + sn1 * e[1], cs * z + sn1 * e[2]]
    s1, r = s0 * a, tau / dt_s
    mc = 1.0 - r * np.log((1.0 + s0 * s0) / (1.0 + s1 * s1))
    ms = 2.0 * r * (np.arctan(s0) - np.arctan(s1))
    return f[:, None] * (mc[:, None] * uh + ms[:, None] * perp)


def delayed(traj, delay):
    """What a camera with latency delay [periods] reports along traj (w, L + 1, 3) [mm] (rows one period apart).

    Linear interpolation at row i - delay; before row 0, extrapolation along the first step.
    """
    n = traj.shape[1]
    if n < 2:
        return np.array(traj, dtype=float)
    s = np.arange(n) - delay
    j = np.clip(np.floor(s).astype(int), 0, n - 2)
    f = (s - j)[None, :, None]
    return traj[:, j] + f * (traj[:, j + 1] - traj[:, j])


# ====================================================================== drawing


def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def _lu(rng, lo, hi):
    """Log-uniform in [lo, hi] (ranges spanning a decade)."""
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


class _Pick:
    """The override for a key if one was given, else the drawn value (drawn anyway, so the stream stays put)."""

    def __init__(self, overrides: dict):
        self.left, self.used = dict(overrides), set()

    def __call__(self, key, drawn):
        if key in self.left:
            self.used.add(key)
            drawn = self.left.pop(key)
        return drawn.tolist() if isinstance(drawn, (np.ndarray, np.generic)) else drawn


def draw_cases(n: int, seed: int) -> list[Case]:
    """n cases: at least 1/6 (>= 10 when n >= 60) "none", at least 2/15 (>= 8 when n >= 60) "outside" (cycling
    through the four), the rest "library" cycling through the nine (each >= 5 times from n = 65 on: at n = 60
    the minimums leave 42); shuffled, each with its own seed."""
    rng = np.random.default_rng([seed, 0])
    n_none = min(max(math.ceil(n / 6), 10 if n >= 60 else 0), n)
    n_out = min(max(math.ceil(2 * n / 15), 8 if n >= 60 else 0), n - n_none)
    plan = ([("none", None)] * n_none + [("outside", OUTSIDE[i % len(OUTSIDE)]) for i in range(n_out)]
            + [("library", LIBRARY[i % len(LIBRARY)]) for i in range(n - n_none - n_out)])
    order, seeds = rng.permutation(n), rng.integers(0, 2**31 - 1, n)
    return [draw_case(int(seeds[i]), *plan[j], index=i) for i, j in enumerate(order)]


def draw_case(seed: int, group: str, effect: str | None = None, index: int = 0, **overrides) -> Case:
    """One case drawn from ``seed`` (a random effect of the group when ``effect`` is None).

    ``overrides`` fix drawn values by their key in ``regime`` (``tau_v_s``, ``speed_per_hz``, ``cd0_ratio``,
    ``cl0_ratio``, ``sink_mm_s``, ``fmax_mm_s``, ``dt_s``, ``noise_mm``, ``noise_axis``, ``outlier_rate``,
    ``lost_rate``, ``f_lo_hz``, ``f_hi_hz``, ``band_hz``, ``cmd_noise_hz``, ``hold_s``, ``lookahead_mm``,
    ``duration_s``, ``logs`` (at most duration / 15 s), ``log_durations_s``, ``path_kinds``, ``near_wall``
    (bool or list)) or in ``truth`` (e.g. ``tau_s``, ``f_so_hz``, ``ell_mm``), and ``law``.
    """
    rng = np.random.default_rng([seed, 1])
    names = {"library": LIBRARY, "outside": OUTSIDE, "none": (None,)}.get(group)
    if names is None:
        raise ValueError(f"unknown group {group!r}; one of library, none, outside")
    effect = str(rng.choice(names)) if effect is None and group != "none" else effect
    if effect not in names:
        raise ValueError(f"effect {effect!r} is not in group {group!r}")
    return _build(rng, seed, group, [effect] if effect is not None else [], index, overrides)


def _build(rng, seed: int, group: str, effects: list, index: int, overrides: dict) -> Case:
    """The case hiding ``effects``: its regime, then each effect's law and truth (a gradient force first: it
    may raise the band the others scale with), all from ``rng``; ``overrides`` as in :func:`draw_case`."""
    check_compatible(effects)
    pick = _Pick(overrides)
    regime = _draw_regime(rng, pick)
    drawn = {e: _draw_truth(rng, pick, e, regime) for e in sorted(effects, key=lambda e: e != "gradient_force")}
    if pick.left:
        raise TypeError(f"unknown override(s): {', '.join(sorted(pick.left))}")
    laws, truths = [drawn[e][0] for e in effects], [drawn[e][1] for e in effects]
    forms = [_true_form(e, law, t, index, seed) for e, law, t in zip(effects, laws, truths)]
    names = [f"true_{e}" if f else None for e, f in zip(effects, forms)]
    if len(effects) == 1:
        return Case(index, int(seed), group, effects[0], laws[0], truths[0], regime, forms[0], names[0])
    if not effects:
        return Case(index, int(seed), group, None, "", {}, regime, None, None)
    return Case(index, int(seed), group, "+".join(effects), "", dict(zip(effects, truths)), regime, None, None,
                effects=list(effects), laws=laws, truths=truths, true_forms=forms, true_form_names=names)


def compatible_pairs(kind: str) -> list[tuple[str, str]]:
    """The effect pairs :func:`draw_multi_cases` hides: "library" (two library effects) or "outside" (a library
    effect and an outside one, not "periodic"), at most one thrust-shaping effect and one flow each."""
    if kind == "library":
        pairs = [(a, b) for i, a in enumerate(LIBRARY) for b in LIBRARY[i + 1:]]
    elif kind == "outside":
        pairs = [(a, b) for a in LIBRARY for b in OUTSIDE if b != "periodic"]
    else:
        raise ValueError(f"pair kind {kind!r}: 'library' or 'outside'")
    ok = []
    for pair in pairs:
        try:
            check_compatible(pair)
        except ValueError:
            continue
        ok.append(pair)
    return ok


def draw_multi_case(seed: int, effects=None, index: int = 0, **overrides) -> Case:
    """One case of group "multi" hiding two effects (a random compatible pair when ``effects`` is None: two
    library effects or, one time in three, a library and an outside one), drawn like :func:`draw_case`."""
    rng = np.random.default_rng([seed, 1])
    if effects is None:
        pairs = compatible_pairs("outside" if rng.random() < 1 / 3 else "library")
        effects = pairs[int(rng.integers(len(pairs)))]
    effects = list(effects)
    if len(effects) < 2:
        raise ValueError(f"a multi case hides at least two effects, not {'+'.join(effects) or 'none'}")
    if "periodic" in effects:
        raise ValueError("a multi case does not hide 'periodic' (it has no true form)")
    return _build(rng, seed, "multi", effects, index, overrides)


def draw_multi_cases(n: int, seed: int) -> list[Case]:
    """n cases of two hidden effects each: two library effects in two cases of three, a library and an outside
    one (not "periodic") in the third; the pairs cycle through shuffled lists of the compatible pairs
    (:func:`compatible_pairs`). Own stream [seed, 3]: :func:`draw_cases` is unchanged."""
    rng = np.random.default_rng([seed, 3])
    lib, out = compatible_pairs("library"), compatible_pairs("outside")
    lib, out = [lib[i] for i in rng.permutation(len(lib))], [out[i] for i in rng.permutation(len(out))]
    plan = [lib[(i - i // 3) % len(lib)] if i % 3 != 2 else out[(i // 3) % len(out)] for i in range(n)]
    order, seeds = rng.permutation(n), rng.integers(0, 2**31 - 1, n)
    return [draw_multi_case(int(seeds[i]), plan[j], index=i) for i, j in enumerate(order)]


def draw_drift_case(seed: int, kind: str | None = None, index: int = 0, **overrides) -> Case:
    """One case of group "drift": nothing hidden, but a parameter of the plant (:data:`DRIFT_PARAMS`, drawn)
    changes ``kind`` (:data:`DRIFT_KINDS`; "steady": nothing changes, a control), stream [seed, 8].

    between: 3-6 logs of 20-90 s, the parameter times (1 + change)^log, |change| 3-12 % per log (log-uniform),
    either sign; within: 1-3 logs of 90-240 s, the parameter times 1 + change t / duration, |change| 8-30 % over
    each log. Steady controls: 1-6 logs of 20-240 s, and the camera gives a frame every 1, 2, 3 or 5 rows
    (``frame_every``). In ``regime["drift"]``: {"param", "kind", "change"} (None for a steady case).
    """
    rng = np.random.default_rng([seed, 8])
    kind = str(rng.choice(DRIFT_KINDS + ("steady",))) if kind is None else kind
    if kind not in DRIFT_KINDS + ("steady",):
        raise ValueError(f"drift kind {kind!r}: one of {', '.join(DRIFT_KINDS)}, steady")
    param = str(rng.choice(DRIFT_PARAMS))
    sign = 1.0 if rng.random() < 0.5 else -1.0
    logs = int(rng.integers(3, 7)) if kind == "between" else int(rng.integers(1, 4))
    if kind == "steady":
        logs = int(rng.integers(1, 7))
    per_log = {"between": (20.0, 90.0), "within": (90.0, 240.0), "steady": (20.0, 240.0)}[kind]
    durations = rng.uniform(*per_log, logs).tolist()
    change = sign * (_lu(rng, 0.03, 0.12) if kind == "between" else _lu(rng, 0.08, 0.30))
    frame_every = int(rng.choice([1, 2, 3, 5])) if kind == "steady" else 1
    regime = {"log_durations_s": durations, "duration_s": float(sum(durations)), "logs": logs}
    case = _build(np.random.default_rng([seed, 1]), seed, "drift", [], index, regime | overrides)
    case.regime["drift"] = None if kind == "steady" else {"param": param, "kind": kind, "change": change}
    case.regime["frame_every"] = frame_every
    return case


def draw_drift_cases(n: int, seed: int) -> list[Case]:
    """n drift cases: one in three a steady control, the others alternating between and within; shuffled.
    Own stream [seed, 7]."""
    rng = np.random.default_rng([seed, 7])
    plan = ["steady" if i % 3 == 2 else DRIFT_KINDS[(i - i // 3) % 2] for i in range(n)]
    order, seeds = rng.permutation(n), rng.integers(0, 2**31 - 1, n)
    return [draw_drift_case(int(seeds[i]), plan[j], index=i) for i, j in enumerate(order)]


def draw_lookalike_case(seed: int, effect: str | None = None, index: int = 0, **overrides) -> Case:
    """One case of group "lookalike": one hidden effect of :data:`LOOKALIKE` (or "quadratic_drag") at a magnitude
    drawn over a wide range, in a regime where the family mimic each other.

    Lags (actuation, heading): tau 0.1-0.5 s (log-uniform); camera latency 2-12 control periods (log-uniform).
    Their regime: the spin rate held 2-5 s up to 3-10 s at a time, command noise 0-0.2 Hz. A quadratic drag:
    the spin rate within a band 0.5-2 Hz wide (logs at about one speed, where it mimics a slower velocity
    response), held as long. These are drawn from stream [seed, 6] and passed to :func:`draw_case`'s
    machinery as overrides (``overrides`` given here win).
    """
    rng = np.random.default_rng([seed, 6])
    names = LOOKALIKE + ("quadratic_drag",)
    drawn = int(rng.integers(len(LOOKALIKE)))
    effect = LOOKALIKE[drawn] if effect is None else effect
    if effect not in names:
        raise ValueError(f"effect {effect!r} is not a look-alike case's; one of {', '.join(names)}")
    hold_lo = _u(rng, 2.0, 5.0)
    regime = {"hold_s": [hold_lo, hold_lo + _u(rng, 1.0, 5.0)], "cmd_noise_hz": _u(rng, 0.0, 0.2)}
    tau, delay, f_lo, width = _lu(rng, 0.1, 0.5), _lu(rng, 2.0, 12.0), _u(rng, 2.0, 15.0), _u(rng, 0.5, 2.0)
    if effect in ("actuation_lag", "heading_lag"):
        regime["tau_s"] = tau
    elif effect == "sensor_latency":
        regime["delay_periods"] = delay
    else:
        regime["band_hz"] = [f_lo, f_lo + width]
    return _build(np.random.default_rng([seed, 1]), seed, "lookalike", [effect], index, regime | overrides)


def draw_lookalike_cases(n: int, seed: int) -> list[Case]:
    """n look-alike cases (:func:`draw_lookalike_case`): one in :data:`LOOKALIKE_QUADRATIC_EVERY` hides a
    quadratic drag, the others cycle through :data:`LOOKALIKE`; shuffled. Own stream [seed, 5]."""
    rng = np.random.default_rng([seed, 5])
    n_quad = n // LOOKALIKE_QUADRATIC_EVERY
    plan = ["quadratic_drag"] * n_quad + [LOOKALIKE[i % len(LOOKALIKE)] for i in range(n - n_quad)]
    order, seeds = rng.permutation(n), rng.integers(0, 2**31 - 1, n)
    return [draw_lookalike_case(int(seeds[i]), plan[j], index=i) for i, j in enumerate(order)]


def _draw_regime(rng, pick) -> dict:
    """Plant, camera, band, controller, logs and paths (see the module docstring for the ranges)."""
    tau = pick("tau_v_s", _lu(rng, 0.03, 0.5))
    sph = pick("speed_per_hz", _u(rng, 1.0, 5.0))
    cd0, cl0 = pick("cd0_ratio", _u(rng, 0.0, 0.8)), pick("cl0_ratio", _u(rng, -0.3, 0.3))
    sink, fmax = pick("sink_mm_s", -_lu(rng, 0.5, 5.0)), pick("fmax_mm_s", _u(rng, -3.0, 3.0))
    cd1 = MASS_MG / (1000.0 * tau)  # tau_v = m / Cd1 [s]; Cd1 [uN s/mm]
    r = {"tau_v_s": tau, "speed_per_hz": sph, "cd0_ratio": cd0, "cl0_ratio": cl0, "sink_mm_s": sink,
         "fmax_mm_s": fmax, "plant": {"mass_mg": MASS_MG, "k": sph * cd1, "Cd0": cd0 * cd1, "Cd1": cd1,
                                      "Cl0": cl0 * cd1, "Fvs": sink * cd1, "Fmax": fmax * cd1}}
    r["dt_s"] = pick("dt_s", 0.02 if rng.random() < 0.8 else float(rng.choice([0.01, 0.04])))
    r["substep_s"] = r["dt_s"] / max(1, round(r["dt_s"] / SUBSTEP_S))
    r["noise_mm"] = pick("noise_mm", _u(rng, 0.05, 0.3))
    r["noise_axis"] = pick("noise_axis", rng.uniform(0.7, 1.3, 3))
    r["outlier_rate"], r["lost_rate"] = pick("outlier_rate", _u(rng, 0, 0.01)), pick("lost_rate", _u(rng, 0, 0.05))
    f_lo = pick("f_lo_hz", _u(rng, 1.0, 5.0))
    r["band_hz"] = pick("band_hz", [f_lo, pick("f_hi_hz", _u(rng, min(f_lo + 5.0, 20.0), 20.0))])
    r["cmd_noise_hz"] = pick("cmd_noise_hz", _u(rng, 0.0, 1.0))
    r["hold_s"] = pick("hold_s", [1.0, 5.0])
    r["lookahead_mm"] = pick("lookahead_mm", _u(rng, 5.0, 12.0))
    duration = pick("duration_s", _lu(rng, 30.0, 300.0))
    logs = max(1, min(int(pick("logs", int(rng.integers(1, 5)))), int(duration // 15)))
    share = rng.dirichlet(np.ones(logs))
    r["log_durations_s"] = pick("log_durations_s", (15.0 + (duration - 15.0 * logs) * share).tolist())
    r["logs"] = logs = len(r["log_durations_s"])
    r["duration_s"] = float(sum(r["log_durations_s"]))
    kinds = pick("path_kinds", rng.choice(PATH_KINDS, logs).tolist())
    near = pick("near_wall", (rng.random(logs) < 1 / 3).tolist())
    near = [near] * logs if isinstance(near, bool) else near
    r["paths"] = [_draw_path(rng, kinds[i % len(kinds)], bool(near[i % len(near)])) for i in range(logs)]
    r["path_kinds"] = [d["kind"] for d in r["paths"]]
    r["near_wall"] = [d["near_wall"] for d in r["paths"]]
    return r


def _draw_path(rng, kind: str, near_wall: bool) -> dict:
    """A path description (JSON-able): shape, orientation, direction, start, offset; see :func:`path_points`."""
    d = {"kind": kind, "yaw_deg": _u(rng, 0, 360), "tilt_deg": _u(rng, 0, 90), "tilt_axis_deg": _u(rng, 0, 360),
         "direction": int(rng.choice([-1, 1])), "start": _u(rng, 0, 1)}
    if kind == "circle":
        d["radius_mm"] = _u(rng, 20, 45)
    elif kind == "racetrack":
        d["straight_mm"], d["radius_mm"] = _u(rng, 20, 40), _u(rng, 20, 40)
    elif kind == "figure8":  # lobes' end radius 4 b^2 / a
        d["a_mm"] = _u(rng, 25, 45)
        d["b_mm"] = d["a_mm"] * _u(rng, 0.4, 0.6)
    elif kind == "helix":  # vertical axis, `turns` up then down
        d["radius_mm"], d["pitch_mm"] = _u(rng, 20, 40), _u(rng, 10, 30)
        d["turns"], d["tilt_deg"] = int(rng.integers(1, int(60 // d["pitch_mm"]) + 1)), 0.0
    else:
        raise ValueError(f"unknown path kind {kind!r}; one of {', '.join(PATH_KINDS)}")
    pts = path_points(d | {"offset_mm": [0.0, 0.0, 0.0]}, ds=2.0)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    off = [_u(rng, -PATH_LIMIT_MM - lo[i], PATH_LIMIT_MM - hi[i]) for i in range(3)]
    axis, side, extreme = int(rng.integers(3)), int(rng.choice([-1, 1])), _u(rng, 63, 71)
    if near_wall:  # the path's extreme along one axis 4-12 mm from that wall
        off[axis] = float(extreme - hi[axis] if side > 0 else -extreme - lo[axis])
        d["wall"] = ("+" if side > 0 else "-") + "xyz"[axis]
    d["near_wall"], d["offset_mm"] = near_wall, off
    return d


def path_points(desc: dict, ds: float = PATH_DS_MM) -> np.ndarray:
    """(N, 3) [mm] points of a closed path ~ds apart, from its start point, in its travel direction."""
    kind, t = desc["kind"], np.linspace(0.0, 1.0, 20001)
    if kind == "circle":
        th, r = 2 * np.pi * t, desc["radius_mm"]
        xyz = np.stack([r * np.cos(th), r * np.sin(th), 0 * t], axis=1)
    elif kind == "racetrack":  # by arc length: straight, half turn, straight back, half turn
        a, r = desc["straight_mm"], desc["radius_mm"]
        s = t * (2 * a + 2 * np.pi * r)
        ang = np.clip(s - a, 0, np.pi * r) / r - np.pi / 2
        ang2 = np.clip(s - 2 * a - np.pi * r, 0, np.pi * r) / r + np.pi / 2
        part = [s < a, s < a + np.pi * r, s < 2 * a + np.pi * r]
        x = np.select(part, [s - a / 2, a / 2 + r * np.cos(ang), a / 2 - (s - a - np.pi * r)],
                      -a / 2 + r * np.cos(ang2))
        y = np.select(part, [-r + 0 * s, r * np.sin(ang), r + 0 * s], r * np.sin(ang2))
        xyz = np.stack([x, y, 0 * t], axis=1)
    elif kind == "figure8":
        th = 2 * np.pi * t
        xyz = np.stack([desc["a_mm"] * np.sin(th), desc["b_mm"] * np.sin(2 * th), 0 * t], axis=1)
    else:
        n, r, pitch = desc["turns"], desc["radius_mm"], desc["pitch_mm"]
        th = 4 * np.pi * n * t
        z = pitch * np.minimum(th, 4 * np.pi * n - th) / (2 * np.pi) - pitch * n / 2
        xyz = np.stack([r * np.cos(th), r * np.sin(th), z], axis=1)
    ax = math.radians(desc["tilt_axis_deg"])
    xyz = xyz @ _rot([0, 0, 1], desc["yaw_deg"]).T @ _rot([math.cos(ax), math.sin(ax), 0.0], desc["tilt_deg"]).T
    xyz = xyz[::-1] if desc["direction"] < 0 else xyz
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xyz, axis=0), axis=1))])
    n_pts = max(int(round(arc[-1] / ds)), 8)
    s = (np.arange(n_pts) / n_pts + desc["start"]) % 1.0 * arc[-1]
    return np.stack([np.interp(s, arc, xyz[:, i]) for i in range(3)], axis=1) + np.asarray(desc["offset_mm"])


def _rot(axis, deg):
    """3x3 rotation by deg about axis (Rodrigues)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    a = math.radians(deg)
    return np.eye(3) + math.sin(a) * kx + (1 - math.cos(a)) * kx @ kx


def _sphere(n: int, radius: float) -> np.ndarray:
    """(n, 3) points spread evenly on a sphere (Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z, phi = 1 - 2 * i / n, np.pi * (1 + 5**0.5) * i
    rho = np.sqrt(1 - z * z)
    return radius * np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)


def _draw_truth(rng, pick, effect, reg) -> tuple[str, dict]:
    """The effect's law and parameters in human units; force scales follow the case's Cd1 and k."""
    cd1, k = reg["plant"]["Cd1"], reg["plant"]["k"]
    f_lo, f_hi = reg["band_hz"]
    law, t = "", {}
    if effect in ("background_flow", "shear_flow", "periodic"):  # horizontal, random direction
        ang = math.radians(pick("dir_deg", _u(rng, 0, 360)))
        if effect == "background_flow":
            s = pick("speed_mm_s", _lu(rng, 0.5, 5.0))
            t = {"speed_mm_s": s, "w_x_mm_s": pick("w_x_mm_s", s * math.cos(ang)),
                 "w_y_mm_s": pick("w_y_mm_s", s * math.sin(ang))}
        elif effect == "shear_flow":  # w = gamma z e, |w| at z = 40 mm
            w40 = pick("w_at_40mm_mm_s", _u(rng, 1.0, 5.0))
            t = {"w_at_40mm_mm_s": w40, "gamma_x_per_s": pick("gamma_x_per_s", w40 / 40 * math.cos(ang)),
                 "gamma_y_per_s": pick("gamma_y_per_s", w40 / 40 * math.sin(ang))}
        else:
            r = pick("f0_over_cd1_mm_s", _u(rng, 1.0, 5.0))
            t = {"f0_over_cd1_mm_s": r, "f0_uN": pick("f0_uN", r * cd1), "f_hz": pick("f_hz", _lu(rng, 0.2, 2.0)),
                 "phase_rad": pick("phase_rad", _u(rng, 0, 2 * math.pi))}
        t["dir_deg"] = math.degrees(ang)
    elif effect == "wall_drag":
        law, r = pick("law", str(rng.choice(WALL_LAWS))), pick("c_over_cd1", _u(rng, 1.0, 5.0))
        if law not in WALL_LAWS:
            raise ValueError(f"wall-drag law {law!r}: one of {', '.join(WALL_LAWS)}")
        t = {"c_over_cd1": r, "c_uNs_mm": pick("c_uNs_mm", r * cd1), "ell_mm": pick("ell_mm", _u(rng, 3.0, 15.0))}
    elif effect == "step_out":
        law = pick("law", "inside" if rng.random() < 0.7 else "top")
        if law not in ("inside", "top"):
            raise ValueError(f"step-out law {law!r}: 'inside' or 'top'")
        x, y = _u(rng, 0.2, 0.8), _u(rng, 0.8, 0.95)
        t = {"f_so_hz": pick("f_so_hz", f_lo + x * (f_hi - f_lo) if law == "inside" else y * f_hi)}
    elif effect == "gradient_force":  # beta ~ 1 / R^2 for coils of radius R; scaled to the peak force at 40 mm
        radius = _u(rng, 90.0, 150.0)
        beta = rng.choice([-1.0, 1.0], 3) * rng.uniform(0.3, 1.0, 3) / radius**2
        frac = pick("frac_at_40mm", _u(rng, 0.2, 0.8))
        peak = math.sqrt((gradient_force(_sphere(400, 40.0), _sphere(400, 1.0)[::-1], beta, 1.0) ** 2).sum(1).max())
        # the spin rate whose thrust beats 1.3 x the force anywhere on the paths (spin axis along the path):
        # below it the swimmer is pushed off its path and pinned to a wall. It is kept <= 16 Hz by lowering frac.
        pts = [path_points(d, ds=2.0) for d in reg["paths"]]
        pts, tangent = np.concatenate(pts), np.concatenate([unit(np.roll(x, -1, axis=0) - x) for x in pts])
        worst = 1.3 * math.sqrt((gradient_force(pts, tangent, beta, 1.0) ** 2).sum(1).max()) / peak * 10.0  # per frac
        capped = worst * frac > 16.0 and "frac_at_40mm" not in pick.used
        frac = 16.0 / worst if capped else frac
        mb = pick("mB_uNmm", frac * 10.0 * k / peak)
        t = {"frac_at_40mm": frac, "frac_capped": capped, "coil_radius_mm": radius, "mB_uNmm": mb,
             "b_uN_mm": pick("b_uN_mm", (mb * beta).tolist()), "min_spin_hz": worst * frac}
        if f_lo < worst * frac and not pick.used & {"band_hz", "f_lo_hz"}:
            reg["band_hz"], reg["band_raised"] = [worst * frac, min(max(f_hi, worst * frac + 5.0), 20.0)], True
    elif effect == "anisotropic_drag":
        r = pick("c_over_cd1", _u(rng, 0.3, 1.0))
        t = {"c_over_cd1": r, "c_uNs_mm": pick("c_uNs_mm", r * cd1)}
    elif effect == "quadratic_drag":  # c |v| = ratio Cd1 at the cruise speed (mid-band)
        r, cruise = pick("ratio_at_cruise", _u(rng, 0.3, 1.5)), reg["speed_per_hz"] * (f_lo + f_hi) / 2
        t = {"ratio_at_cruise": r, "cruise_mm_s": cruise, "c_uNs2_mm2": pick("c_uNs2_mm2", r * cd1 / cruise)}
    elif effect in ("actuation_lag", "heading_lag"):
        t = {"tau_s": pick("tau_s", _lu(rng, 0.03, 0.5))}
    elif effect == "sensor_latency":
        dp = pick("delay_periods", _lu(rng, 0.5, 5.0))
        t = {"delay_periods": dp, "delay_s": dp * reg["dt_s"]}
    elif effect == "rotating_flow":  # axis within 30 mm of the centre, |w| at 40 mm from it
        rr, ang, w40 = 30.0 * math.sqrt(rng.random()), _u(rng, 0, 2 * math.pi), _u(rng, 1.0, 5.0)
        sign = float(rng.choice([-1.0, 1.0]))
        t = {"x0_mm": pick("x0_mm", rr * math.cos(ang)), "y0_mm": pick("y0_mm", rr * math.sin(ang)),
             "w_at_40mm_mm_s": pick("w_at_40mm_mm_s", w40)}
        t["omega_rad_s"] = pick("omega_rad_s", sign * t["w_at_40mm_mm_s"] / 40.0)
    elif effect == "thrust_nonuniform":  # k (1 + g . p), |g| 40 mm = change
        r, g = pick("change_at_40mm", _u(rng, 0.1, 0.3)), unit(rng.normal(size=3))
        t = {"change_at_40mm": r, "g_per_mm": pick("g_per_mm", (g * r / 40.0).tolist())}
    return law, t


# ====================================================================== simulation


class _Plant:
    """The continuous-time plant of one case for all its L logs at once, advanced one control period at a time.

    ``hidden`` maps each hidden effect to its truth (at most one thrust-shaping effect and one flow: see
    :func:`check_compatible`); forces add up and every drag acts on the velocity relative to the water.
    ``state`` holds the thrust-shaping effect's own state: the field's rotation vector [Hz] (actuation lag,
    (L, 3)), the body axis (heading lag, (L, 3)) or the magnet's lag phase phi as (sin(phi/2), cos(phi/2))
    (step-out, (L, 2)); None before the first period.
    """

    def __init__(self, case: Case):
        pl, dt = case.regime["plant"], case.regime["dt_s"]
        check_compatible(case.effects)
        self.hidden = dict(zip(case.effects, case.truths))
        self.wall_law = dict(zip(case.effects, case.laws)).get("wall_drag", "")
        # the plant's coefficients as accelerations: [mm/s^2 / Hz], [1/s], [mm/s^2]
        self.k, self.cd0, self.cd1, self.cl0, self.fvs, self.fmax = (ACC * pl[n] for n in ("k", "Cd0", "Cd1", "Cl0",
                                                                                              "Fvs", "Fmax"))
        self.base = {"thrust": (self.k,), "drag": (self.cd0, self.cd1, self.cl0), "weight": (self.fvs,)}
        self.uses_p = bool(set(self.hidden) & {"rotating_flow", "shear_flow", "wall_drag", "thrust_nonuniform"})
        self.m = max(1, round(dt / SUBSTEP_S))
        self.dt, self.h = dt, dt / self.m
        self.tj = np.arange(self.m + 1) * self.h  # substep boundaries within a period [s]
        self.state, self.guess, self.passes = None, None, []
        self._guess_rate(self.cd1)
        if "background_flow" in self.hidden:
            t = self.hidden["background_flow"]
            self.flow = np.array([t["w_x_mm_s"], t["w_y_mm_s"], 0.0])
        if "periodic" in self.hidden:
            a = math.radians(self.hidden["periodic"]["dir_deg"])
            self.pdir = np.array([math.cos(a), math.sin(a), 0.0])

    def period(self, p, v, u, t0):
        """States P, V (M + 1, L, 3) [mm, mm/s] at the substep ends of [t0, t0 + dt) from p, v under u (L, 3) [Hz]."""
        thrust, axis, held = self._drive(u, p, v, t0)
        drive = thrust[0] if len(thrust) == 1 else thrust.mean(axis=0)
        if self.guess is None:
            P, V = np.broadcast_to(p, (self.m + 1,) + p.shape), np.broadcast_to(v, (self.m + 1,) + v.shape)
        else:  # the previous period's solution, corrected linearly for the new start velocity and drive
            P0, V0, drive0 = self.guess
            dv, da = v - V0[0], drive - drive0
            P = (P0 - P0[0] + p) + self.guess_q * dv + self.guess_r * da
            V = V0 + self.guess_e * dv + self.guess_q * da
        for n_pass in range(1, PICARD_MAX + 1):
            pm = (P[1:] + P[:-1]) * 0.5 if self.uses_p else None
            lam, acc = self._rates(pm, (V[1:] + V[:-1]) * 0.5, thrust, axis, held)
            Pn, V = self._solve(p, v, lam, acc)
            change, P = abs(Pn[-1] - P[-1]).max(), Pn
            if change < PICARD_TOL_MM:
                break
        self.guess = (P, V, drive)
        self.passes.append(n_pass)
        if len(self.passes) % 50 == 0:
            self._guess_rate(float(lam.mean()))
        return P, V

    def drift(self, param: str, factor: np.ndarray) -> None:
        """Scale the plant's ``param`` (:data:`DRIFT_PARAMS`) by ``factor`` (L,), one per log, from now on."""
        f = np.asarray(factor, dtype=float)
        if param == "thrust":
            self.k = self.base["thrust"][0] * f[:, None]  # multiplies commands (L, 3)
        elif param == "drag":
            self.cd0, self.cd1, self.cl0 = (c * f for c in self.base["drag"])
        elif param == "weight":
            self.fvs = self.base["weight"][0] * f
        else:
            raise ValueError(f"unknown drift parameter {param!r}; one of {', '.join(DRIFT_PARAMS)}")

    def _guess_rate(self, lam):
        """The guess's linear response to a change of start velocity or drive, at the drag rate lam [1/s]."""
        self.guess_e = np.exp(-lam * self.tj)[:, None, None]
        self.guess_q = (1.0 - self.guess_e) / lam
        self.guess_r = (self.tj[:, None, None] - self.guess_q) / lam

    def _drive(self, u, p, v, t0):
        """Thrust and unit spin/body axis per substep ((M or 1), L, 3), and the held forces, all / m [mm/s^2]."""
        hid, k = self.hidden, self.k
        uh = field_axis = unit(u)  # the field's rotation axis: the command's, unless the field lags it
        thrust, axis = (k * u)[None], uh[None]
        mid = p + (0.5 * self.dt) * v  # predicted mid-period position
        r = np.sqrt((mid * mid).sum(1, keepdims=True))
        held = mid * (np.sin(r * (np.pi / PB_NORM_MM)) * (-self.fmax) / np.maximum(r, 1e-12))  # Eq. 6
        held[:, 2] += self.fvs
        if "actuation_lag" in hid:  # omega_eff' = (u - omega_eff) / tau: exact means over the substeps
            t = hid["actuation_lag"]
            y0 = u if self.state is None else self.state
            decay = np.exp(-self.tj / t["tau_s"])
            mean = u + (y0 - u) * ((t["tau_s"] / self.h) * (decay[:-1] - decay[1:]))[:, None, None]
            self.state = u + (y0 - u) * decay[-1]
            thrust, axis = k * mean, unit(mean)
            field_axis = unit(mean.mean(axis=0))
        if "heading_lag" in hid:  # tan(theta / 2) decays as exp(-t / tau) in the plane (b, u_hat); see heading_mean
            t = hid["heading_lag"]
            b = uh if self.state is None else self.state
            c = np.clip((b * uh).sum(1), -1.0, 1.0)
            q = b - c[:, None] * uh
            sn = np.sqrt((q * q).sum(1))
            perp = q / np.maximum(sn, 1e-300)[:, None]
            if np.any((sn < 1e-12) & (c < 0)):  # opposite: turn about any normal
                alt = np.where(np.abs(uh[:, 2:3]) < 0.9, uh[:, [1, 0, 2]] * [-1, 1, 0], uh[:, [0, 2, 1]] * [0, -1, 1])
                alt = unit(alt)
                perp = np.where(((sn < 1e-12) & (c < 0))[:, None], alt, perp)
            s = (np.where(1.0 + c > 1e-12, sn / np.maximum(1.0 + c, 1e-12), 1e6)
                 * np.exp(-self.tj / t["tau_s"])[:, None])  # (M + 1, L)
            w = t["tau_s"] / self.h
            mc = 1.0 - w * np.log((1.0 + s[:-1] ** 2) / (1.0 + s[1:] ** 2))
            ms = 2.0 * w * (np.arctan(s[:-1]) - np.arctan(s[1:]))
            mean = mc[..., None] * uh + ms[..., None] * perp
            thrust, axis = k * np.sqrt((u * u).sum(1, keepdims=True)) * mean, unit(mean)
            s1 = s[-1][:, None]
            self.state = ((1.0 - s1 * s1) * uh + 2.0 * s1 * perp) / (1.0 + s1 * s1)
        if "step_out" in hid:  # Adler phase equation, solved exactly (see _adler)
            t = hid["step_out"]
            f = np.sqrt((u * u).sum(1))
            if self.state is None:  # locked at rest (or at phase 0 when slipping)
                half = 0.5 * np.arcsin(np.minimum(f / t["f_so_hz"], 1.0))
                self.state = np.stack([np.sin(half), np.cos(half)], axis=1)
            spin, self.state = _adler(f, t["f_so_hz"], self.state, self.tj)
            thrust = k * spin[..., None] * uh
        if "gradient_force" in hid:
            t = hid["gradient_force"]
            held = held + ACC * gradient_force(mid, field_axis, t["b_uN_mm"], t["mB_uNmm"])
        if "periodic" in hid:  # exact mean of F0 sin(2 pi f t + phase) over each substep
            t = hid["periodic"]
            om = 2 * np.pi * t["f_hz"]
            ph = om * (t0 + self.tj) + t["phase_rad"]
            mean_sin = (np.cos(ph[:-1]) - np.cos(ph[1:])) / (om * self.h)
            held = held + (ACC * t["f0_uN"] * mean_sin)[:, None, None] * self.pdir
        return thrust, axis, held

    def _rates(self, pm, vm, thrust, axis, held):
        """Drag rate lambda (M, L) [1/s] and the other acceleration (M, L, 3) [mm/s^2] at the substeps' midpoints.

        pm, vm: midpoint positions (None unless an effect needs them) and velocities (M, L, 3).
        """
        hid = self.hidden
        w = None
        if "background_flow" in hid:
            w = self.flow
        elif "rotating_flow" in hid:
            t = hid["rotating_flow"]
            w = rotating_flow(pm, t["x0_mm"], t["y0_mm"], t["omega_rad_s"])
        elif "shear_flow" in hid:
            t = hid["shear_flow"]
            w = shear_flow(pm, t["gamma_x_per_s"], t["gamma_y_per_s"])
        vr = vm if w is None else vm - w
        lam, acc = hydro_terms(vr, axis, self.cd0, self.cd1, self.cl0)  # coefficients / m: lambda, lift / m
        acc = acc + thrust + held
        if "wall_drag" in hid:
            t = hid["wall_drag"]
            lam = lam + (ACC * t["c_uNs_mm"]) * wall_gain(wall_distance(pm), self.wall_law, t["ell_mm"])
        if "quadratic_drag" in hid:
            lam = lam + (ACC * hid["quadratic_drag"]["c_uNs2_mm2"]) * np.sqrt((vr * vr).sum(-1))
        if w is not None:  # every drag on v - w: -lambda v (implicit) + lambda w
            acc = acc + lam[..., None] * w
        if "anisotropic_drag" in hid:  # on the velocity across the body axis
            acc = acc - (ACC * hid["anisotropic_drag"]["c_uNs_mm"]) * (vr - (vr * axis).sum(-1, keepdims=True) * axis)
        if "thrust_nonuniform" in hid:  # k (1 + g . p) omega
            acc = acc + (pm @ np.asarray(hid["thrust_nonuniform"]["g_per_mm"]))[..., None] * thrust
        return lam, acc

    def _solve(self, p0, v0, lam, acc):
        """Exact solution of v' = -lam_j v + acc_j, p' = v on each substep j from p0, v0 (L, 3): P, V (M + 1, L, 3).

        With x = lam h, q = (1 - e^-x) / lam, r = (h - q) / lam: v_{j+1} = e^-x_j v_j + q_j acc_j and
        p_{j+1} = p_j + q_j v_j + r_j acc_j, summed in closed form with E_j = exp(x_0 + ... + x_{j-1}):
        v_j = (v0 + sum_{i<j} E_{i+1} q_i acc_i) / E_j (E < e^12 here: no overflow, no cancellation).
        """
        x = lam * self.h
        q = np.expm1(-x)
        q /= -lam
        r = ((self.h - q) / lam)[..., None]
        q = q[..., None]
        grow = np.exp(np.add.accumulate(x, axis=0))[..., None]
        V = np.empty((len(x) + 1,) + v0.shape)
        V[0] = v0
        np.add.accumulate(grow * q * acc, axis=0, out=V[1:])
        V[1:] += v0
        V[1:] /= grow
        P = np.empty_like(V)
        P[0] = p0
        np.add.accumulate(q * V[:-1] + r * acc, axis=0, out=P[1:])
        P[1:] += p0
        return P, V


def _adler(f, f_so, w0, tj):
    """Mean spin [Hz] (M, L) over each substep of a magnet lagging the field by phi, phi' = 2 pi (f - f_so sin phi).

    z = tan(phi / 2) obeys a Riccati equation, so w = (sin(phi/2), cos(phi/2)) follows the linear flow w' = A w,
    A = [[-b/2, a/2], [-a/2, b/2]] (a = 2 pi f, b = 2 pi f_so), A^2 = D I, D = (b^2 - a^2) / 4: exp(A t) = C I + S A
    (cosh/sinh when locked, cos/sin when slipping). The spin is f - phi' / 2 pi; returns it and w at the end.
    """
    a, b = 2 * np.pi * f, 2 * np.pi * f_so
    d = 0.25 * (b * b - a * a)
    rt = np.maximum(np.sqrt(np.abs(d)), 1e-9)
    x, lock = tj[:, None] * rt, d > 0  # (M + 1, L)
    c = np.where(lock, np.cosh(x), np.cos(x))[..., None]
    s = (np.where(lock, np.sinh(x), np.sin(x)) / rt)[..., None]
    w = c * w0 + s * (0.5 * (a[:, None] * w0[:, ::-1] - b * w0) * np.array([1.0, -1.0]))  # not normalised
    n, cs = w[..., 0], w[..., 1]
    half = np.arctan2(cs[:-1] * n[1:] - n[:-1] * cs[1:], n[:-1] * n[1:] + cs[:-1] * cs[1:])  # phi/2 per substep
    return f - half / (np.pi * (tj[1] - tj[0])), w[-1] / np.sqrt((w[-1] * w[-1]).sum(-1, keepdims=True))


def _schedule(rng, n: int, dt: float, band, hold) -> np.ndarray:
    """(n,) spin rate [Hz] per period: uniform in band, redrawn after holds uniform in hold [s]."""
    count = int(n * dt / hold[0]) + 2
    edges = np.cumsum(rng.uniform(hold[0], hold[1], count))
    return rng.uniform(band[0], band[1], count + 1)[np.searchsorted(edges, np.arange(n) * dt, side="right")]


def run_case(case: Case, states: bool = False) -> dict:
    """Simulate a case's logs together (deterministic from ``case.seed``); :func:`simulate` writes them.

    Returns (n = the longest log's rows, L logs): ``rows`` (L,), ``t_s`` (n,), ``omega_hz`` (n, L, 3) commands,
    ``p_meas_mm`` (n, L, 3) camera (NaN = lost), ``p_true_mm`` (n, L, 3) true positions at t_i, ``paths``
    [(N, 3) mm], ``picard`` (mean passes per period), ``clamps`` (wall contacts, log-periods).
    """
    reg, rng = case.regime, np.random.default_rng([case.seed, 2])
    dt = reg["dt_s"]
    rows = [int(round(d / dt)) for d in reg["log_durations_s"]]
    n_logs, n = len(rows), max(rows)
    freq = np.stack([_schedule(rng, n, dt, reg["band_hz"], reg["hold_s"]) for _ in range(n_logs)], axis=1)[..., None]
    return _closed_loop(case, rng, freq, [path_points(d) for d in reg["paths"]], rows, states)


def _closed_loop(case: Case, rng, freq: np.ndarray, paths: list, rows: list, states: bool = False) -> dict:
    """Run the closed loop of :func:`run_case` on L logs: spin rate ``freq`` (n, L, 1) [Hz], ``paths`` [(N, 3) mm]
    (L of them), ``rows`` (L,); the command noise and camera errors come from ``rng`` in this order.

    ``states``: also return ``v_true_mm_s`` (n, L, 3), the true velocities at t_i, and ``effect_state`` [n]:
    the plant's thrust-shaping state at t_i (a copy, or None; see :class:`_Plant`); no draw changes.
    """
    reg, dt = case.regime, case.regime["dt_s"]
    n_logs, n = len(rows), max(rows)
    u_noise = rng.normal(0.0, reg["cmd_noise_hz"], (n, n_logs, 3))
    cam = rng.normal(size=(n, n_logs, 3)) * (reg["noise_mm"] * np.asarray(reg["noise_axis"]))
    lost = rng.random((n, n_logs)) < reg["lost_rate"]
    jump = (rng.random((n, n_logs)) < reg["outlier_rate"]) & ~lost  # reflections: 3-15 mm off
    cam += jump[..., None] * unit(rng.normal(size=(n, n_logs, 3))) * rng.uniform(3.0, 15.0, (n, n_logs, 1))
    every_k = int(reg.get("frame_every", 1))  # a camera giving a frame only every k rows (no draw: streams unchanged)
    if every_k > 1:
        lost |= (np.arange(n) % every_k != 0)[:, None]
    any_lost = lost.any(axis=1)

    plant = _Plant(case)
    drift = reg.get("drift")
    if drift is not None:  # between: (1 + change)^log; within: 1 + change t / the log's duration
        span = np.asarray(rows, dtype=float) * dt
        between = drift["kind"] == "between"
        plant.drift(drift["param"], (1.0 + drift["change"]) ** np.arange(n_logs) if between else np.ones(n_logs))
    m = plant.m
    lag = case.hidden("sensor_latency")[1]["delay_periods"] * m if "sensor_latency" in case.effects else None
    hist = np.empty((n * m + 1, n_logs, 3)) if lag is not None else None  # lag [substeps]
    # pure pursuit: the nearest path point from 10 mm behind to 30 mm ahead of the last one; target `ahead` further
    npts = np.array([len(x) for x in paths])
    back, fwd, ahead = round(10 / PATH_DS_MM), round(30 / PATH_DS_MM), round(reg["lookahead_mm"] / PATH_DS_MM)
    ext = np.stack([x[(np.arange(npts.max() + back + max(fwd, ahead) + 1) - back) % len(x)] for x in paths])
    search, lrow, every = np.arange(back + fwd + 1), np.arange(n_logs), max(1, round(0.02 / dt))  # search stride
    p, v = ext[:, back].copy(), np.zeros((n_logs, 3))
    last, idx, heading = p.copy(), np.zeros(n_logs, dtype=int), unit(ext[:, back + 1] - ext[:, back])
    omega, meas, true = (np.empty((n, n_logs, 3)) for _ in range(3))
    vel, held_states = (np.empty((n, n_logs, 3)), []) if states else (None, None)
    clamps = 0
    for i in range(n):
        true[i] = seen = p
        if states:
            vel[i] = v
            held_states.append(None if plant.state is None else np.array(plant.state))
        if lag is not None:  # the camera shows where the swimmer was `lag` substeps ago (at rest before t = 0)
            hist[i * m] = p
            x = i * m - lag
            j = int(math.floor(x))
            seen = hist[0] if x <= 0 else hist[j] + (x - j) * (hist[j + 1] - hist[j])
        meas[i] = z = seen + cam[i]
        last = np.where(lost[i][:, None], last, z) if any_lost[i] else z
        if i % every == 0:
            cand = idx[:, None] + search
            d = ext[lrow[:, None], cand] - last[:, None]
            idx = (cand[lrow, (d * d).sum(2).argmin(1)] - back) % npts
        to = ext[lrow, idx + (back + ahead)] - last
        dist = np.sqrt((to * to).sum(1, keepdims=True))
        heading = to / dist if dist.min() > 1e-9 else np.where(dist > 1e-9, to / np.maximum(dist, 1e-9), heading)
        omega[i] = u = freq[i] * heading + u_noise[i]
        if drift is not None and not between:
            plant.drift(drift["param"], 1.0 + drift["change"] * np.minimum((i + 0.5) * dt / span, 1.0))
        P, V = plant.period(p, v, u, i * dt)
        if hist is not None:
            hist[i * m + 1:(i + 1) * m] = P[1:-1]
        p, v = P[-1], V[-1]
        if abs(p).max() > CLAMP_MM:  # wall contact: stopped there
            over = np.abs(p) > CLAMP_MM
            clamps += int(over.any(axis=1).sum())
            p, v = np.clip(p, -CLAMP_MM, CLAMP_MM), np.where(over & (v * p > 0), 0.0, v)
    meas[lost] = np.nan
    out = {"rows": rows, "t_s": np.arange(n) * dt, "omega_hz": omega, "p_meas_mm": meas, "p_true_mm": true,
           "paths": paths, "picard": float(np.mean(plant.passes)), "clamps": clamps}
    if states:
        out.update(v_true_mm_s=vel, effect_state=held_states)
    return out


def simulate(case: Case, out_dir) -> list[Path]:
    """Write the case's raw logs ``out_dir/log_00.csv``, ... (deterministic from ``case.seed``); returns their paths."""
    res = run_case(case)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for i, nrow in enumerate(res["rows"]):
        files.append(out / f"log_{i:02d}.csv")
        write_log(files[-1], res["t_s"][:nrow] * 1000.0, 2 * np.pi * res["omega_hz"][:nrow, i],
                  res["p_meas_mm"][:nrow, i] / 1000.0)
    return files


def read_schedule(path) -> tuple[np.ndarray, np.ndarray]:
    """(t_s (k,), freq_hz (k,)) of a spin-rate schedule CSV with header ``t_s,freq_hz`` (times increasing from
    >= 0 s, rates >= 0 Hz); ValueError naming the file and the problem otherwise."""
    path = Path(path)
    lines = [x.strip() for x in path.read_text().splitlines() if x.strip()]
    if not lines or [c.strip() for c in lines[0].split(",")] != ["t_s", "freq_hz"]:
        raise ValueError(f"{path}: the first line must be the header 't_s,freq_hz'")
    try:
        table = np.array([[float(c) for c in x.split(",")] for x in lines[1:]], dtype=float).reshape(-1, 2)
    except ValueError as exc:
        raise ValueError(f"{path}: every row must be two numbers t_s,freq_hz ({exc})") from None
    t, f = table[:, 0], table[:, 1]
    if len(t) == 0:
        raise ValueError(f"{path}: no rows after the header")
    if not (np.all(np.isfinite(table)) and t[0] >= 0 and np.all(np.diff(t) > 0) and np.all(f >= 0)):
        raise ValueError(f"{path}: times must increase from >= 0 s and rates be finite and >= 0 Hz")
    return t, f


def experiment_path(case: Case, rng) -> dict:
    """A horizontal circle of radius :data:`EXPERIMENT_RADIUS_MM` about the centre of the case's paths (kept
    within the paths' limits), random orientation, direction and start from ``rng`` (a path description)."""
    pts = np.concatenate([path_points(d, ds=2.0) for d in case.regime["paths"]])
    centre = pts.mean(axis=0)
    room = np.array([PATH_LIMIT_MM - EXPERIMENT_RADIUS_MM] * 2 + [PATH_LIMIT_MM])
    centre = np.clip(centre, -room, room)
    return {"kind": "circle", "radius_mm": EXPERIMENT_RADIUS_MM, "yaw_deg": _u(rng, 0, 360), "tilt_deg": 0.0,
            "tilt_axis_deg": 0.0, "direction": int(rng.choice([-1, 1])), "start": _u(rng, 0, 1),
            "near_wall": False, "offset_mm": centre.tolist()}


def simulate_experiment(case: Case, schedule_csv, out_dir, path: int | dict | None = None,
                        name: str = "log_experiment.csv") -> Path:
    """One more log of the case's plant (same hidden effects and camera regime, fresh stream [case seed, 4])
    with the spin rate of ``schedule_csv`` (``t_s,freq_hz``, each rate held from its row's time to the next;
    before the first row, the first rate). Its length is the schedule's: the last row's time plus the spacing
    before it (one control period for a single row), in control periods of the case. The direction comes
    from the simulator's pure pursuit on the case's path ``path`` (an index into ``regime["paths"]``), on the
    path ``path`` describes (a dict, see :func:`path_points`: the experiment's own path, as a rig would follow
    it) or, by default, on a new circle (:func:`experiment_path`). Writes and returns ``out_dir/name``.
    """
    rng = np.random.default_rng([case.seed, 4])
    t, f = read_schedule(schedule_csv)
    dt = case.regime["dt_s"]
    end = t[-1] + (t[-1] - t[-2] if len(t) > 1 else dt)
    n = max(2, int(round(end / dt)))
    rate = f[np.maximum(np.searchsorted(t, np.arange(n) * dt + 1e-6, side="right") - 1, 0)]  # 1 us: CSV rounding
    if path is None:
        desc = experiment_path(case, rng)
    elif isinstance(path, dict):
        desc = path
    elif 0 <= path < len(case.regime["paths"]):
        desc = case.regime["paths"][path]
    else:
        raise ValueError(f"path {path}: the case has paths 0-{len(case.regime['paths']) - 1}")
    res = _closed_loop(case, rng, rate[:, None, None], [path_points(desc)], [n])
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_log(out / name, res["t_s"] * 1000.0, 2 * np.pi * res["omega_hz"][:, 0], res["p_meas_mm"][:, 0] / 1000.0)
    return out / name


def write_log(path, t_ms, omega_rad_s, p_m) -> None:
    """Raw log CSV: header :data:`HEADER`; t [ms], omega [rad/s], p [m], 12 significant digits; NaN written empty."""
    table = np.column_stack([t_ms, omega_rad_s, p_m])
    body = (("%.12g" + ",%.12g" * 6 + "\n") * len(table)) % tuple(table.ravel().tolist())
    Path(path).write_text(HEADER + "\n" + body.replace("nan", ""))


# ====================================================================== true forms

_FORM = '''"""True form of a blind-bench hidden effect: {effect}{lawtxt} (case {index}, seed {seed}).

Generated by benchmarks/blind_sim.py: the simulator's own law in diagnose units (p mm, v mm/s,
u = omega Hz, force uN, time s), its parameters free and initialised at the truth, and the
truth also a start that holds while the model's own parameters adapt to it{lookback_doc}:
{truth}
"""
{imports}
import numpy as np

from cosim import hookimpl
from cosim_plugins.identify.effect import Effect, EffectParam
{constants}

{laws}


def {fn}({args}, prm):
    return {expr}


EFFECT = Effect(
    name={name!r},
    kind={kind!r},
    params=({params}
    ),
    {role}={fn},
    doc={doc!r},
    starts=({starts},),{lookback}
)


@hookimpl
def cosim_register_effects(register):
    register(EFFECT)
'''

_FLOW = ": drag and lift act on the velocity relative to the water, v - w."
_XYZ = tuple(enumerate("xyz"))
# effect: (kind, law functions copied, the force / transform expression, doc,
#          params as (name, initial value, lo, hi, unit): a truth key, a callable of the truth or a number)
_FORMS = {
    "background_flow": (
        "force", (hydro_terms, flow_force), 'flow_force(v, u, np.array([prm["w_x"], prm["w_y"], 0.0]), prm)',
        "Uniform horizontal water velocity w = (w_x, w_y, 0) [mm/s]" + _FLOW,
        (("w_x", "w_x_mm_s", -50, 50, "mm/s"), ("w_y", "w_y_mm_s", -50, 50, "mm/s"))),
    "rotating_flow": (
        "force", (hydro_terms, flow_force, rotating_flow),
        'flow_force(v, u, rotating_flow(p, prm["x0"], prm["y0"], prm["omega"]), prm)',
        "Water in solid-body rotation at omega [rad/s] about the vertical through (x0, y0) [mm]" + _FLOW,
        (("x0", "x0_mm", -200, 200, "mm"), ("y0", "y0_mm", -200, 200, "mm"), ("omega", "omega_rad_s", -2, 2, "rad/s"))),
    "shear_flow": (
        "force", (hydro_terms, flow_force, shear_flow),
        'flow_force(v, u, shear_flow(p, prm["gamma_x"], prm["gamma_y"]), prm)',
        "Horizontal water velocity growing with height, w = z (gamma_x, gamma_y, 0) [1/s]" + _FLOW,
        (("gamma_x", "gamma_x_per_s", -2, 2, "1/s"), ("gamma_y", "gamma_y_per_s", -2, 2, "1/s"))),
    "wall_drag": (
        "force", (wall_distance, wall_gain), '-(prm["c"] * wall_gain(wall_distance(p), LAW, prm["ell"]))[:, None] * v',
        "Extra linear drag -c g(d) v, d the distance from the centre to the nearest wall [mm], g = ell / (d + ell) "
        "('1/d'), exp(-d / ell) ('exp') or (ell / (d + ell))^2 ('1/d^2'); c [uN s/mm], ell [mm].",
        (("c", "c_uNs_mm", 0, lambda t: 20 * t["c_uNs_mm"], "uN s/mm"), ("ell", "ell_mm", 0.5, 60, "mm"))),
    "step_out": (
        "force", (adler_mean_spin, step_out_loss), 'step_out_loss(u, prm["k"], prm["f_so"])',
        "Step-out: the thrust lost, -k (f - mean spin) u_hat, the mean spin f - sqrt(f^2 - f_so^2) above the "
        "step-out frequency f_so [Hz] (Adler).", (("f_so", "f_so_hz", 0.5, 100, "Hz"),)),
    "gradient_force": (
        "force", (gradient_force,), 'gradient_force(p, unit(u), [prm["b_x"], prm["b_y"], prm["b_z"]], prm["mB"])',
        "Turn-averaged magnetic gradient force m grad|B| of three axisymmetric coil pairs (|B| quadratic near the "
        "centre): b = m B0 beta [uN/mm] per pair, mB = m B0 [uN mm].",
        tuple((f"b_{a}", lambda t, i=i: t["b_uN_mm"][i], -5, 5, "uN/mm") for i, a in _XYZ)
        + (("mB", "mB_uNmm", lambda t: t["mB_uNmm"] / 100, lambda t: t["mB_uNmm"] * 100, "uN mm"),)),
    "anisotropic_drag": (
        "force", (), '-prm["c"] * (v - (v * unit(u)).sum(1, keepdims=True) * unit(u))',
        "Extra drag -c v_perp on the velocity across the body (spin) axis; c [uN s/mm].",
        (("c", "c_uNs_mm", -2, 5, "uN s/mm"),)),
    "quadratic_drag": (
        "force", (), '-prm["c"] * np.sqrt((v * v).sum(1, keepdims=True)) * v',
        "Quadratic drag -c |v| v; c [uN s^2/mm^2].",
        (("c", "c_uNs2_mm2", 0, lambda t: 20 * t["c_uNs2_mm2"], "uN s^2/mm^2"),)),
    "thrust_nonuniform": (
        "force", (), 'prm["k"] * (p @ np.array([prm["g_x"], prm["g_y"], prm["g_z"]]))[:, None] * u',
        "Thrust gain varying with position, k (1 + g . p) omega: the extra force k (g . p) omega; g [1/mm].",
        tuple((f"g_{a}", lambda t, i=i: t["g_per_mm"][i], -0.1, 0.1, "1/mm") for i, a in _XYZ)),
    "actuation_lag": (
        "input", (lag_mean,), 'lag_mean(u, dt_s, prm["tau"])',
        "The field's rotation vector follows the command through a first-order lag tau [s] (period means).",
        (("tau", "tau_s", 0, 2, "s"),)),
    "heading_lag": (
        "input", (heading_mean,), 'heading_mean(u, dt_s, prm["tau"])',
        "The body axis relaxes on the sphere towards the commanded axis with time constant tau [s]; thrust along "
        "it at the commanded spin rate (period means).", (("tau", "tau_s", 0, 2, "s"),)),
    "sensor_latency": (
        "sensor", (delayed,), 'delayed(traj, prm["delay"])',
        "The camera reports where the swimmer was delay [control periods] earlier (linear interpolation).",
        (("delay", "delay_periods", 0, 20, "periods"),)),
}


def _true_form(effect, law, truth, index, seed) -> str | None:
    """Source of an effect file registering ``true_<effect>``: the simulator's law, parameters at the truth.

    None without an effect and for "periodic": its force depends on time, which a force effect is not given
    (the bench uses the simulator's true residual instead).
    """
    if effect is None or effect == "periodic":
        return None
    kind, fns, expr, doc, spec = _FORMS[effect]

    def value(x):
        return float(x(truth) if callable(x) else truth[x] if isinstance(x, str) else x)

    params = "".join(f"\n        EffectParam({name!r}, {value(init)!r}, {value(lo)!r}, {value(hi)!r}, {unt!r}),"
                     for name, init, lo, hi, unt in spec)
    laws = "\n\n\n".join(inspect.getsource(f).rstrip() for f in (unit, *fns))
    consts = {"TANK_HALF_MM": TANK_HALF_MM, "GRADIENT_PHASES": GRADIENT_PHASES, "LAW": law}
    constants = "".join(f"\n{k} = {v!r}" for k, v in consts.items() if k in laws + expr)
    shown = ", ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}" for k, v in truth.items())
    fn, args = {"force": ("true_force", "p, v, u"), "input": ("true_transform", "u, dt_s"),
                "sensor": ("true_transform", "traj, dt_s")}[kind]
    starts = "{" + ", ".join(f"{name!r}: {value(init)!r}" for name, init, *_ in spec) + "}"
    # a delay reads the path before each window (the effect contract's lookback), not an extrapolation
    delay = effect == "sensor_latency"
    return _FORM.format(starts=starts, imports="\nimport math\n" if delay else "",
                        lookback="\n    lookback=lambda prm: math.ceil(prm[\"delay\"] - 1e-9)," if delay else "",
                        lookback_doc="; the rollouts start ceil(delay) rows before each window" if delay else "",
                        effect=effect, lawtxt=f" ({law})" if law else "", index=index, seed=seed,
                        truth=textwrap.fill(shown, 96), constants=constants + "\n" if constants else "", laws=laws,
                        fn=fn, args=args, expr=expr, name=f"true_{effect}", kind=kind, params=params,
                        role="force" if kind == "force" else "transform", doc=doc)

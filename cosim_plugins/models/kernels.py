"""The physical model's per-column arithmetic, compiled (numba): the angle terms of Eq. 2-5, the centring force,
the hydrodynamic force and its change in moving water, and one pass of the exponential integrator.

The rollouts that fitting and diagnosis run step a few hundred columns at a time, where numpy's cost per call,
not the arithmetic, dominates: each function here is one loop over the columns. Arrays are component-major,
(3, n) [any memory layout], one column per sample; units as in :mod:`cosim_plugins.models.physical` (p mm,
v mm/s, u Hz, forces uN). The arithmetic is written in the order of the formulas in that module's doc.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: below this |v| |omega| [mm/s Hz] the angle of attack is taken as 0 (no lift, no sin(alpha) drag)
ANGLE_EPS = 1e-12


@njit(cache=True)
def _angles(vx, vy, vz, ux, uy, uz):
    """(sin(alpha), a, b) of one sample: sin(2 alpha) |v| v_perp = a u - b v, with alpha the angle between the
    velocity v [mm/s] and the spin omega = u [Hz] (0 when either vanishes): 2 cos (|v| u_hat - cos v)."""
    vn = math.sqrt(vx * vx + vy * vy + vz * vz)
    wn = math.sqrt(ux * ux + uy * uy + uz * uz)
    den = vn * wn
    cos, c2 = 1.0, 0.0
    if den > ANGLE_EPS:
        cos = min(max((ux * vx + uy * vy + uz * vz) / den, -1.0), 1.0)
        c2 = 2.0 * cos
    return math.sqrt(1.0 - cos * cos), c2 * vn / (wn if wn > ANGLE_EPS else 1.0), c2 * cos


@njit(cache=True)
def _drag_lift(s, a, b, uk, vk, cd0, cd1, cl0):
    """One component [uN] of -(Cd0 sin(alpha) + Cd1) v + Cl0 sin(2 alpha) |v| v_perp, from :func:`_angles`'
    (s, a, b) and that component of u [Hz] and v [mm/s]."""
    return cl0 * (a * uk - b * vk) - (cd0 * s + cd1) * vk


@njit(cache=True)
def angle_terms(v, u):
    """(sin(alpha) (n,), sin(2 alpha) |v| v_perp (3, n) [mm/s]) at velocities v and commands u (3, n)."""
    n = v.shape[1]
    sin_a, lift = np.empty(n), np.empty((3, n))
    for i in range(n):
        s, a, b = _angles(v[0, i], v[1, i], v[2, i], u[0, i], u[1, i], u[2, i])
        sin_a[i] = s
        for k in range(3):
            lift[k, i] = a * u[k, i] - b * v[k, i]
    return sin_a, lift


@njit(cache=True)
def centring(p, pb_norm_mm):
    """sin(pi |p| / |P_b|) c_hat (3, n) [-] at positions p (3, n) [mm] (c_hat = -p / |p|; 0 at the centre)."""
    n = p.shape[1]
    out = np.empty((3, n))
    for i in range(n):
        pn = math.sqrt(p[0, i] * p[0, i] + p[1, i] * p[1, i] + p[2, i] * p[2, i])
        c = -math.sin((math.pi / pb_norm_mm) * pn) / (pn if pn > ANGLE_EPS else 1.0)
        for k in range(3):
            out[k, i] = p[k, i] * c
    return out


@njit(cache=True)
def hydrodynamic(v, u, cd0, cd1, cl0):
    """-(Cd0 sin(alpha) + Cd1) v + Cl0 sin(2 alpha) |v| v_perp (3, n) [uN] at v [mm/s], u [Hz] (3, n)."""
    n = v.shape[1]
    out = np.empty((3, n))
    for i in range(n):
        s, a, b = _angles(v[0, i], v[1, i], v[2, i], u[0, i], u[1, i], u[2, i])
        for k in range(3):
            out[k, i] = _drag_lift(s, a, b, u[k, i], v[k, i], cd0, cd1, cl0)
    return out


@njit(cache=True)
def flow_change(v, w, u, cd0, cd1, cl0):
    """H(v - w) - H(v) (3, n) [uN]: the change of :func:`hydrodynamic` when the water moves at w (3, 1) or
    (3, n) [mm/s]; v [mm/s], u [Hz] (3, n)."""
    n = v.shape[1]
    per = w.shape[1] > 1
    out, r = np.empty((3, n)), np.empty(3)
    for i in range(n):
        j = i if per else 0
        for k in range(3):
            r[k] = v[k, i] - w[k, j]
        ux, uy, uz = u[0, i], u[1, i], u[2, i]
        s1, a1, b1 = _angles(r[0], r[1], r[2], ux, uy, uz)
        s0, a0, b0 = _angles(v[0, i], v[1, i], v[2, i], ux, uy, uz)
        for k in range(3):
            out[k, i] = (_drag_lift(s1, a1, b1, u[k, i], r[k], cd0, cd1, cl0)
                         - _drag_lift(s0, a0, b0, u[k, i], v[k, i], cd0, cd1, cl0))
    return out


@njit(cache=True)
def exp_pass(x, u, drive, cent, v_geo, th, sh, h, forces=None, slowing=None):
    """One pass of the exponential integrator: the new state (6, n) from x (6, n) [mm, mm/s].

    Held over the step: ``drive`` (3, n) [uN] (thrust and the vertical force), Fmax ``cent`` (``cent``:
    :func:`centring`), the lift and the extra terms' ``forces`` (3, n) [uN] or None; the angle terms are taken
    at ``v_geo`` (3, n) [mm/s] and the command u (3, n) [Hz]. ``th`` (6, m): the base parameters k, Cd0, Cd1,
    Cl0, Fvs, Fmax per column (m = n) or shared (m = 1). ``slowing`` (n,) or None: the extra terms' drag
    power -(F(v) - F(0)) . v [uN mm/s], which joins the exact decay at rate max(slowing, 0) / |v_geo|^2 and is
    given back to the held forces. ``sh`` = 1000 h / m [mm/(uN s)], h [s]:
    v' = exp(-sh drag) v + sh phi1(sh drag) a, p' = p + h v'.
    """
    n = x.shape[1]
    per = th.shape[1] > 1
    out = np.empty((6, n))
    a = np.empty(3)
    for i in range(n):
        j = i if per else 0
        gx, gy, gz = v_geo[0, i], v_geo[1, i], v_geo[2, i]
        s, la, lb = _angles(gx, gy, gz, u[0, i], u[1, i], u[2, i])
        for k in range(3):
            a[k] = drive[k, i] + th[3, j] * (la * u[k, i] - lb * v_geo[k, i]) + th[5, j] * cent[k, i]
        drag = th[1, j] * s + th[2, j]
        if forces is not None:
            for k in range(3):
                a[k] += forces[k, i]
        if slowing is not None:
            extra = max(slowing[i], 0.0) / max(gx * gx + gy * gy + gz * gz, 1e-12)
            drag += extra
            for k in range(3):
                a[k] += extra * v_geo[k, i]
        z = sh * drag + 1e-300  # exp(-z) = 1 + em, phi1(z) = -em / z with em = expm1(-z) (z != 0)
        em = math.expm1(-z)
        g = sh * em / z
        for k in range(3):
            vk = (1.0 + em) * x[3 + k, i] - g * a[k]
            out[3 + k, i] = vk
            out[k, i] = vk * h + x[k, i]
    return out

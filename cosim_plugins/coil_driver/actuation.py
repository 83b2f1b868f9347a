"""The coil driver's own actuation model: field per ampere and coil impedance.

Six coils on the cube faces +x, -x, +y, -y, +z, -z; positive current in a
coil makes field along +x, +y or +z at the centre. The driver plans with
the centre's field-per-ampere matrix (a lab calibrates it with a gauss
meter) and each coil's series RLC impedance; the plant's true field varies
over the workspace, which the controllers must tolerate.
"""

from __future__ import annotations

import math

import numpy as np

from cosim_plugins.vec3 import Vec3, add, cross, div, dot, length, scale, sub

MU0 = 4e-7 * np.pi


def loop_field_on_axis_t_per_a(turns: float, r_inner_m: float, r_outer_m: float, z_near_m: float,
                               z_far_m: float, n: int = 8) -> float:
    """Axial field [T/A] at distance z from a thick coil, averaged over its winding cross-section.

    Each turn is a loop of radius r at distance z: ``B = mu0 r^2 / (2 (r^2 + z^2)^1.5)``;
    turns are spread evenly over ``[r_inner, r_outer] x [z_near, z_far]``.
    """
    r = np.linspace(r_inner_m, r_outer_m, n)[:, None]
    z = np.linspace(z_near_m, z_far_m, n)[None, :]
    return float(turns * np.mean(MU0 * r**2 / (2 * (r**2 + z**2) ** 1.5)))


def centre_matrix(field_per_amp_t: float) -> np.ndarray:
    """Field at the centre per ampere of each coil, shape (3, 6) [T/A]."""
    m = np.zeros((3, 6))
    for i in range(6):
        m[i // 2, i] = field_per_amp_t
    return m


def impedance_ohm(freq_hz: float, r_ohm: float, l_h: float, c_f: float) -> complex:
    """Series RLC impedance at ``freq_hz`` (a capacitor blocks DC: infinite at 0 Hz)."""
    w = 2 * np.pi * freq_hz
    if w == 0.0:
        return complex(r_ohm, np.inf)
    return complex(r_ohm, w * l_h - 1.0 / (w * c_f))


#: Fallback directions for :func:`plane_start`, tried in order.
_FALLBACKS: tuple[Vec3, ...] = ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0))


def plane_start(n: Vec3, towards: Vec3 | None) -> Vec3:
    """Unit vector perpendicular to unit ``n``: ``towards`` projected onto the plane, else any."""
    for candidate in (towards, *_FALLBACKS):
        if candidate is None:
            continue
        v = sub(candidate, scale(n, dot(candidate, n)))
        size = length(v)
        if size > 1e-6:
            return div(v, size)
    raise ValueError("no perpendicular found")  # unreachable for a unit n


def rotating_field_phasor(n: Vec3, e1: Vec3, amplitude_t: float) -> tuple[complex, complex, complex]:
    """Complex field phasor (x, y, z) of a field of ``amplitude_t`` [T] rotating about unit ``n``.

    ``Re(phasor * exp(j theta)) = A (e1 cos(theta) + e2 sin(theta))`` with
    ``e2 = n x e1``: the field points along ``e1`` at ``theta = 0`` and turns
    right-handed about ``n``.
    """
    e2 = cross(n, e1)
    return (amplitude_t * (e1[0] - 1j * e2[0]), amplitude_t * (e1[1] - 1j * e2[1]),
            amplitude_t * (e1[2] - 1j * e2[2]))


def field_direction(n: Vec3, e1: Vec3, theta: float) -> Vec3:
    """Unit field direction at rotation angle ``theta`` of the field defined as above."""
    return add(scale(e1, math.cos(theta)), scale(cross(n, e1), math.sin(theta)))

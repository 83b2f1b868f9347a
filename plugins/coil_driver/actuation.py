"""The coil driver's own actuation model: field per ampere and coil impedance.

Six coils on the cube faces +x, -x, +y, -y, +z, -z; positive current in a
coil makes field along +x, +y or +z at the centre. The driver plans with
the centre's field-per-ampere matrix (a lab calibrates it with a gauss
meter) and each coil's series RLC impedance; the plant's true field varies
over the workspace, which the controllers must tolerate.
"""

from __future__ import annotations

import numpy as np

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


def rotating_field_phasor(omega_rad_s: np.ndarray, amplitude_t: float) -> np.ndarray:
    """Complex field phasor (3,) of a field rotating about ``omega`` (right-handed), amplitude in T.

    ``B(t) = Re(phasor * exp(j 2 pi f t)) = A (e1 cos(2 pi f t) + e2 sin(2 pi f t))``
    with ``(e1, e2, omega_hat)`` a right-handed orthonormal frame.
    """
    nx, ny, nz = omega_rad_s / np.sqrt(omega_rad_s @ omega_rad_s)
    if abs(nz) < 0.9:  # e1 = z x n, normalised
        e1 = np.array([-ny, nx, 0.0]) / np.hypot(nx, ny)
    else:  # e1 = x x n, normalised
        e1 = np.array([0.0, -nz, ny]) / np.hypot(ny, nz)
    e2 = np.array([ny * e1[2] - nz * e1[1], nz * e1[0] - nx * e1[2], nx * e1[1] - ny * e1[0]])  # n x e1
    return amplitude_t * (e1 - 1j * e2)

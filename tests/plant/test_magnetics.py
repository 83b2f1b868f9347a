"""Coil field, its gradient and the RLC drive."""

from __future__ import annotations

import ctypes
import math
import zipfile

import numpy as np
import pytest
from scipy.special import ellipe, ellipk

from cosim_plugins.effects.forces import GRADIENT_FORCE


@pytest.fixture(scope="module")
def coil_fields(plant_fmu, tmp_path_factory):
    """The FMU's own coil-field routine (test hook exported by the binary)."""
    d = tmp_path_factory.mktemp("so")
    with zipfile.ZipFile(plant_fmu) as zf:
        name = next(n for n in zf.namelist() if n.startswith("binaries/"))
        zf.extract(name, d)
    lib = ctypes.CDLL(str(d / name))
    fn = lib.swimmer_plant_coil_fields
    dbl = ctypes.c_double
    fn.argtypes = [dbl] * 5 + [ctypes.POINTER(dbl)] * 3
    fn.restype = None

    def call(p, offset_m=0.150):
        """(G (6, 3) [T/A], J (6, 3, 3) [T/(A m)]) of the six coils at p [m], each pair offset_m from the centre."""
        P, G, J = (dbl * 3)(*p), (dbl * 18)(), (dbl * 54)()
        fn(795.0, 0.180, 0.215, 0.040, offset_m, P, G, J)
        return np.array(G).reshape(6, 3), np.array(J).reshape(6, 3, 3)

    return call


def reference_coil_field(p, coil, n=12):
    """Field per ampere [T/A] of coil 0..5 at p, fine Gauss quadrature (scipy)."""
    k, sign = coil // 2, (1 if coil % 2 == 0 else -1)
    e = np.eye(3)[k]
    d = np.asarray(p, float) - sign * 0.150 * e
    zl = d @ e
    perp = d - zl * e
    rho = np.linalg.norm(perp)
    x, w = np.polynomial.legendre.leggauss(n)
    B = np.zeros(3)
    for xi, wi in zip(x, w):
        a = 0.1975 + 0.0175 * xi
        for xj, wj in zip(x, w):
            z = zl - 0.020 * xj
            s = a * a + rho * rho + z * z
            al2, be2 = s - 2 * a * rho, s + 2 * a * rho
            m = 4 * a * rho / be2
            K, E = ellipk(m), ellipe(m)
            c = 4e-7 * 795 * wi * wj / 4           # mu0/pi * turns * weight
            bz = c / (2 * al2 * math.sqrt(be2)) * ((a * a - rho * rho - z * z) * E + al2 * K)
            B += bz * e
            if rho > 0:
                br = c * z / (2 * al2 * math.sqrt(be2) * rho) * (s * E - al2 * K)
                B += br * perp / rho
    return B


def test_centre_field_per_ampere_of_a_pair(sim, helpers):
    """Pair at resonance, actuation lag off: B_x / I at the centre vs the analytic loop
    formula at the mean radius (0.5 %) and the exact thick-winding integral (0.05 %)."""
    f0 = 1 / (2 * math.pi * math.sqrt(helpers.L_COIL * helpers.C_COIL))
    T = 0.02
    phase = -2 * math.pi * f0 * T        # current peaks at the end of the step
    drive = {
        "coil_voltage_amp": np.array([10.0, 10.0, 0, 0, 0, 0]),
        "coil_voltage_phase": np.full(6, phase),
        "drive_freq": np.array(f0),
    }
    r = sim.run({"actuation_lag_on": False}, drive, T=T)
    amp = r["coil_current_amp"][-1]
    assert amp[0] == pytest.approx(10.0 / helpers.R_COIL, rel=1e-9)
    per_amp = r["field"][-1][0] / amp[0]
    a, z = 0.5 * (helpers.R_IN + helpers.R_OUT), helpers.HALF
    loop = 2 * helpers.MU0 * helpers.TURNS * a * a / (2 * (a * a + z * z) ** 1.5)
    assert per_amp == pytest.approx(loop, rel=5e-3)
    assert per_amp == pytest.approx(helpers.PAIR_FIELD_PER_AMP, rel=5e-4)
    assert per_amp == pytest.approx(2.556e-3, rel=1e-3)


@pytest.mark.parametrize("p", [(0, 0, 0), (0.075, 0.075, 0.075), (-0.075, 0.07, -0.02), (0.0, 0.0, -0.075)])
def test_field_within_one_percent_inside_tank(coil_fields, p):
    G, _ = coil_fields(p)
    for i in range(6):
        ref = reference_coil_field(p, i)
        assert np.linalg.norm(G[i] - ref) <= 1e-3 * np.linalg.norm(ref)   # 0.1 % (spec: 1 %)


@pytest.mark.parametrize("p", [(0.0, 0.0, 0.0), (0.03, -0.05, 0.07), (1e-7, 0.02, 0.0)])
def test_gradient_is_consistent_curl_and_divergence_free(coil_fields, p):
    G, J = coil_fields(p)
    h = 1e-5
    for b in range(3):
        dp = np.zeros(3)
        dp[b] = h
        fd = (coil_fields(np.add(p, dp))[0] - coil_fields(np.subtract(p, dp))[0]) / (2 * h)
        assert np.allclose(J[:, :, b], fd, rtol=0, atol=1e-6 * np.abs(J).max())
    assert np.allclose(J, np.swapaxes(J, 1, 2), atol=1e-12)            # curl B = 0
    assert np.allclose(np.trace(J, axis1=1, axis2=2), 0, atol=1e-12)   # div B = 0


def test_current_amplitude_peaks_at_rlc_resonance(sim, helpers):
    """10 V on coil 1; after the transient the current amplitude follows |V/Z(f)|
    (2 %) and peaks at f0 = 1/(2 pi sqrt(LC)) = 11.97 Hz."""
    f0 = 1 / (2 * math.pi * math.sqrt(helpers.L_COIL * helpers.C_COIL))
    freqs = np.arange(6.0, 20.01, 0.5)
    amps = []
    for f in freqs:
        drive = helpers.zero_drive()
        drive["coil_voltage_amp"] = np.array([10.0, 0, 0, 0, 0, 0])
        drive["drive_freq"] = np.array(f)
        r = sim.run({}, drive, T=1.0)
        amps.append(r["coil_current_amp"][-10:, 0].mean())
        assert amps[-1] == pytest.approx(10.0 / abs(helpers.impedance(f)), rel=0.02)
    assert abs(freqs[int(np.argmax(amps))] - f0) <= 0.5
    assert max(amps) == pytest.approx(10.0 / helpers.R_COIL, rel=0.02)


def test_current_lags_by_l_over_r(sim, helpers):
    """Step in voltage amplitude at resonance: the envelope rises as 1 - exp(-t R/2L)."""
    f0 = 1 / (2 * math.pi * math.sqrt(helpers.L_COIL * helpers.C_COIL))
    drive = helpers.zero_drive()
    drive["coil_voltage_amp"] = np.array([10.0, 0, 0, 0, 0, 0])
    drive["drive_freq"] = np.array(f0)
    lag = sim.run({}, drive, T=0.4)
    instant = sim.run({"actuation_lag_on": False}, drive, T=0.4)
    tau = 2 * helpers.L_COIL / helpers.R_COIL        # envelope time constant at resonance
    k = int(round(tau / 0.02))
    ratio = lag["coil_current_amp"][k, 0] / instant["coil_current_amp"][k, 0]
    assert ratio == pytest.approx(1 - math.exp(-lag["t"][k] / tau), abs=0.05)
    assert instant["coil_current_amp"][1, 0] == pytest.approx(10 / helpers.R_COIL, rel=1e-9)


def _pair_centre_fields(coil_fields, offsets_m):
    """(3,) [T/A]: pair k's field along its axis at the centre, its coils offsets_m[k] [m] from it."""
    centre = [coil_fields((0.0, 0.0, 0.0), o)[0] for o in offsets_m]
    return np.array([centre[k][2 * k, k] + centre[k][2 * k + 1, k] for k in range(3)])


def _turn_averaged_force(coil_fields, p, axis, offsets_m, per_unit, phases=24):
    """m grad|B| per unit m B0 [1/m], averaged over a turn of a unit field rotating about ``axis`` (3,) at p [m]:
    pair k of the coils at offsets_m[k] [m] from the centre, its current over per_unit[k] (its centre field per
    ampere, :func:`_pair_centre_fields`) for a unit centre field."""
    fields = [coil_fields(p, o) for o in offsets_m]
    G = np.array([fields[k][0][2 * k + i] for k in range(3) for i in (0, 1)])   # (6, 3)
    J = np.array([fields[k][1][2 * k + i] for k in range(3) for i in (0, 1)])   # (6, 3, 3)
    e1 = np.cross(axis, [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    force = np.zeros(3)
    for th in (np.arange(phases) + 0.5) * np.pi / phases:  # F(t + pi) = F(t): half a turn
        current = np.repeat((math.cos(th) * e1 + math.sin(th) * e2) / per_unit, 2)
        B, grad = current @ G, np.einsum("i,iab->ab", current, J)
        force += grad.T @ B / np.linalg.norm(B)
    return force / phases


def _coil_samples(coil_fields, offsets_m, half_mm, n, seed, phases=24):
    """(p (n, 3) [mm] uniform within +-half_mm, unit rotation axes (n, 3), the coils' turn-averaged m grad|B| per
    unit m B0 at them, flattened (3 n,) [1/mm]): pair k's coils offsets_m[k] [m] from the centre."""
    rng = np.random.default_rng(seed)
    p_mm = rng.uniform(-half_mm, half_mm, (n, 3))
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    per_unit = _pair_centre_fields(coil_fields, offsets_m)
    y = np.concatenate([_turn_averaged_force(coil_fields, p * 1e-3, a, offsets_m, per_unit, phases) * 1e-3
                        for p, a in zip(p_mm, axes)])
    return p_mm, axes, y


def test_the_gradient_force_cross_terms_follow_the_pairs_gradients(coil_fields):
    """Three pairs at different spacings (so three different gradients): within 10 mm of the centre the coils'
    turn-averaged m grad|B| is the library's three-coefficient form (cross terms u_j u_k (b_j + b_k)), which fits
    as closely as one with the cross coefficients free, and the free fit's cross coefficients come out b_j + b_k."""
    p_mm, axes, y = _coil_samples(coil_fields, (0.12, 0.15, 0.18), 10.0, 300, seed=7)
    unit_b = [{n: float(n == m) for n in ("b_x", "b_y", "b_z")} for m in ("b_x", "b_y", "b_z")]
    tied = np.stack([GRADIENT_FORCE.force(p_mm, None, 8.0 * axes, prm).ravel() for prm in unit_b], 1)
    b, *_ = np.linalg.lstsq(tied, y, rcond=None)
    misfit_tied = np.linalg.norm(y - tied @ b) / np.linalg.norm(y)
    # the same pairs with the three cross coefficients free: (1 - u_k^2) (2 x_k e_k - x_j e_j - x_l e_l) and
    # u_j u_k (x_k e_j + x_j e_k)
    free = []
    for k in range(3):
        shape = np.full(3, -1.0)
        shape[k] = 2.0
        free.append(((1.0 - axes[:, k:k + 1] ** 2) * p_mm * shape).ravel())
    for j, k in ((0, 1), (0, 2), (1, 2)):
        col = np.zeros_like(p_mm)
        col[:, j], col[:, k] = axes[:, j] * axes[:, k] * p_mm[:, k], axes[:, j] * axes[:, k] * p_mm[:, j]
        free.append(col.ravel())
    free = np.stack(free, 1)
    x, *_ = np.linalg.lstsq(free, y, rcond=None)
    misfit_free = np.linalg.norm(y - free @ x) / np.linalg.norm(y)
    assert np.ptp(b) > 0.3 * np.abs(b).max(), b  # the three pairs' gradients do differ
    assert misfit_tied < 0.01 and misfit_tied < misfit_free + 1e-3, (misfit_tied, misfit_free)
    assert np.allclose(x[:3], b, rtol=0, atol=0.01 * np.abs(b).max())
    assert np.allclose(x[3:], [b[0] + b[1], b[0] + b[2], b[1] + b[2]], rtol=0, atol=0.02 * np.abs(b).max()), x


def test_the_gradient_force_bends_with_the_field_strength_far_from_the_centre(coil_fields):
    """Pairs far from the Helmholtz spacing (|B| changes by 3-5 % at 40 mm): over +-40 mm the coils' turn-averaged
    m grad|B| (per unit m B0, so curv = 1 / (m B0) is 1) is fitted better by the law with the field's strength
    in it than by its near-centre line, and the fit reads curv near 1; at curv = 0 the law is the line."""
    from scipy.optimize import least_squares

    p_mm, axes, y = _coil_samples(coil_fields, (0.05, 0.25, 0.07), 40.0, 150, seed=11, phases=12)

    def law(x):
        return GRADIENT_FORCE.force(p_mm, None, 8.0 * axes, dict(zip(("b_x", "b_y", "b_z", "curv"), x))).ravel()

    line = least_squares(lambda x: law([*x, 0.0]) - y, np.zeros(3), x_scale=1e-3)
    bent = least_squares(lambda x: law(x) - y, [*line.x, 0.0], bounds=([-1.0] * 3 + [0.0], [1.0] * 3 + [1e3]),
                         x_scale=[1e-3, 1e-3, 1e-3, 1.0])
    misfit_line, misfit_bent = (np.linalg.norm(f.fun) / np.linalg.norm(y) for f in (line, bent))
    assert misfit_bent < 0.8 * misfit_line, (misfit_line, misfit_bent)
    assert 0.5 < bent.x[3] < 1.5, bent.x
    near = {"b_x": 0.02, "b_y": -0.01, "b_z": 0.03}
    curved_at_zero = GRADIENT_FORCE.force(p_mm, None, 8.0 * axes, {**near, "curv": 0.0})
    tiny = GRADIENT_FORCE.force(p_mm, None, 8.0 * axes, {**near, "curv": 1e-9})
    assert np.allclose(curved_at_zero, tiny, rtol=0, atol=1e-6 * np.abs(tiny).max())

"""The per-tick hot paths on Python floats compute, bit for bit, what their numpy formulations computed.

The camera, the PI controller, pure pursuit and the coil driver work on
three (or six) Python floats instead of small arrays (numpy's per-call cost
was most of theirs). Same operations in the same order give the same
doubles; these tests hold each against the vectorised formulation it
replaced, on random inputs and on the awkward ones (zeros of either sign,
halves, NaN, windows across a closed path's start), comparing bits where
the formulation was elementwise. Where it went through the BLAS (a dot
product, a norm) the comparison is to rounding: the BLAS picks its kernel by
the CPU, and on an AVX-512 machine its fused multiply-adds differ from the
Python floats in the last bit (a run stays byte-identical to itself: every
process runs the same float paths).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim_plugins import vec3
from cosim_plugins.camera.emulator import _rint
from cosim_plugins.coil_driver.actuation import impedance_ohm
from cosim_plugins.coil_driver.interlocks import Limits, ThermalBudget, limit_scale
from cosim_plugins.coil_driver.inverse import InverseMagnetics
from cosim_plugins.controllers.pi import PIController
from cosim_plugins.controllers.pure_pursuit import WINDOW_AHEAD, WINDOW_BACK, PurePursuit
from cosim_plugins.paths.shapes import Circle, Helix, Racetrack

DT = 0.02


def same_bits(a, b) -> bool:
    """Equal arrays, NaN where NaN, and zeros of the same sign."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


def same_to_rounding(a, b, rel: float = 1e-12) -> bool:
    """Equal shapes, NaN where NaN, and every element within ``rel`` of the largest magnitude of ``b``."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.shape != b.shape or not np.array_equal(np.isnan(a), np.isnan(b)):
        return False
    ok = ~np.isnan(b)
    scale = float(np.max(np.abs(b[ok]), initial=0.0))
    return bool(np.all(np.abs(a[ok] - b[ok]) <= rel * scale))


def same_angle_to_rounding(a, b, rel: float = 1e-12) -> bool:
    """Angles [rad] equal to rounding modulo 2 pi (a rounding at the branch cut moves one by 2 pi)."""
    d = np.angle(np.exp(1j * (np.asarray(a, dtype=float) - np.asarray(b, dtype=float))))
    return bool(np.all(np.abs(d) <= rel * 2 * math.pi))


def vectors(rng, n: int) -> np.ndarray:
    """(n, 3) vectors over nine decades, some with exact zeros of either sign."""
    v = rng.standard_normal((n, 3)) * 10.0 ** rng.uniform(-6, 3, (n, 1))
    v[rng.random((n, 3)) < 0.1] = 0.0
    v[rng.random((n, 3)) < 0.05] = -0.0
    return v


# ---------------------------------------------------------------- vec3


def test_vec3_matches_numpy_on_3_vectors():
    rng = np.random.default_rng(1)
    a_all, b_all = vectors(rng, 2000), vectors(rng, 2000)
    for a, b in zip(a_all, b_all):
        ta, tb = tuple(a.tolist()), tuple(b.tolist())
        k = float(b[0]) or 1.5
        assert abs(vec3.dot(ta, tb) - a.dot(b)) <= 4e-16 * np.abs(a).dot(np.abs(b))  # a few roundings of the terms
        assert same_to_rounding(vec3.length(ta), vec3.norm(a), rel=4e-16)
        assert same_bits(vec3.cross(ta, tb), np.cross(a, b))
        assert same_bits(vec3.add(ta, tb), a + b)
        assert same_bits(vec3.sub(ta, tb), a - b)
        assert same_bits(vec3.scale(ta, k), k * a)
        assert same_bits(vec3.div(ta, k), a / k)
    assert vec3.all_finite(np.array([1.0, 2.0, 3.0])) and vec3.all_finite((1.0, -0.0, 1e308))
    assert not vec3.all_finite(np.array([1.0, np.nan, 3.0])) and not vec3.all_finite((1.0, 2.0, -math.inf))


# ---------------------------------------------------------------- camera


def test_rint_is_numpys_rint_for_one_float():
    rng = np.random.default_rng(2)
    values = [*(rng.standard_normal(5000) * 300).tolist(), 0.5, 1.5, 2.5, -0.5, -1.5, -2.5, -0.3, -0.0, 0.0,
              0.49999999999999994, 2.0**53 + 1, -(2.0**60), math.nan, math.inf, -math.inf]
    assert same_bits([_rint(x) for x in values], np.rint(values))


def test_one_standard_normal_call_is_the_stream_of_the_two_normal_calls():
    sd = 0.5 * 0.19e-3
    ours, theirs = np.random.default_rng(7), np.random.default_rng(7)
    for _ in range(200):
        assert same_bits(ours.random(3), theirs.random(3))
        z = ours.standard_normal(7).tolist()
        assert same_bits([0.0 + sd * v for v in z[:4]], theirs.normal(0.0, sd, size=4))
        assert same_bits([0.0 + 1.0 * v for v in z[4:]], theirs.normal(size=3))


# ---------------------------------------------------------------- pure pursuit


def closest_reference(pts: np.ndarray, closed: bool, position: np.ndarray, start: int, stop: int):
    """The window search as an (m, 3) fancy-indexed formulation: ``(segment, fraction)`` of the
    projection onto the segments ``start .. stop - 1`` (mod n on a closed path) nearest ``position``."""
    n = len(pts)
    seg = np.arange(start, stop) % n if closed else np.arange(max(start, 0), min(stop, n - 1))
    a, b = pts[seg], pts[(seg + 1) % n]
    v = b - a
    t = np.clip(((position - a) * v).sum(axis=1) / (v * v).sum(axis=1), 0.0, 1.0)
    d = position - (a + t[:, None] * v)
    k = int((d * d).sum(axis=1).argmin())
    return int(seg[k]), float(t[k])


@pytest.mark.parametrize("path", [Racetrack(), Circle(radius_mm=3.0), Helix()],
                         ids=["racetrack", "short_circle", "helix"])
def test_the_window_search_matches_the_fancy_indexed_one_across_the_start(path):
    pts = path.points(0.0)
    n = len(pts)
    segments = n if path.closed else n - 1
    rng = np.random.default_rng(3)
    pursuit = PurePursuit(path)
    first = pts[5] + 1e-4 * rng.standard_normal(3)
    pursuit.reference(first, np.zeros(3), 0.0)
    assert pursuit.index == closest_reference(pts, path.closed, first, 0, segments)[0]
    for index in [0, 1, WINDOW_BACK - 1, WINDOW_BACK, n // 2, n - WINDOW_AHEAD, n - WINDOW_AHEAD + 1, n - 2]:
        index %= segments
        position = pts[(index + 7) % n] + 1e-3 * rng.standard_normal(3)
        pursuit.index = index
        _, closest, _ = pursuit.reference(position, np.zeros(3), 0.0)
        segment, fraction = closest_reference(pts, path.closed, position, index - WINDOW_BACK, index + WINDOW_AHEAD)
        assert pursuit.index == segment
        expected = pts[segment] + fraction * (pts[(segment + 1) % n] - pts[segment])
        assert np.allclose(closest, expected, rtol=0.0, atol=1e-15)


# ---------------------------------------------------------------- PI


def pi_reference(c: PIController, integral: np.ndarray, pos: np.ndarray, target: np.ndarray,
                 closest: np.ndarray, at_end: bool) -> tuple[np.ndarray, np.ndarray]:
    """One PI step in the (3,)-array formulation: (omega, the new integral)."""
    to_target = target - pos
    dist = np.linalg.norm(to_target)
    speed = c.speed * (min(dist / c.pursuit.lookahead_m, 1.0) if at_end else 1.0)
    cross = closest - pos
    integral = integral + c.ki * cross * c.dt
    size = np.linalg.norm(integral)
    integral = integral if size <= c.i_max else integral * (c.i_max / size)
    v_des = speed * to_target / max(dist, 1e-9) + c.kp * cross + integral
    speed = np.linalg.norm(v_des)
    if speed < 1e-12:
        return np.zeros(3), integral
    f = min(speed / c.m_per_hz, c.f_max)
    return v_des / speed * (2 * math.pi * f), integral


def test_pi_matches_its_array_formulation():
    c = PIController()
    c.setup({"dt": DT, "path": Racetrack(), "i_max_mm_s": 0.5}, np.random.default_rng(0))
    pts = c.pursuit.path.points(0.0)
    rng = np.random.default_rng(4)
    integral = np.zeros(3)
    for k in range(400):
        pos = pts[(3 * k) % len(pts)] + 3e-3 * rng.standard_normal(3)
        pos[2] = [0.0, -0.0, pos[2]][k % 3]
        vel = 0.02 * rng.standard_normal(3)
        index = c.pursuit.index
        omega = c.step(k * DT, {"position": pos, "velocity": vel})["omega"]
        c.pursuit.index = index  # the same reference again, for the formulation
        target, closest, at_end = c.pursuit.reference(pos, vel, k * DT)
        expected, integral = pi_reference(c, integral, pos, target, closest, at_end)
        assert same_to_rounding(omega, expected) and same_to_rounding(c.integral, integral)


# ---------------------------------------------------------------- coil driver


def limit_scale_reference(amp, prev, z_abs, dt, limits) -> float:
    peak = float(amp.max(initial=0.0))
    if peak == 0.0:
        return 1.0
    scale = min(1.0, limits.v_max / peak, limits.i_max * z_abs / peak)
    rising = amp * scale > prev + limits.slew_v_per_s * dt
    if rising.any():
        scale = min(scale, float(((prev[rising] + limits.slew_v_per_s * dt) / amp[rising]).min()))
    return scale


def test_limit_scale_matches_its_array_formulation_nan_included():
    rng = np.random.default_rng(5)
    limits = Limits(40.0, 3.0, 200.0)
    for k in range(3000):
        amp, prev = rng.uniform(0, 60, 6), rng.uniform(0, 60, 6)
        amp[rng.random(6) < 0.2] = 0.0
        if k % 10 == 0:
            amp[rng.integers(6)] = np.nan
        z_abs = rng.uniform(5, 50)
        ours = limit_scale(amp.tolist(), prev.tolist(), z_abs, DT, limits)
        assert same_bits(ours, limit_scale_reference(amp, prev, z_abs, DT, limits))


def test_thermal_budget_matches_its_array_formulation():
    rng = np.random.default_rng(6)
    ours = ThermalBudget(r_ohm=12.9, dt_s=DT, window_s=0.2, budget_j=0.6)
    ring, energy = np.zeros((10, 6)), np.zeros(6)
    for k in range(300):
        current = rng.uniform(0, 2.5, 6)
        fault = ours.add(current.tolist())
        tick = current**2 * (12.9 / 2 * DT)
        energy += tick - ring[k % 10]
        ring[k % 10] = tick
        assert same_bits(ours.energy_j, energy)
        over = np.flatnonzero(energy > 0.6)
        assert (fault is None) == (not over.size)
        if fault is not None:
            assert f"coil {('+x', '-x', '+y', '-y', '+z', '-z')[over[np.argmax(energy[over])]]} " in fault.message


class ArrayDriver:
    """The driver's phasors in the (3,)- and (6,)-array formulation (the shaping limits included)."""

    def __init__(self, driver: InverseMagnetics):
        self.d, self.rotation, self.prev_amp = driver, None, np.zeros(6)

    def step(self, t: float, omega: np.ndarray):
        d, p = self.d, self.d.p
        f = np.linalg.norm(omega) / (2 * math.pi)
        if f < p["f_min_hz"]:
            self.rotation, self.prev_amp = None, np.zeros(6)
            return np.zeros(6), np.zeros(6), 0.0
        n = omega / (2 * math.pi * f)
        candidates = [np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])]
        if self.rotation is not None:
            n0, e10, f0, t0 = self.rotation
            theta = 2 * math.pi * f0 * (t - t0)
            candidates.insert(0, math.cos(theta) * e10 + math.sin(theta) * np.cross(n0, e10))
        for c in candidates:
            v = c - c.dot(n) * n
            if np.linalg.norm(v) > 1e-6:
                e1 = v / np.linalg.norm(v)
                break
        self.rotation = (n, e1, f, t)
        field = p["field_mT"] * 1e-3 * (e1 - 1j * np.cross(n, e1))
        z = impedance_ohm(f, p["r_ohm"], p["l_h"], p["c_f"])
        volts = d.m_pinv.dot(field) * z
        amp = np.abs(volts)
        scale = limit_scale_reference(amp, self.prev_amp, abs(z), DT, d.limits)
        if scale < 1.0:
            volts = volts * scale
            amp = np.abs(volts)
        self.prev_amp = amp
        return amp, np.angle(volts) - (2 * math.pi * f * t) % (2 * math.pi), f


def test_the_coil_driver_matches_its_array_formulation():
    driver = InverseMagnetics()
    driver.setup({"dt": DT, "slew_v_per_s": 300.0, "thermal_budget_j": 1e9}, np.random.default_rng(0))
    reference = ArrayDriver(driver)
    rng = np.random.default_rng(8)
    omega = np.zeros(3)
    for k in range(1500):
        if k % 7 == 0:  # a new command now and then (held in between, as a slower controller's)
            omega = vectors(rng, 1)[0]
            omega *= rng.uniform(0.0, 2 * math.pi * 20) / max(np.linalg.norm(omega), 1e-300)
            if k % 21 == 0:
                omega[rng.integers(3)] = [0.0, -0.0][k % 2]
        out = driver.step(k * DT, {"omega": omega})
        amp, phase, f = reference.step(k * DT, omega)
        assert driver.fault is None
        assert same_to_rounding(out["coil_voltage_amp"], amp)
        assert same_angle_to_rounding(out["coil_voltage_phase"], phase)
        assert same_to_rounding(out["drive_freq"], f)
    driver.close()

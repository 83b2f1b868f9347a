"""Fixtures for the plant tests: one FMU build per session and a small driver."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim_plugins.plant.build import build_fmu
from cosim_plugins.plant.fmu_component import FmuPlant

MU0 = 4e-7 * math.pi
# Default coil data (cosim_plugins/plant/swimmer_plant/README.md)
TURNS, R_IN, R_OUT, THICK, HALF = 795, 0.180, 0.215, 0.040, 0.150
R_COIL, L_COIL, C_COIL = 12.9, 0.411, 430e-6


def thick_coil_axis_field(d: float, turns=TURNS, r1=R_IN, r2=R_OUT, t=THICK) -> float:
    """On-axis field per ampere [T/A] of a uniformly wound thick coil whose winding
    centre is a distance ``d`` [m] away (exact integral of the loop formula)."""

    def f(z):
        return z * math.log((r2 + math.hypot(r2, z)) / (r1 + math.hypot(r1, z)))

    j = turns / (t * (r2 - r1))  # turns per m^2
    return 0.5 * MU0 * j * (f(d + t / 2) - f(d - t / 2))


#: Field per ampere [T/A] at the centre of one coil pair driven in phase.
PAIR_FIELD_PER_AMP = 2 * thick_coil_axis_field(HALF)


def impedance(f_hz: float, R=R_COIL, L=L_COIL, C=C_COIL) -> complex:
    w = 2 * math.pi * f_hz
    return complex(R, w * L - 1 / (w * C))


def rotating_drive(axis, field_t: float, f_hz: float, vmax: float = 40.0) -> dict:
    """Plant inputs for a field of amplitude ``field_t`` [T] at the centre rotating
    at ``f_hz`` about ``axis`` (right-handed), voltages clipped to ``vmax``."""
    n = np.asarray(axis, float)
    n = n / np.linalg.norm(n)
    ref = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = ref - (ref @ n) * n
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    z = impedance(f_hz)
    amp, phase = np.zeros(6), np.zeros(6)
    for k in range(3):
        v = field_t / PAIR_FIELD_PER_AMP * complex(e1[k], -e2[k]) * z  # I(t) = Re(I e^{iwt})
        amp[2 * k: 2 * k + 2] = min(abs(v), vmax)
        phase[2 * k: 2 * k + 2] = np.angle(v)
    return {"coil_voltage_amp": amp, "coil_voltage_phase": phase, "drive_freq": np.array(float(f_hz))}


def zero_drive() -> dict:
    return {"coil_voltage_amp": np.zeros(6), "coil_voltage_phase": np.zeros(6), "drive_freq": np.array(0.0)}


class Sim:
    """Run the plant component for a fixed time with constant inputs."""

    def __init__(self, fmu):
        self.fmu = fmu

    def run(self, params=None, inputs=None, T=1.0, dt=0.02) -> dict[str, np.ndarray]:
        plant = FmuPlant()
        plant.setup({"fmu": self.fmu, **(params or {})}, np.random.default_rng(0))
        inputs = inputs or zero_drive()
        try:
            rows = [plant.initial_outputs()]
            for k in range(1, int(round(T / dt)) + 1):
                rows.append(plant.step(k * dt, inputs))
        finally:
            plant.close()
        out = {key: np.array([r[key] for r in rows]) for key in rows[0]}
        out["t"] = np.arange(len(rows)) * dt
        return out


@pytest.fixture(scope="session")
def plant_fmu(tmp_path_factory):
    """The FMU built once from the current sources."""
    return build_fmu(tmp_path_factory.mktemp("fmu") / "swimmer_plant.fmu")


@pytest.fixture(scope="session")
def sim(plant_fmu):
    return Sim(plant_fmu)


@pytest.fixture(scope="session")
def helpers():
    """Drive builders and reference formulas (conftest is not importable by name)."""
    from types import SimpleNamespace

    return SimpleNamespace(
        rotating_drive=rotating_drive,
        zero_drive=zero_drive,
        impedance=impedance,
        thick_coil_axis_field=thick_coil_axis_field,
        PAIR_FIELD_PER_AMP=PAIR_FIELD_PER_AMP,
        MU0=MU0, TURNS=TURNS, R_IN=R_IN, R_OUT=R_OUT, THICK=THICK, HALF=HALF,
        R_COIL=R_COIL, L_COIL=L_COIL, C_COIL=C_COIL,
    )

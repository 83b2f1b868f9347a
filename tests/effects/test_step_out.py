"""The step-out effect: the magnet's mean spin per control period from its phase (Adler's equation)."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from cosim_plugins.effects import step_out
from cosim_plugins.effects.step_out import STEP_OUT, adler_mean_spin


def _integrated_spin(f, dt_s, f_so):
    """Mean spin per period by integrating phi' = 2 pi (f - f_so sin phi) numerically, phi settled at the start."""
    phi, spin = np.arcsin(min(f[0] / f_so, 1.0)), []
    for fi in f:
        end = solve_ivp(lambda t, y: [2 * np.pi * (fi - f_so * np.sin(y[0]))], (0, dt_s), [phi],
                        rtol=1e-10, atol=1e-12).y[0, -1]
        spin.append(fi - (end - phi) / (2 * np.pi * dt_s))
        phi = end
    return np.array(spin)


@pytest.mark.parametrize("dt_s,f_so", [(0.02, 12.3), (0.1, 5.0), (0.01, 16.5), (0.05, 100.0)])
def test_mean_spin_follows_the_integrated_phase(dt_s, f_so):
    rng = np.random.default_rng(3)
    f = np.repeat(rng.uniform(0.0, 17.0, 25), rng.integers(1, 12, 25))  # held rates, some above f_so
    assert np.allclose(adler_mean_spin(f, dt_s, f_so), _integrated_spin(f, dt_s, f_so), atol=1e-5)


def test_long_run_spin_is_the_adler_mean_law_over_the_spread_and_the_direction_is_kept():
    u = np.tile([[6.0, 8.0, 0.0]], (4000, 1))  # 10 Hz
    out = STEP_OUT.transform(u, 0.02, {"f_so": 6.0})
    f_so = 6.0 * (1.0 + step_out.SPREAD * step_out._NODES)
    mean_law = step_out._WEIGHTS @ (10.0 - np.sqrt(100.0 - f_so**2))  # 2 Hz at f_so = 6 Hz alone
    assert (out @ [0.6, 0.8, 0.0]).mean() == pytest.approx(mean_law, rel=0.01)  # signed: it turns back in a slip
    assert np.allclose(np.cross(out, u), 0.0)
    below = STEP_OUT.transform(u, 0.02, {"f_so": 20.0})
    assert np.allclose(below, u)  # settled below step-out (every f_so of the spread): it turns with the field


def test_several_step_out_frequencies_at_once_match_one_at_a_time():
    f = np.random.default_rng(4).uniform(2.0, 15.0, 300)
    both = adler_mean_spin(f, 0.02, np.array([7.0, 11.0]))
    assert np.allclose(both, [adler_mean_spin(f, 0.02, 7.0), adler_mean_spin(f, 0.02, 11.0)])

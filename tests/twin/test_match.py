"""The wall-drag parameters matched to the FMU's law: the exponential form exactly, the library's 1/d form as
closely as it allows (and how close that is)."""

from __future__ import annotations

import numpy as np
import pytest

from cosim_plugins.effects.forces import WALL_DRAG
from cosim_plugins.twin.match import fmu_wall_kappa, wall_drag_exp_like_fmu, wall_drag_like_fmu


def test_the_fmus_wall_drag_is_gain_times_drag_at_contact_and_decays_over_its_length():
    d = np.array([1.25, 3.75])  # mm from the wall: contact (the margin), then one length further
    assert np.allclose(fmu_wall_kappa(d), [2.0 * 0.08, 2.0 * 0.08 / np.e])


def test_the_exponential_form_equals_the_fmus_law():
    fit = wall_drag_exp_like_fmu()
    d = np.linspace(1.25, 30.0, 50)
    assert np.allclose(fit["c"] * np.exp(-d / fit["ell"]), fmu_wall_kappa(d), rtol=1e-12)


def test_the_library_form_is_fitted_within_the_effects_bounds_and_reports_its_misfit():
    fit = wall_drag_like_fmu()
    lo = {p.name: p.lo for p in WALL_DRAG.params}
    assert fit["ell"] >= lo["ell"] and fit["c"] > 0
    d = np.linspace(1.25, 20.0, 400)
    err = fit["c"] * fit["ell"] / (d + fit["ell"]) - fmu_wall_kappa(d)
    assert np.max(np.abs(err)) == pytest.approx(fit["max_abs_error"])
    assert fit["max_abs_error"] < 0.25 * fmu_wall_kappa(np.array([1.25]))[0]  # a fit, not a guess
    fmu20, lib20 = fit["at_20mm"]
    assert lib20 > 10 * fmu20  # the 1/d tail the form cannot shed

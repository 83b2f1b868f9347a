"""The MPC drops its model's dependence on the absolute position (``position_terms: false``, the
default): identified on closed-loop logs, the lab model learned ``y' = 1.0039 y + ...`` per 20 ms
(7.8 mm/s outwards at the racetrack's y = 40 mm), a drift the swimmer does not have, and the MPC
steered inwards against it: mean radial offset -0.92 mm on the lab racetrack, on the straights
too (30 s, seed 1: 1.07 mm, without the terms 0.53 mm; PI 0.80 mm). Here 12 s on the short lab
dataset's model, where the inward offset goes (curves -0.83 -> +0.46 mm: the outward lag on the
curves that PI shows too; straights -1.05 -> +0.16 mm) and the error falls from 1.00 to 0.72 mm."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_controllers_mpc_cross import curve_stats

from cosim_plugins.resources import SCENARIOS_DIR

SCENARIOS = SCENARIOS_DIR
RUN = ["profile=lab", "duration_s=12", "components.controller.plugin=controller.mpc"]


def straight_offset_mm(trace: Path, after_s: float = 2.0, straight_mm: float = 30.0,
                       radius_mm: float = 40.0) -> float:
    """Mean signed offset from the straights, positive outwards [mm]."""
    with np.load(trace) as d:
        t, p = d["t_s"], d["plant.position"] * 1e3
    x, y = p[t > after_s, 0], p[t > after_s, 1]
    on = np.abs(x) <= straight_mm / 2
    return float(np.mean(np.abs(y[on]) - radius_mm))


@pytest.fixture(scope="module")
def runs(run_scenario):
    return {keep: run_scenario(SCENARIOS / "controllers_racetrack.yaml", *RUN,
                               *([] if keep is None else [f"components.controller.params.position_terms={keep}"]))
            for keep in (True, None)}


def test_with_the_position_terms_the_mpc_sits_inside_the_path(runs):
    summary, out = runs[True]
    assert summary["status"] == "ok"
    _, curves = curve_stats(out / "trace.npz")
    straights = straight_offset_mm(out / "trace.npz")
    assert curves < -0.5 and straights < -0.5, f"curves {curves:.2f} mm, straights {straights:.2f} mm"


def test_without_them_the_offset_goes(runs):
    (_, kept_dir), (dropped, dropped_dir) = runs[True], runs[None]
    assert dropped["status"] == "ok"
    straights, straights_kept = (straight_offset_mm(d / "trace.npz") for d in (dropped_dir, kept_dir))
    assert abs(straights) < 0.3 * abs(straights_kept), f"straights {straights:.2f} mm (kept: {straights_kept:.2f})"
    (_, curves), (_, curves_kept) = (curve_stats(d / "trace.npz") for d in (dropped_dir, kept_dir))
    assert curves > -0.1, f"curves {curves:.2f} mm: still inside the path (kept: {curves_kept:.2f})"


def test_without_position_terms_is_the_same_everywhere():
    from cosim_plugins.controllers.mpc import without_position_terms

    rng = np.random.default_rng(5)
    A = np.eye(6) + 0.05 * rng.standard_normal((6, 6))
    Ai = without_position_terms(A)
    x, shift = rng.standard_normal(6), np.concatenate([rng.standard_normal(3), np.zeros(3)])
    # a shifted state steps to the shifted successor: nothing depends on where the swimmer is
    np.testing.assert_allclose(Ai @ (x + shift), Ai @ x + shift)
    np.testing.assert_array_equal(Ai[:, 3:], A[:, 3:])  # the velocity columns are the model's

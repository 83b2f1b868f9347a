"""The experiment design probes where a wall drag and a background flow differ: near a wall, or at rest.

Two members built from the library's own forms on the paper's plant: a wall drag (c = Cd1, ell = 5 mm)
and a slow flow (0.4 mm/s along x). On a circle in the middle of the tank, at a steady spin rate, the
drag hardly acts and the flow pushes a little: the old design (spin-rate schedules on the workspace's
central circle) sees them barely apart. The design now also tries the circle at each side of the box the
logs visited, and stop-and-go schedules; its choice must separate them by well over the noise floor, and
clearly more than the best central spin-rate schedule. A 10 s design on a synthetic workspace: seconds.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from cosim.contract.plugins import lookup
from cosim_plugins.diagnose.experiment import any_force, design_experiment, placements
from cosim_plugins.identify import synthetic as syn
from cosim_plugins.identify.dataset import Dataset
from cosim_plugins.identify.effect import known_effects
from cosim_plugins.identify.timeline import Timeline
from cosim_plugins.raw_log import Log

DT_S = 0.02
FLOOR_MM = 0.2  # a typical camera's noise floor at the reference horizon


def _member(effect: str, params: dict):
    host = lookup("model", "physical").from_params(syn.TRUE_PARAMS)
    host.dt_s = DT_S
    from cosim_plugins.identify.joint import JointModel

    return SimpleNamespace(model=JointModel(host, [known_effects()[effect]], base_params=params))


@pytest.fixture(scope="module")
def workspace_timeline():
    """A log whose positions fill x, y in [-40, 40] mm and z in [0, 68] mm (7 mm under the lid) at 5-15 Hz."""
    rng = np.random.default_rng(0)
    n = 3000
    t = np.arange(n) * DT_S
    p = np.column_stack([rng.uniform(-40, 40, n), rng.uniform(-40, 40, n), rng.uniform(0, 68, n)])
    u = rng.normal(size=(n, 3))
    u *= rng.uniform(5.0, 15.0, (n, 1)) / np.linalg.norm(u, axis=1, keepdims=True)
    none = np.zeros(n, dtype=bool)
    log = Log(path="workspace", t_s=t, omega_hz=u, p_mm=p, gap=none, repeat=none, outlier=none)
    return Timeline.from_dataset(Dataset.from_logs([log]))


def test_the_circle_is_placed_at_every_side_of_the_logs_box(workspace_timeline):
    places, radius = placements(workspace_timeline)
    named = dict(places)
    assert set(named) == {"centre", "-x", "+x", "-y", "+y", "-z", "+z"}
    lo, hi = np.nanpercentile(workspace_timeline.p, [1, 99], axis=0)
    for name, c in places:  # every circle stays inside the box
        assert lo[0] - 1e-9 <= c[0] - radius and c[0] + radius <= hi[0] + 1e-9, name
        assert lo[2] - 1e-9 <= c[2] <= hi[2] + 1e-9, name
    assert named["+z"][2] == pytest.approx(hi[2])


def test_a_circle_stays_inside_the_box_of_logs_that_dwell_near_a_wall():
    """Most rows near the +y side of the box (a long log there, short ones across the tank): the positions'
    median lies 9 mm inside that side, and a circle of half the spread about it crossed the box, and the tank's
    wall, by 35 - 9 mm (the blind bench's seed 80, multi_008: the experiment's log ran along the wall)."""
    rng = np.random.default_rng(1)
    near = np.column_stack([rng.uniform(-40, 40, 4000), rng.uniform(46, 70, 4000), rng.uniform(-10, 10, 4000)])
    across = np.column_stack([rng.uniform(-40, 40, 1500), rng.uniform(-55, 70, 1500), rng.uniform(-10, 10, 1500)])
    p = np.vstack([near, across])
    n = len(p)
    none = np.zeros(n, dtype=bool)
    log = Log(path="near_wall", t_s=np.arange(n) * DT_S, omega_hz=np.tile([5.0, 0.0, 0.0], (n, 1)), p_mm=p,
              gap=none, repeat=none, outlier=none)
    tl = Timeline.from_dataset(Dataset.from_logs([log]))
    places, radius = placements(tl)
    lo, hi = np.nanpercentile(tl.p, [1, 99], axis=0)
    assert np.median(p[:, 1]) + radius > hi[1] + 10.0  # the old circle about the median crossed the box
    for name, c in places:
        for axis in (0, 1):
            assert lo[axis] - 1e-9 <= c[axis] - radius and c[axis] + radius <= hi[axis] + 1e-9, (name, c, radius)


def test_a_wall_drag_and_a_flow_are_separated_beyond_the_old_spin_only_design(workspace_timeline):
    cd1 = syn.TRUE_PARAMS["Cd1"]
    step = SimpleNamespace(effects=["wall_drag", "background_flow"], member_fits={
        "wall_drag": _member("wall_drag", {"wall_drag.c": cd1, "wall_drag.ell": 5.0}),
        "background_flow": _member("background_flow", {"background_flow.w_x": 0.4, "background_flow.w_y": 0.0})})
    fitter = SimpleNamespace(lead=10, steps={"0.2": 10, "1.0": 50})
    exp = design_experiment(step, workspace_timeline, fitter, FLOOR_MM, duration_s=10.0)
    old = max(x.separation_mm for x in exp.tried if x.place == "centre" and not x.excitation.startswith("stop"))
    assert exp.separation_mm == max(x.separation_mm for x in exp.tried)
    assert exp.separation_mm >= 3.0 * FLOOR_MM, exp.tried
    assert exp.separation_mm >= 2.0 * old, (exp.separation_mm, old)
    assert exp.place != "centre" or exp.excitation.kind == "stop"
    summary = exp.summary()
    assert summary.path.center_mm == exp.center_mm and summary.separation_over_floor >= 3.0


def test_stops_are_tried_for_forces_only():
    """A stop shows what moves a swimmer at rest: a force; a lag or a latency only its start from rest."""
    lag = _member("actuation_lag", {"actuation_lag.tau": 0.2}).model
    late = _member("sensor_latency", {"sensor_latency.delay": 4.0}).model
    flow = _member("background_flow", {"background_flow.w_x": 0.4}).model
    assert not any_force(["actuation_lag", "sensor_latency"], [lag, late])
    assert any_force(["actuation_lag", "background_flow"], [lag, flow])


def test_members_that_do_not_depend_on_the_position_keep_the_central_circle(workspace_timeline):
    """Two flows in different directions differ the same anywhere: the circle stays at the centre."""
    step = SimpleNamespace(effects=["along_x", "along_y"], member_fits={
        "along_x": _member("background_flow", {"background_flow.w_x": 0.4, "background_flow.w_y": 0.0}),
        "along_y": _member("background_flow", {"background_flow.w_x": 0.0, "background_flow.w_y": 0.4})})
    exp = design_experiment(step, workspace_timeline, SimpleNamespace(lead=10, steps={"0.2": 10, "1.0": 50}),
                            FLOOR_MM, duration_s=10.0)
    assert exp.place == "centre" and exp.separation_mm > 0
    assert max(x.separation_mm for x in exp.tried) < 1.1 * exp.separation_mm

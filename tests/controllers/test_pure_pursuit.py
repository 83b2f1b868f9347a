"""The pure pursuit's reference is continuous in the position and lies at the look-ahead arc length.

The tracker once took the nearest path point and rounded the look-ahead to
whole points: a micrometre's move of the measured position could move the
reference by a whole path spacing (0.5 mm). Now the closest point is the
projection onto the polyline's segments and the target the point at the
exact arc length ahead, so both move by about the position's move.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_controllers_mpc_qp import swimmer_like

from cosim.contract.paths import ReferencePath
from cosim_plugins.controllers.mpc import MPCController
from cosim_plugins.controllers.pure_pursuit import PurePursuit
from cosim_plugins.paths.shapes import SPACING_M, Circle, Helix, HelixRacetrack, Racetrack, RotatingCircle

LOOKAHEAD_M, GAIN_S = 9e-3, 0.001
UM = 1e-6


class Straight(ReferencePath):
    """An open straight path along +x from the origin, ``length_mm`` long."""

    closed = False
    spacing_m = SPACING_M

    def __init__(self, length_mm: float = 100.0):
        self.length = length_mm * 1e-3

    def base_points(self):
        return np.array([[0.0, 0.0, 0.0], [self.length, 0.0, 0.0]])


def tracked(path: ReferencePath, positions: np.ndarray, velocity: np.ndarray):
    """Follow ``positions`` (k, 3) [m] in order; yield (tracker state before, position, reference)."""
    pursuit = PurePursuit(path, LOOKAHEAD_M, GAIN_S)
    for p in positions:
        before = pursuit.index
        yield before, p, pursuit.reference(p, velocity, 0.0)


def moved(path: ReferencePath, index: int | None, position: np.ndarray, velocity: np.ndarray):
    """The reference of a tracker in state ``index`` at ``position``."""
    pursuit = PurePursuit(path, LOOKAHEAD_M, GAIN_S)
    pursuit.index = index
    return pursuit.reference(position, velocity, 0.0)


def along_path(path: ReferencePath, offset_m: float, rng) -> np.ndarray:
    """Positions (k, 3) [m] along the path in order: every third vertex, then a random fraction of
    the segment on, moved by up to ``offset_m`` in a random direction."""
    pts = path.points(0.0)
    n = len(pts)
    index = np.arange(0, n - 1 if not path.closed else n, 3)
    frac = rng.random(len(index))[:, None]
    on_path = pts[index] + frac * (pts[(index + 1) % n] - pts[index])
    step = rng.standard_normal((len(index), 3))
    return on_path + offset_m * rng.random((len(index), 1)) * step / np.linalg.norm(step, axis=1)[:, None]


@pytest.mark.parametrize("path", [Racetrack(), Helix(), HelixRacetrack()],
                         ids=["racetrack", "helix", "helix_racetrack"])
def test_a_micrometre_moves_the_reference_by_micrometres_never_a_path_spacing(path):
    rng = np.random.default_rng(37)
    velocity = np.array([0.03, 0.01, 0.0])
    worst = 0.0
    for index, p, (target, closest, at_end) in tracked(path, along_path(path, 0.5e-3, rng), velocity):
        for _ in range(3):
            step = rng.standard_normal(3)
            t2, c2, end2 = moved(path, index, p + UM * step / np.linalg.norm(step), velocity)
            worst = max(worst, np.linalg.norm(t2 - target), np.linalg.norm(c2 - closest))
    # a bend of theta at a vertex: on its inner side, 1 um across the bisector moves the
    # projection from one segment to the next, d * theta apart (d <= 0.5 mm, theta <= 0.017)
    assert worst < 10 * UM
    assert worst < SPACING_M / 50


@pytest.mark.parametrize("path", [Racetrack(), Helix()], ids=["racetrack", "helix"])
def test_halfway_between_two_vertices_a_micrometre_moves_the_reference_by_a_micrometre(path):
    """Where the nearest vertex changes (the old tracker's jump by a path spacing)."""
    pts = path.points(0.0)
    velocity = np.zeros(3)
    for k in range(10, len(pts) - 400, 97):
        mid = 0.5 * (pts[k] + pts[k + 1])
        along = (pts[k + 1] - pts[k]) / np.linalg.norm(pts[k + 1] - pts[k])
        side = np.cross(along, [0.0, 0.0, 1.0])
        p = mid + 0.3e-3 * side / np.linalg.norm(side)
        before = moved(path, k, p - 0.5 * UM * along, velocity)
        after = moved(path, k, p + 0.5 * UM * along, velocity)
        for a, b in zip(before[:2], after[:2]):
            assert np.linalg.norm(b - a) < 2 * UM


def test_on_a_straight_the_target_is_the_projection_plus_the_lookahead():
    path = Straight()
    rng = np.random.default_rng(1)
    for x in rng.uniform(1e-3, 80e-3, 50):
        p = np.array([x, *rng.uniform(-3e-3, 3e-3, 2)])
        v = rng.uniform(-0.05, 0.05, 3)
        target, closest, at_end = moved(path, None, p, v)
        assert np.allclose(closest, [x, 0.0, 0.0], rtol=0.0, atol=1e-12)
        ahead = LOOKAHEAD_M + GAIN_S * np.linalg.norm(v)
        assert np.allclose(target, [x + ahead, 0.0, 0.0], rtol=0.0, atol=1e-12)
        assert not at_end


def test_on_a_circle_the_target_is_the_lookahead_arc_on():
    radius = 35e-3
    path = Circle(radius_mm=radius * 1e3)
    rng = np.random.default_rng(2)
    velocity = np.array([0.0, 0.04, 0.0])
    ahead = LOOKAHEAD_M + GAIN_S * 0.04
    for phi, offset in zip(rng.uniform(0.0, 2 * np.pi, 60), rng.uniform(-2e-3, 2e-3, 60)):
        p = (radius + offset) * np.array([np.cos(phi), np.sin(phi), 0.0]) + [0.0, 0.0, 1e-3]
        target, closest, at_end = moved(path, None, p, velocity)
        # the polyline's chords lie within h^2 / (8 R) = 0.9 um inside the circle; the projection onto
        # a chord is the radial one to within (h / 2) |offset| / R along it
        assert radius - 1.0 * UM < np.linalg.norm(closest) <= radius
        at = np.arctan2(closest[1], closest[0])
        assert abs(np.angle(np.exp(1j * (at - phi)))) * radius < SPACING_M / 2 * abs(offset) / radius + 0.1 * UM
        on = at + ahead / radius
        assert np.linalg.norm(target - radius * np.array([np.cos(on), np.sin(on), 0.0])) < 1.5 * UM
        assert not at_end


def test_a_closed_path_wraps_across_its_start():
    path = Racetrack()
    pts = path.points(0.0)
    n = len(pts)
    pursuit = PurePursuit(path, LOOKAHEAD_M, GAIN_S)
    pursuit.reference(pts[n - 30], np.zeros(3), 0.0)
    length = path.length_m
    for k in range(n - 30, n + 30, 3):  # over the start, in order
        p = pts[k % n] + [0.0, 2e-4, 0.0]
        target, closest, at_end = pursuit.reference(p, np.zeros(3), 0.0)
        assert not at_end
        assert np.linalg.norm(closest - pts[k % n]) < 2.1e-4
        assert pursuit.index in (k % n, (k - 1) % n)
        expected = pursuit.line(0.0).at_arc(pursuit.arc_m + LOOKAHEAD_M)[0]
        assert np.array_equal(target, expected)
        assert abs(np.linalg.norm(target - closest) - LOOKAHEAD_M) < 2e-5  # a chord of the straight
    assert 0.0 <= pursuit.arc_m < length
    walk = pursuit.along(np.array([0.0, LOOKAHEAD_M, length]), 0.0)  # a whole lap comes back
    assert np.allclose(walk[2], walk[0], rtol=0.0, atol=1e-12)


def test_an_open_path_ends_with_at_end():
    path = Helix()
    line = PurePursuit(path).line(0.0)
    total = line.length_m
    pts = path.points(0.0)
    pursuit = PurePursuit(path, LOOKAHEAD_M, 0.0)
    pursuit.reference(pts[len(pts) - 60], np.zeros(3), 0.0)
    ends = []
    for k in range(len(pts) - 60, len(pts)):
        target, closest, at_end = pursuit.reference(pts[k], np.zeros(3), 0.0)
        assert at_end == (pursuit.arc_m + LOOKAHEAD_M >= total)
        if at_end:
            assert np.array_equal(target, pts[-1])
        ends.append(at_end)
    assert not ends[0] and ends[-1]
    assert np.array_equal(pursuit.along(np.array([1.0]), 0.0)[0], line.at_arc(total)[0])


def test_the_mpc_path_reference_walks_on_from_the_projection(monkeypatch):
    monkeypatch.setattr(MPCController, "_load_model", lambda self, p: swimmer_like())
    mpc = MPCController()
    mpc.setup({"dt": 0.02, "path": Racetrack(), "reference": "path"}, np.random.default_rng(0))
    pts = Racetrack().points(0.0)
    velocity = np.array([0.04, 0.0, 0.0])
    step_m = mpc.p["speed_mm_s"] * 1e-3 * mpc.dt
    for k in (3, 200, len(pts) - 2):
        p = pts[k] + [1e-4, 3e-4, 0.0]
        mpc.pursuit.index = None  # a fresh search over the whole path
        refs = mpc.horizon_reference(0.0, p, velocity)  # (N, 3) [m]
        line = mpc.pursuit.line(0.0)
        for i, r in enumerate(refs, start=1):
            s = mpc.pursuit.arc_m + mpc.p["lead_mm"] * 1e-3 + i * step_m
            assert np.array_equal(r, line.at_arcs(np.array([s]))[0])
            assert np.allclose(r, line.at_arc(s)[0], rtol=0.0, atol=1e-15)
        nudged = mpc.horizon_reference(0.0, p + [UM, 0.0, 0.0], velocity)
        assert np.abs(nudged - refs).max() < 2 * UM


class Redrawn(RotatingCircle):
    """The rotating circle without its rigid motion: the tracker rebuilds it at every time."""

    def motion(self, t_s):
        return None


def test_a_rigidly_moving_path_is_searched_in_its_own_frame():
    path, redrawn = RotatingCircle(angle_deg=20.0), Redrawn(angle_deg=20.0)
    rng = np.random.default_rng(5)
    for t in (0.0, 0.13, 0.77, 1.4):
        rotation, offset = path.motion(t)
        assert np.allclose(path.points(0.0) @ rotation.T + offset, path.points(t), rtol=0.0, atol=1e-15)
    fast, slow = PurePursuit(path), PurePursuit(redrawn)
    velocity = np.array([0.0, 0.03, 0.01])
    for k in range(60):
        t = 0.02 * k
        p = path.points(t)[(5 * k) % 400] + 5e-4 * rng.standard_normal(3)
        ours, theirs = fast.reference(p, velocity, t), slow.reference(p, velocity, t)
        assert fast.index == slow.index and ours[2] == theirs[2]
        for a, b in zip(ours[:2], theirs[:2]):
            assert np.allclose(a, b, rtol=0.0, atol=1e-15)
        assert np.allclose(fast.along(np.array([0.0, 0.01]), t), slow.along(np.array([0.0, 0.01]), t),
                           rtol=0.0, atol=1e-15)

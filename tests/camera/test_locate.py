"""Finding the swimmer in a frame pair: accuracy, reflections and glints, losses."""

from __future__ import annotations

import numpy as np

from cosim_plugins.camera.detect import BlobParams, find_blobs
from cosim_plugins.camera.locate import FOUND, LOST, REJECTED, PairLocator, PairParams
from cosim_plugins.camera.sources.render import Look, Renderer

AXIS = np.array([1.0, 0.0, 0.0])


def locator(cameras, **pair):
    return PairLocator(cameras, BlobParams(), PairParams(**pair))


def test_positions_are_found_to_hundredths_of_a_millimetre(cameras):
    rng = np.random.default_rng(4)
    renderer = Renderer(cameras, Look(), np.random.default_rng(5))
    errors = []
    for _ in range(60):
        truth = rng.uniform(-0.06, 0.06, 3)
        axis = rng.normal(size=3)
        pair = renderer.grab(0.0, {"position": truth, "axis": axis / np.linalg.norm(axis)})
        fix = locator(cameras).locate(0.0, pair.images)  # a fresh locator: the whole-frame search
        assert fix.status == FOUND
        errors.append(np.linalg.norm(fix.position_m - truth) * 1e3)
    assert np.median(errors) < 0.02 and max(errors) < 0.1, errors


def test_a_wall_reflection_darker_than_the_body_is_not_taken(cameras, draw):
    # 3 mm from the +y wall: the top camera also sees the swimmer mirrored behind the wall, and here
    # the mirror image is the darkest blob; it agrees with the side view, but lies outside the tank
    truth = np.array([0.02, 0.072, -0.01])
    mirror = truth * [1, -1, 1] + [0, 2 * 0.075, 0]
    top, side = draw([(truth, AXIS, 0.7), (mirror, AXIS, 1.0)], [(truth, AXIS, 1.0)])
    unbounded = locator(cameras, tank_mm=1000.0).locate(0.0, (top, side))
    assert np.linalg.norm(unbounded.position_m - mirror) < 5e-4  # without the tank's bounds: the mirror
    fix = locator(cameras).locate(0.0, (top, side))
    assert fix.status == FOUND and np.linalg.norm(fix.position_m - truth) < 5e-5


def test_a_glint_in_one_view_only_is_not_paired(cameras, draw):
    truth = np.array([-0.03, 0.01, 0.02])
    glint = np.array([0.035, -0.02, 0.0])  # elsewhere in x: no blob of the side view matches it
    top, side = draw([(truth, AXIS, 0.7), (glint, AXIS, 1.0)], [(truth, AXIS, 1.0)])
    fix = locator(cameras).locate(0.0, (top, side))
    assert len(fix.blobs[0]) == 2
    assert fix.status == FOUND and np.linalg.norm(fix.position_m - truth) < 5e-5


def test_a_decoy_both_views_agree_on_loses_to_the_last_position(cameras, draw):
    # a blob in the top view at the swimmer's x but 30 mm off in y: the side view, which sees x and z,
    # agrees with it as well as with the swimmer, and it lies in the tank; the last position decides
    truth = np.array([0.01, -0.02, 0.0])
    track = locator(cameras)
    clean = draw([(truth, AXIS, 1.0)], [(truth, AXIS, 1.0)])
    assert track.locate(0.0, clean).status == FOUND
    moved = truth + [0.0004, 0.0, 0.0]
    decoy = moved + [0.0, 0.03, 0.0]
    top, side = draw([(moved, AXIS, 0.7), (decoy, AXIS, 1.0)], [(moved, AXIS, 1.0)])
    fresh = locator(cameras).locate(0.02, (top, side))
    assert np.linalg.norm(fresh.position_m - decoy) < 1e-3  # alone, the darker decoy (30 mm off) wins
    fix = track.locate(0.02, (top, side))
    assert fix.status == FOUND and np.linalg.norm(fix.position_m - moved) < 5e-5


def test_a_lost_frame_or_an_empty_view_is_lost_not_guessed(cameras, draw):
    truth = np.array([0.0, 0.0, 0.0])
    top, side = draw([(truth, AXIS, 1.0)], [])
    track = locator(cameras)
    for images in ((top, None), (None, side), (top, side)):
        fix = track.locate(0.0, images)
        assert fix.status == LOST and np.isnan(fix.position_m).all() and np.isnan(fix.reprojection_px)


def test_a_jump_is_rejected_until_the_last_position_is_forgotten(cameras, draw):
    track = locator(cameras, max_rejects=3)
    here, there = np.array([0.0, 0.0, 0.0]), np.array([0.03, 0.02, -0.01])
    assert track.locate(0.0, draw([(here, AXIS, 1.0)], [(here, AXIS, 1.0)])).status == FOUND
    far = draw([(there, AXIS, 1.0)], [(there, AXIS, 1.0)])
    statuses = [track.locate(0.02 * (k + 1), far).status for k in range(5)]
    assert statuses == [REJECTED, REJECTED, REJECTED, FOUND, FOUND]


def test_tracking_finds_the_same_blob_as_the_whole_frame_search(cameras, draw):
    truth = np.array([-0.05, 0.04, 0.03])
    top, _ = draw([(truth, np.array([0.3, 0.8, 0.5]), 1.0)], [])
    expected = cameras["top"].project(truth[None])[0]
    whole, tracked = find_blobs(top, BlobParams()), find_blobs(top, BlobParams(), expected + [9.0, -7.0])
    assert len(whole) == len(tracked) == 1
    # the windows differ, and with them the background level each measures against: by hundredths
    assert np.linalg.norm(whole.centres[0] - tracked.centres[0]) < 0.02
    assert np.linalg.norm(whole.centres[0] - expected) < 0.05

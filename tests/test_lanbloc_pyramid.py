"""Pyramid-level detection in the C++ front end's search windows
(``LanBLocSettings.detect_side_px``): on frames of the scenario camera
(2560×1440) it finds the markers that full-resolution detection finds in the
same windows, with corners within 0.1 px after refinement (both images) and the
same fixes; bad settings are named.  And the Python side that the benchmarks
compare it with: a :class:`~safenav.vision.frame.StereoFrame` cut from a
rendered pair (its pyramid levels are block means), the region pipeline on it,
and the tiled noise of ``render_regions``."""

from __future__ import annotations

import math

import numpy as np
import pytest

import safenav
from safenav import _core
from safenav.vision.detect import FiducialDetector
from safenav.vision.lanbloc import LanBLoc, scenario_camera
from safenav.vision.render import StereoRenderer
from safenav.world import Landmark, World
from test_lanbloc_cpp import SCENES, _front_end, _scene, random_frame

P = np.diag([0.3 ** 2, 0.3 ** 2, math.radians(2.0) ** 2])


@pytest.fixture(scope="module")
def rig():
    return scenario_camera(safenav.default_scenario(), None, None, 1.5, {})[0]


def _frames(rig, n: int, seed: int = 0):
    """``n`` frames of :func:`random_frame` (the generator of bench/bench_lanbloc_cpp.py); with seed 0,
    frame 6 has a marker 6 px from the top."""
    rng = np.random.default_rng(seed)
    for k in range(n):
        pose, world, _, pair = random_frame(rng, k, rig)
        yield pose, world, pair


@pytest.mark.parametrize("whole", [False, True], ids=["windows", "whole_frame"])
def test_pyramid_finds_the_full_resolution_markers_with_the_same_corners(rig, whole):
    # Windows from a prediction; or no prediction: the whole frame, at the level where a board at
    # max_range_m (30 m, the scenario camera's) is still detect_side_px wide (level 1 here).
    moved = 0
    fixes = 0
    for pose, world, (left, right) in _frames(rig, 8):
        pred = () if whole else (np.array(pose), P)
        full = _front_end(world, rig, detect_side_px=0.0, max_range_m=30.0).localize(left, right, *pred)
        pyr = _front_end(world, rig, max_range_m=30.0).localize(left, right, *pred)
        assert pyr.search == full.search == (_core.SearchMode.WHOLE_FRAME if whole else _core.SearchMode.WINDOWS)
        assert [o.landmark_id for o in pyr.observations] == [o.landmark_id for o in full.observations]
        assert pyr.ok == full.ok
        for o, q in zip(pyr.observations, full.observations):
            assert o.ok == q.ok, (o.reason, q.reason)
            for a, b in ((o.corners_left, q.corners_left), (o.corners_right, q.corners_right)):
                a, b = np.asarray(a), np.asarray(b)
                assert np.isfinite(a).all() == np.isfinite(b).all()
                if np.isfinite(a).all():
                    d = np.abs(a - b).max()
                    assert d <= 0.1, (o.landmark_id, d)
                    moved += d > 0
        if full.ok:
            fixes += 1
            # the corners' difference (≤ 0.1 px, within the 0.1 px step tolerance of the refinement)
            # moves the fix by centimetres at these ranges
            assert np.hypot(*(np.asarray(pyr.position) - np.asarray(full.position))) < 0.1
            assert np.hypot(*(np.asarray(pyr.position) - pose[:2])) < 0.5
    assert fixes >= 5
    assert moved > 0   # the pyramid path ran: its corners start elsewhere and end within 0.1 px


def test_pyramid_is_off_without_subpixel_and_at_zero(rig):
    pose, world, (left, right) = next(_frames(rig, 1, seed=3))
    a = _front_end(world, rig, detect_side_px=0.0).localize(left, right, np.array(pose), P)
    b = _front_end(world, rig, detect_side_px=0.0, relative_corner_refinement_win_size=0.0).localize(
        left, right, np.array(pose), P)
    c = _front_end(world, rig, subpixel=False).localize(left, right, np.array(pose), P)
    d = _front_end(world, rig, subpixel=False, detect_side_px=0.0).localize(left, right, np.array(pose), P)
    assert [o.landmark_id for o in a.observations] == [o.landmark_id for o in b.observations]
    # without refinement the pyramid is not used: the integer corners of full resolution
    for o, q in zip(c.observations, d.observations):
        np.testing.assert_array_equal(np.asarray(o.corners_left), np.asarray(q.corners_left))


@pytest.mark.parametrize("bad", [-1.0, 8.0, 15.9, math.nan])
def test_detect_side_px_is_checked(rig, bad):
    with pytest.raises(ValueError, match="detect_side_px"):
        _front_end(World(landmarks=(Landmark(1, (10.0, 0.0, 2.0), "m", 1),)), rig, detect_side_px=bad)


def test_frame_of_images_cuts_block_means():
    from safenav.vision.rig import StereoRig
    r = StereoRig()
    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    ren = StereoRenderer(world, r, noise_std=1.0, seed=2)
    left, right = ren.render(pose)
    frame = ren.frame(pose, images=(left, right))
    np.testing.assert_array_equal(frame.patch("right", (10, 20, 110, 90)), right[20:90, 10:110])
    p = frame.patch("left", (8, 16, 200, 120), 2)
    blocks = left[16:120, 8:200].reshape(26, 4, 48, 4).mean(axis=(1, 3))
    assert np.abs(p.astype(float) - blocks).max() <= 0.5 + 1e-9
    # past the image's edge the last pixels repeat: a block column cut at the edge is still a mean
    edge = frame.patch("left", (r.width - 6, 0, r.width, 8), 2)
    assert edge.shape == (2, 2)
    # the region pipeline on the given pixels finds the markers and fixes the pose
    res = LanBLoc(world, r, FiducialDetector(world, aruco3=True), ranging="corners").localize_frame(frame)
    assert res.ok, res.reason
    assert np.hypot(*(np.asarray(res.position) - pose[:2])) < 0.3
    with pytest.raises(ValueError, match="images"):
        ren.frame(pose, images=(left[:10], right))


def test_region_noise_is_tiled_and_deterministic():
    from safenav.vision.rig import StereoRig
    r = StereoRig()
    ren = StereoRenderer(World(landmarks=()), r, noise_std=2.0, seed=4)
    box = [(0, 0, 300, 100)]
    a = ren.render_regions((0.0, 0.0, 0.3), box, box, noise_seed=9)
    b = ren.render_regions((0.0, 0.0, 0.3), box, box, noise_seed=9)
    clean = StereoRenderer(World(landmarks=()), r, noise_std=0.0).render_regions((0.0, 0.0, 0.3), box, box)
    np.testing.assert_array_equal(a[0], b[0])
    d = a[0][:100, :300].astype(float) - clean[0][:100, :300]
    # N(0, 2²) rounded to the nearest grey level: mean 0, σ ≈ √(4 + 1/12)
    assert abs(d.mean()) < 0.1 and abs(d.std() - math.sqrt(4 + 1 / 12)) < 0.15
    assert not np.array_equal(a[0][:100, :300], a[1][:100, :300])   # the two images' noise differs
    # A region larger than the tile (the scenario camera's whole frame): blocks of at most the tile's
    # side, each a window of the tile at its own offset; the same statistics, deterministic.
    big = StereoRig(width=2560, height=1440, focal_length_px=1400.0)
    n = StereoRenderer.REGION_NOISE_TILE
    full = [(0, 0, big.width, big.height)]
    ren = StereoRenderer(World(landmarks=()), big, noise_std=2.0, seed=4)
    a = ren.render_regions((0.0, 0.0, 0.3), full, full, noise_seed=9)[0].astype(float)
    b = ren.render_regions((0.0, 0.0, 0.3), full, full, noise_seed=9)[0].astype(float)
    c = StereoRenderer(World(landmarks=()), big, noise_std=0.0).render_regions((0.0, 0.0, 0.3), full, full)[0]
    np.testing.assert_array_equal(a, b)
    d = a - c
    for y0 in range(0, big.height, n):
        for x0 in range(0, big.width, n):   # every block has noise, N(0, 2²) rounded, away from saturation
            blk = d[y0:y0 + n, x0:x0 + n][(c[y0:y0 + n, x0:x0 + n] > 10) & (c[y0:y0 + n, x0:x0 + n] < 245)]
            assert abs(blk.mean()) < 0.1 and abs(blk.std() - math.sqrt(4 + 1 / 12)) < 0.15
    assert not np.array_equal(d[:n, :n], d[:n, n:2 * n])   # blocks at their own offsets

"""Pixels drawn on demand (the core's SimulatedCamera, PixelRenderer and RenderedFrame, and the
front end's StereoPixels): a box at level 0 is the whole image's pixels there, a box at a pyramid
level is what the front end finds the same markers in as in the full-resolution image, the noise
is σ/2^L and reproducible, bad boxes are named, and the core's camera sees the boards the Python
geometry sees."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from safenav import _core
from safenav.vision.camera_loop import front_end
from safenav.vision.render import StereoRenderer
from safenav.vision.rig import StereoRig, camera_rotation
from safenav.world import Circle, Landmark, World
from test_lanbloc_cpp import random_frame

SIGMA = 1.0


@pytest.fixture(scope="module")
def frames():
    rng = np.random.default_rng(11)
    return [random_frame(rng, k) for k in range(8)]


def test_a_level_0_box_is_the_whole_images_pixels_there(frames):
    rng = np.random.default_rng(0)
    for pose, _world, ren, _pair in frames[:4]:
        px = ren.pixels(pose, 0, noise=False)
        w, h = ren.rig.width, ren.rig.height
        for right in (False, True):
            whole = px.draw(right, 0, 0, 0, w, h)
            for _ in range(6):
                bw, bh = int(rng.integers(8, 200)), int(rng.integers(8, 150))
                x0, y0 = int(rng.integers(0, w - bw)), int(rng.integers(0, h - bh))
                box = px.draw(right, 0, x0, y0, bw, bh)
                # the boards' warps are placed from the box's own origin (OpenCV maps each pixel at
                # 1/32 px): a few pixels on a board's edges may differ
                same = box == whole[y0:y0 + bh, x0:x0 + bw]
                assert same.mean() >= 0.995, (pose, right, (x0, y0, bw, bh))


def test_the_front_end_finds_in_drawn_levels_what_it_finds_in_the_images(frames):
    """The plan's regions drawn on demand at the detection levels against the whole images drawn at
    full resolution (the same scene and noise level): the same markers ranged, and fixes that differ
    as two draws of the noise do."""
    fixes = agree = 0
    for pose, world, ren, _pair in frames:
        fe = front_end(world, ren.rig, marker_size_m=ren.marker_size_m)
        plan = fe.plan(np.array(pose), np.diag([0.05 ** 2, 0.05 ** 2, 0.005 ** 2]))
        assert plan.mode == _core.SearchMode.WINDOWS, plan.reason
        whole = [(0, 0, ren.rig.width, ren.rig.height)]
        left, right = ren.render_regions(pose, whole, whole, 3)
        full = fe.localize_plan(left, right, plan)
        px = ren.pixels(pose, 3)
        drawn = fe.localize_pixels(px, plan)
        assert {o.landmark_id for o in drawn.observations} == {o.landmark_id for o in full.observations}
        assert all(a.ok == b.ok for a, b in zip(drawn.observations, full.observations))
        # a random frame may be near a trilateration ambiguity, which the noise settles either way
        agree += drawn.ok == full.ok
        if full.ok and drawn.ok:
            fixes += 1
            # two draws of independent noise: the fixes differ by N(0, 2P) (χ², 2 dof, 99.9 %)
            e = np.asarray(drawn.position) - full.position
            assert e @ np.linalg.solve(2 * np.asarray(full.covariance), e) < 13.8, (e, full.covariance)
        # only what detection reads was drawn: far fewer pixels than the two images
        assert 0 < px.pixels < 0.5 * 2 * ren.rig.width * ren.rig.height
    assert fixes >= 4 and agree >= len(frames) - 1


class _Recorder:
    """StereoPixels that record the boxes drawn, (right, level, x0, y0, width, height); with
    ``both_right`` the left image is the right one too."""

    def __init__(self, pixels, both_right: bool = False):
        self.pixels, self.both_right, self.boxes = pixels, both_right, []

    def draw(self, right, level, x0, y0, width, height):
        self.boxes.append((right, level, x0, y0, width, height))
        return self.pixels.draw(right or self.both_right, level, x0, y0, width, height)


def test_the_whole_frame_searches_the_right_image_along_the_left_markers_rows(frames):
    """Without a prediction the left image is searched whole and the right one only in bands along
    the rows of the landmarks found in the left (the rig is rectified): each band holds its
    landmark's true marker in the right image, the bands are a small part of it, and they find in
    the right image every landmark of the left one that a search of the whole right image finds."""
    found = 0
    for pose, world, ren, _pair in frames:
        fe = front_end(world, ren.rig, marker_size_m=ren.marker_size_m)
        px = ren.pixels(pose, 0)
        rec = _Recorder(px)
        fix = fe.localize_pixels(rec, fe.plan())
        assert fix.search == _core.SearchMode.WHOLE_FRAME
        w, h = ren.rig.width, ren.rig.height
        right = [b for b in rec.boxes if b[0]]
        left_ids = {o.landmark_id for o in fix.observations}
        # the right image searched whole, as a left image (the same pixels, the same level)
        whole_right = {o.landmark_id for o in fe.localize_pixels(_Recorder(px, True), fe.plan()).observations}
        in_right = {o.landmark_id for o in fix.observations if o.reason != "not found in the right image"}
        assert in_right == left_ids & whole_right, (in_right, left_ids, whole_right)
        found += len(in_right)
        if not left_ids:
            assert not right
            continue
        # the bands, drawn at the search level; corner patches are drawn at level 0 below it
        top = max(b[1] for b in right)
        bands = [(x0, y0, x0 + (bw << lv), y0 + (bh << lv)) for _r, lv, x0, y0, bw, bh in right if lv == top]
        corners = ren.marker_corners(pose)
        for lid in left_ids:
            uv, z = ren.project(pose, corners[lid], "right")
            if (z > 0).all() and (uv >= 0).all() and (uv[:, 0] <= w - 1).all() and (uv[:, 1] <= h - 1).all():
                assert any((uv[:, 0] >= x0).all() and (uv[:, 0] <= x1).all() and (uv[:, 1] >= y0).all()
                           and (uv[:, 1] <= y1).all() for x0, y0, x1, y1 in bands), (lid, uv, bands)
        mask = np.zeros((h, w), bool)
        for x0, y0, x1, y1 in bands:
            mask[y0:y1, x0:x1] = True
        assert mask.mean() < 0.3, mask.mean()
    assert found >= 20


@pytest.mark.parametrize("level", [0, 1, 2, 3])
def test_pixel_noise_is_sigma_over_two_to_the_level_and_reproducible(frames, level):
    pose, _world, ren, _pair = frames[0]
    k = 1 << level
    w, h = 512 // k, 256 // k
    clean = ren.pixels(pose, 5, noise=False).draw(False, level, 64, 100, w, h).astype(float)
    a = ren.pixels(pose, 5).draw(False, level, 64, 100, w, h)
    again = ren.pixels(pose, 5).draw(False, level, 64, 100, w, h)
    other = ren.pixels(pose, 6).draw(False, level, 64, 100, w, h)
    np.testing.assert_array_equal(a, again)
    if level <= 2:  # at level 3, σ/8 rounds to 0 in all but ~1 pixel in 10⁴
        assert not np.array_equal(a, other)
    # a pixel's noise is the frame's, whatever was drawn before: a box inside `a`, drawn after other
    # boxes of the same frame, is `a` there (boards' edges may round the other way, as above)
    px = ren.pixels(pose, 5)
    px.draw(True, level, 0, 0, w // 3, h // 3)
    inner = px.draw(False, level, 64 + 8 * k, 100 + 4 * k, w // 2, h // 2)
    assert (inner == a[4:4 + h // 2, 8:8 + w // 2]).mean() >= 0.995
    keep = (clean > 5) & (clean < 250)             # away from saturation
    d = (a - clean)[keep]
    # N(0, (σ/2^L)²) rounded to whole grey levels (half to even, as OpenCV saturates)
    want = (np.round(np.random.default_rng(1).normal(0.0, SIGMA / k, 200_000))).std()
    assert abs(d.mean()) < 0.05 and abs(d.std() - want) < 0.1 * want + 0.01, (d.mean(), d.std(), want)


def test_bad_boxes_and_pixels_are_named(frames):
    pose, world, ren, _pair = frames[0]
    px = ren.pixels(pose, 0)
    w, h = ren.rig.width, ren.rig.height
    with pytest.raises(ValueError, match="not inside the 640x480 image"):
        px.draw(False, 0, w - 10, 0, 20, 10)
    with pytest.raises(ValueError, match="not inside"):
        px.draw(True, 2, 0, 0, w // 4 + 1, 10)
    with pytest.raises(ValueError, match="must be >= 1"):
        px.draw(False, 0, 0, 0, 0, 10)
    with pytest.raises(ValueError, match="board 999 has no mip pyramid"):
        _core.RenderedFrame(ren.camera().renderer, None, (0.0, np.eye(3), np.zeros(3),
                                                          [(999, np.ones((4, 3)), None, (0, 0, 1, 1))]),
                            (0.0, np.eye(3), np.zeros(3), []), 0)
    fe = front_end(world, ren.rig)
    plan = fe.plan(np.array(pose), np.diag([0.01, 0.01, 1e-4]))

    class Wrong:
        def draw(self, right, level, x0, y0, width, height):
            return np.zeros((height + 1, width), np.uint8)

    with pytest.raises(ValueError, match=r"must return a \(height, width\) uint8 array"):
        fe.localize_pixels(Wrong(), plan)
    with pytest.raises(ValueError, match="an object with draw"):
        fe.localize_pixels(42, plan)


@settings(max_examples=40, deadline=None)
@given(x=st.floats(60.0, 140.0), y=st.floats(60.0, 140.0), th=st.floats(-math.pi, math.pi),
       yaw=st.one_of(st.none(), st.floats(-math.pi, math.pi)), pitch=st.sampled_from([0.0, -0.08, 0.1]),
       seed=st.integers(0, 2 ** 16))
def test_the_cores_camera_sees_what_the_python_geometry_sees(x, y, th, yaw, pitch, seed):
    """The core's simulated camera (which boards each camera draws, in camera coordinates, far first,
    and how many centres the left image holds) against the renderer's Python geometry (culled,
    _board, hidden: the region pipeline's), with obstacles hiding some boards, boards facing the
    camera or at a fixed yaw, boards behind, beside and above the camera."""
    rng = np.random.default_rng(seed)
    lms = tuple(Landmark(i, (*rng.uniform(50, 150, 2), rng.uniform(0.3, 5.0)), "m", 1) for i in range(14))
    obstacles = tuple(Circle(center=tuple(rng.uniform(60, 140, 2)), radius=float(rng.uniform(1, 6))) for _ in range(4))
    world = World(landmarks=lms, obstacles=obstacles)
    rig = StereoRig(width=640, height=360, focal_length_px=350.0, pitch_rad=pitch, max_range_m=40.0)
    ren = StereoRenderer(world, rig, facing="camera" if yaw is None else yaw, occlusion=True)
    pose = (x, y, th)
    views = ren.camera().views(np.array(pose))
    R = camera_rotation(th, pitch)
    boards = [ren._board(i, pose) for i in ren.culled(pose)]
    hidden = ren.hidden(pose)
    for view, cam, C in zip(views, ("left", "right"), rig.camera_centers(pose)):
        want = []
        for lid, corners, _pole, facing in boards:
            pc = (corners - C) @ R.T
            if facing and lid not in hidden[cam] and (pc[:, 2] > rig.near_m).all():
                want.append((float(pc[:, 2].mean()), lid, pc))
        want.sort(key=lambda t: -t[0])
        got = view[3]
        assert [b[0] for b in got] == [w[1] for w in want], cam
        for b, w in zip(got, want):
            np.testing.assert_allclose(b[1], w[2], rtol=1e-12, atol=1e-9)
    # the early out's count: centres inside the left image, not hidden
    C = rig.camera_centers(pose)[0]
    n = 0
    for i in ren.culled(pose):
        pc = (ren._L[i] - C) @ R.T
        u, v = rig.focal_length_px * pc[:2] / pc[2] + [rig.cx, rig.cy]
        n += bool(pc[2] > rig.near_m and 0 <= u <= rig.width - 1 and 0 <= v <= rig.height - 1
                  and ren.landmarks[i].id not in hidden["left"])
    assert ren.centres_in_view(pose) == n

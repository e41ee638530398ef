"""The stereo renderer (camera in the loop): pinhole geometry of the
markers, disparity f·B/Z of markers and of the ground, zero disparity of the
background, culling, the matching calibration, determinism and bad input.

The expected pixel positions are computed here from the pinhole model written
out independently of ``safenav.vision.render`` (camera x right, y down, z forward;
pixel centres at integer coordinates; the vehicle's position is the left
camera's centre)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import safenav
from safenav.vision.detect import FiducialDetector
from safenav.vision.render import StereoRenderer, StereoRig
from safenav.vision.stereo import StereoMatcher
from safenav.world import Landmark, World

RIG = StereoRig()   # 640x480, f = 350 px, B = 0.3 m, h = 1.5 m


def _world(*lms):
    return World(landmarks=tuple(Landmark(i, p, "marker", 0) for i, p in lms))


def _expected_corners(rig, pose, centre, size, pitch=0.0):
    """Pixel corners (TL, TR, BR, BL) of a marker facing back along the heading (fronto-parallel),
    in the left and right images, and its depth."""
    x, y, th = pose
    fwd = np.array([math.cos(th), math.sin(th)])
    right = np.array([math.sin(th), -math.cos(th)])
    d = np.asarray(centre[:2]) - [x, y]
    X, Z = float(d @ right), float(d @ fwd)
    Y = -(centre[2] - rig.camera_height_m)
    s = size / 2
    pts = np.array([[X - s, Y - s, Z], [X + s, Y - s, Z], [X + s, Y + s, Z], [X - s, Y + s, Z]])
    # pitch up by φ: the level camera's point expressed in the pitched camera
    c, sn = math.cos(pitch), math.sin(pitch)
    pts = np.column_stack([pts[:, 0], pts[:, 1] * c + pts[:, 2] * sn, -pts[:, 1] * sn + pts[:, 2] * c])
    out = []
    for dx in (0.0, -rig.baseline_m):   # the right camera sees x shifted by −B
        u = rig.focal_length_px * (pts[:, 0] + dx) / pts[:, 2] + (rig.width - 1) / 2
        v = rig.focal_length_px * pts[:, 1] / pts[:, 2] + (rig.height - 1) / 2
        out.append(np.column_stack([u, v]))
    return out[0], out[1], pts[:, 2]


def _square_edges(img: np.ndarray, uv: np.ndarray, cells: int = 6) -> np.ndarray:
    """Measured (left, right, top, bottom) edges of an axis-aligned black square with a white
    quiet zone, near the expected corners ``uv``: over a window straddling an edge from white (255)
    to black (0), pixel i covering [i - 1/2, i + 1/2), the sum of I/255 is the white length, so the
    edge sits at ``start - 1/2 + sum`` (exact for any symmetric blur of a step, hence subpixel)."""
    (u0, v0), (u1, v1) = uv.min(axis=0), uv.max(axis=0)
    half = max(2, int(0.7 * (u1 - u0) / cells))
    um, vm = int(round((u0 + u1) / 2)), int(round((v0 + v1) / 2))
    rows = slice(vm - 1, vm + 2)   # three rows / columns through the middle of the square, averaged
    cols = slice(um - 1, um + 2)
    out = []
    for e, line, rising in ((u0, img[rows].mean(axis=0), False), (u1, img[rows].mean(axis=0), True),
                            (v0, img[:, cols].mean(axis=1), False), (v1, img[:, cols].mean(axis=1), True)):
        a, b = int(math.floor(e)) - half, int(math.ceil(e)) + half + 1
        white = float(np.sum(line[a:b])) / 255.0
        out.append(b - 0.5 - white if rising else a - 0.5 + white)
    return np.array(out)


def _fronto_scene(pose, placements, size, pitch=0.0):
    """Markers facing back along the heading (parallel to the image plane) at (depth, lateral, height)."""
    th = pose[2]
    fwd = np.array([math.cos(th), math.sin(th)])
    right = np.array([math.sin(th), -math.cos(th)])
    centres = {k: (*(np.array(pose[:2]) + z * fwd + lat * right), hgt) for k, (z, lat, hgt) in placements.items()}
    rig = StereoRig(pitch_rad=pitch)
    return rig, centres, StereoRenderer(_world(*centres.items()), rig, marker_size_m=size, facing=th + math.pi)


def test_marker_edges_project_where_the_pinhole_model_says():
    """The black square's edges, measured to subpixel precision, lie where the independent pinhole
    model puts them (within 0.1 px) in both images, for markers at 5-20 m."""
    pose = (10.0, 9.0, 0.3)
    size = 1.2
    rig, centres, r = _fronto_scene(pose, {1: (5.0, -2.0, 2.0), 2: (9.0, 0.3, 1.0), 3: (14.0, 3.0, 3.0),
                                           4: (20.0, 8.0, 1.8)}, size)
    images = dict(zip(("left", "right"), r.render(pose)))
    assert sorted(r.visible(pose)) == [1, 2, 3, 4]
    for lid, c in centres.items():
        exp = dict(zip(("left", "right"), _expected_corners(rig, pose, c, size)[:2]))
        for cam, img in images.items():
            uv = exp[cam]
            want = [uv[:, 0].min(), uv[:, 0].max(), uv[:, 1].min(), uv[:, 1].max()]
            np.testing.assert_allclose(_square_edges(img, uv), want, atol=0.1, err_msg=f"marker {lid}, {cam}")
            # the renderer's own projection agrees with the independent one
            np.testing.assert_allclose(r.project(pose, r.marker_corners(pose)[lid], cam)[0], uv, atol=1e-9)


@pytest.mark.parametrize("pitch", [0.0, 0.08])
def test_detected_corners_match_the_pinhole_model(pitch):
    """ArUco's corners on the rendered markers, pitched camera included.  The tolerance is 1.25 px:
    cornerSubPix is made for saddle points, and on a convex marker corner blurred by the optics'
    point spread (σ 0.8 px) it lands up to ~1.1 px inside (the subpixel edge test above pins the
    rendering itself to 0.1 px; the front end refines at full resolution in its own windows)."""
    pose = (10.0, 9.0, 0.3)
    size = 1.2
    rig, centres, r = _fronto_scene(pose, {1: (9.0, 1.5, 2.2), 2: (14.0, -3.0, 3.0)}, size, pitch)
    left, right_img = r.render(pose)
    det = FiducialDetector()
    found_l = {d.landmark_id: d for d in det.detect(left)}
    found_r = {d.landmark_id: d for d in det.detect(right_img)}
    assert set(found_l) == set(found_r) == {1, 2}
    for lid, c in centres.items():
        uv_l, uv_r, _ = _expected_corners(rig, pose, c, size, pitch)
        np.testing.assert_allclose(found_l[lid].corners, uv_l, atol=1.25)
        np.testing.assert_allclose(found_r[lid].corners, uv_r, atol=1.25)
        np.testing.assert_allclose(r.project(pose, r.marker_corners(pose)[lid], "left")[0], uv_l, atol=1e-9)


def test_marker_disparity_is_fB_over_Z_and_rows_agree():
    """Fronto-parallel markers at 6-25 m: the left minus right position of each vertical edge is
    f·B/Z (within 0.2 px, limited by the edge measurement on a 21 px marker at 25 m; the issue
    asks for a pixel), and rows agree (rectified)."""
    pose = (50.0, 50.0, -1.0)
    depths = {1: 6.0, 2: 11.0, 3: 17.0, 4: 25.0}
    lat = {1: -2.5, 2: 1.0, 3: -1.2, 4: 6.0}
    rig, centres, r = _fronto_scene(pose, {k: (z, lat[k], 2.0) for k, z in depths.items()}, 1.5)
    left, right_img = r.render(pose)
    assert sorted(r.visible(pose)) == [1, 2, 3, 4]
    for lid, z in depths.items():
        uv_l, uv_r, _ = _expected_corners(rig, pose, centres[lid], 1.5)
        el, er = _square_edges(left, uv_l), _square_edges(right_img, uv_r)
        np.testing.assert_allclose(el[:2] - er[:2], RIG.fB / z, atol=0.2, err_msg=f"marker {lid}")
        np.testing.assert_allclose(el[2:], er[2:], atol=0.1)
    # the detector sees all four in both images, with equal rows and its corners give f·B/Z within a pixel
    det = FiducialDetector()
    fl = {d.landmark_id: d for d in det.detect(left)}
    fr = {d.landmark_id: d for d in det.detect(right_img)}
    assert set(fl) == set(fr) == set(depths)
    for lid, z in depths.items():
        np.testing.assert_allclose(fl[lid].corners[:, 0] - fr[lid].corners[:, 0], RIG.fB / z, atol=1.0)
        # rows: the convex-corner slide of cornerSubPix (see above) differs between the images
        np.testing.assert_allclose(fl[lid].corners[:, 1], fr[lid].corners[:, 1], atol=1.25)


def test_visible_excludes_markers_hidden_by_nearer_ones():
    pose = (50.0, 50.0, 0.0)
    _, _, r = _fronto_scene(pose, {1: (6.0, 0.0, 2.0), 2: (15.0, 0.3, 2.0), 3: (15.0, 4.0, 2.0)}, 1.5)
    assert sorted(r.visible(pose)) == [1, 3]
    found = {d.landmark_id for d in FiducialDetector().detect(r.render(pose)[0])}
    assert found == {1, 3}


def _subpixel_shift(a: np.ndarray, b: np.ndarray, max_shift: int) -> float:
    """The shift s (a[u] ≈ b[u - s]) maximising the normalised cross-correlation, with a parabolic peak fit."""
    a = a.astype(float)
    b = b.astype(float)
    n = len(a)
    lo, hi = max_shift, n - max_shift
    ref = a[lo:hi] - a[lo:hi].mean()
    scores = []
    for s in range(max_shift + 1):
        seg = b[lo - s:hi - s] - b[lo - s:hi - s].mean()
        scores.append(ref @ seg / math.sqrt((ref @ ref) * (seg @ seg)))
    k = int(np.argmax(scores))
    k = min(max(k, 1), max_shift - 1)
    y0, y1, y2 = scores[k - 1], scores[k], scores[k + 1]
    return k + 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)


def test_ground_rows_shift_by_fB_over_Z():
    """On a level camera every ground pixel of row v lies at depth Z = h·f/(v - c_y), so the
    right image's row is the left one shifted by f·B/Z = B·(v - c_y)/h."""
    r = StereoRenderer(_world(), RIG)
    left, right = r.render((3.0, 7.0, 0.7))
    for v in (300, 360, 420, 470):
        want = RIG.baseline_m * (v - RIG.cy) / RIG.camera_height_m
        got = _subpixel_shift(left[v], right[v], int(want) + 4)
        assert got == pytest.approx(want, abs=0.15), v


def test_background_is_at_infinity_and_turns_with_the_heading():
    r = StereoRenderer(_world(), RIG)
    left, right = r.render((0.0, 0.0, 0.0))
    horizon = int(RIG.cy)
    np.testing.assert_array_equal(left[:horizon - 2], right[:horizon - 2])     # zero disparity
    # turning left by 40 px worth of angle at the image centre moves the background right by ~40 px
    dth = math.atan2(40.0, RIG.focal_length_px)
    turned, _ = r.render((0.0, 0.0, dth))
    row = 150
    assert _subpixel_shift(turned[row, 200:440], left[row, 200:440], 60) == pytest.approx(40.0, abs=1.5)


def test_culling_matches_brute_force_and_culled_markers_are_not_drawn():
    pose = (100.0, 100.0, math.pi / 2)   # looking north
    lms = {1: (100.0, 110.0, 2.0),   # ahead, 10 m
           2: (100.0, 90.0, 2.0),    # behind
           3: (100.0, 150.0, 2.0),   # ahead but beyond 30 m
           4: (130.0, 105.0, 2.0),   # far outside the 85° field of view (to the right)
           5: (104.0, 118.0, 3.0)}   # ahead, inside
    r = StereoRenderer(_world(*lms.items()), RIG)
    got = {r.landmarks[i].id for i in r.culled(pose)}
    half = RIG.horizontal_fov_rad / 2
    brute = set()
    for lid, p in lms.items():
        d = np.array(p) - [pose[0], pose[1], RIG.camera_height_m]
        ang = abs(math.atan2(-d[0], d[1]))          # heading north: forward = +y, left = -x
        if np.linalg.norm(d) <= RIG.max_range_m and d[1] > 0 and ang <= half:
            brute.add(lid)
    assert got == brute == {1, 5}
    only_visible = StereoRenderer(_world(*((k, lms[k]) for k in (1, 5))), RIG)
    a, b = r.render(pose), only_visible.render(pose)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert set(r.visible(pose)) == {1, 5}


def test_calibration_is_rectified_already():
    cal = RIG.calibration()
    np.testing.assert_array_equal(cal.R, np.eye(3))
    np.testing.assert_array_equal(cal.T, [-RIG.baseline_m, 0, 0])
    assert not np.any(cal.D1) and not np.any(cal.D2)
    m = StereoMatcher(cal)
    rect = m.rectification
    np.testing.assert_allclose(rect["R1"], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(rect["R2"], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(rect["P1"][:, :3], RIG.K, atol=1e-9)
    assert rect["P2"][0, 3] == pytest.approx(-RIG.fB)
    world = safenav.default_scenario().world
    c = world.cluster_centroid(6)
    left, right = StereoRenderer(world, RIG).render((c[0] - 15, c[1] - 3, 0.2))
    lr, rr = m.rectify(left, right)
    assert np.abs(lr.astype(int) - left).max() <= 1 and np.abs(rr.astype(int) - right).max() <= 1
    cam = RIG.rectified_camera()
    assert (cam.f, cam.cx, cam.cy, cam.baseline, cam.doffs) == (350.0, 319.5, 239.5, 0.3, 0.0)


def test_render_is_deterministic_and_noise_has_its_std():
    world = safenav.default_scenario().world
    c = world.cluster_centroid(1)
    pose = (c[0] - 20, c[1], 0.0)
    a = StereoRenderer(world, RIG, noise_std=3.0, seed=5).render(pose)
    b = StereoRenderer(world, RIG, noise_std=3.0, seed=5).render(pose)
    clean = StereoRenderer(world, RIG).render(pose)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    diff = a[0].astype(float) - clean[0]
    mid = (clean[0] > 20) & (clean[0] < 235)   # away from clipping
    assert diff[mid].std() == pytest.approx(3.0, rel=0.05)
    assert not np.array_equal(a[0], a[1])
    color = StereoRenderer(world, RIG, color=True).render(pose)[0]
    assert color.shape == (480, 640, 3) and np.array_equal(color[:, :, 0], clean[0])


def test_bad_input_names_the_value():
    world = _world((1, (10.0, 10.0, 2.0)))
    r = StereoRenderer(world, RIG)
    with pytest.raises(ValueError, match="finite"):
        r.render((np.nan, 0.0, 0.0))
    with pytest.raises(ValueError, match="pose"):
        r.render((1.0, 2.0))
    with pytest.raises(ValueError, match="landmark 120"):
        StereoRenderer(_world((120, (10.0, 10.0, 2.0))), RIG, dictionary="DICT_4X4_100")
    with pytest.raises(ValueError, match="focal_length_px"):
        StereoRig(focal_length_px=-1.0)
    with pytest.raises(ValueError, match="pitch_rad"):
        StereoRig(pitch_rad=float("nan"))
    with pytest.raises(ValueError, match="facing"):
        StereoRenderer(world, RIG, facing="north")
    with pytest.raises(ValueError, match="marker_size_m"):
        StereoRenderer(world, RIG, marker_size_m=0.0)
    with pytest.raises(ValueError, match="camera"):
        r.project((0, 0, 0), np.zeros((1, 3)), camera="middle")

"""LanBLoc's stereo front end in the C++ core (``safenav._core.LanBLocFrontEnd``,
cpp/include/safenav/lanbloc.hpp) on rendered stereo pairs: the same landmarks,
ranges, bearings and fix as the Python whole-frame pipeline with corner
ranging; search windows from a predicted pose (equal to the whole frame when
the prediction is right, blind outside them when it is wrong, the whole frame
when it is too uncertain); the windows' σ against Monte Carlo; statuses; bad
input; and the C++ example ``lanbloc_frames`` on PGM files, built against the
installed package."""

from __future__ import annotations

import math
import subprocess

import numpy as np
import pytest

from safenav import _core
from safenav.vision.lanbloc import LanBLoc
from safenav.vision.render import StereoRenderer, StereoRig
from safenav.world import Landmark, World
# The installed core and the examples built against it, as the other C++ examples are.
from test_cpp_example import _link_command, example_build, installed_prefix  # noqa: F401

RIG = StereoRig()           # 640x480, f = 350 px, B = 0.3 m, h = 1.5 m
# The corners' sub-pixel refinement stops once a step is below 0.1 px (ArUco's
# cornerRefinementMinAccuracy), so two detectors that start it from different
# integer corners may end up to ~0.1 px apart: the bound on the left/right
# disparity difference between OpenCV 4.6 (C++) and pip's cv2 (Python).
VERSION_PX = 0.1


def _scene(pose, placements):
    """Landmarks at (depth, lateral to the right, height) from the vehicle at ``pose``."""
    th = pose[2]
    fwd = np.array([math.cos(th), math.sin(th)])
    right = np.array([math.sin(th), -math.cos(th)])
    return World(landmarks=tuple(Landmark(k, (*(np.array(pose[:2]) + z * fwd + lat * right), hgt), f"class{k}", 1)
                                 for k, (z, lat, hgt) in placements.items()))


SCENES = [
    ((40.0, 60.0, 0.5), {1: (7.0, -3.0, 2.5), 2: (10.0, 2.0, 1.8), 3: (13.0, -0.5, 4.0), 4: (16.0, 6.0, 3.0),
                         5: (11.0, -8.5, 1.2)}),
    ((120.0, 30.0, -2.2), {7: (6.0, 1.5, 1.5), 8: (12.0, -3.5, 2.2), 9: (15.0, 3.5, 5.0)}),
    ((15.0, 40.0, 2.0), {11: (8.0, -1.0, 2.0), 12: (10.0, 3.0, 2.5), 13: (14.0, 7.5, 1.6), 14: (19.0, -7.5, 2.2)}),
]


def _front_end(world: World, rig: StereoRig = RIG, **settings) -> _core.LanBLocFrontEnd:
    cam = _core.RectifiedCamera()
    cam.f, cam.cx, cam.cy, cam.baseline, cam.doffs = rig.focal_length_px, rig.cx, rig.cy, rig.baseline_m, 0.0
    cam.width, cam.height = rig.width, rig.height
    s = _core.LanBLocSettings()
    for k, v in settings.items():
        setattr(s, k, v)
    return _core.LanBLocFrontEnd(_core.LanBLocRig(cam, rig.camera_height_m, rig.pitch_rad),
                                 {lm.id: (*lm.position[:2], lm.height) for lm in world.landmarks}, s)


def random_frame(rng, k: int, rig: StereoRig = RIG):
    """A random pose with 3-6 markers at 5-25 m within ±0.6 rad of the heading, heights 1-4 m, drawn
    from ``rng``, and its pair rendered with pixel noise σ = 1 (renderer seed ``k``):
    ``(pose, world, renderer, (left, right))``.  The frames of bench/bench_lanbloc_cpp.py and of
    tests/test_lanbloc_pyramid.py."""
    pose = (rng.uniform(40, 160), rng.uniform(40, 160), rng.uniform(-math.pi, math.pi))
    th = pose[2]
    fwd, right = np.array([math.cos(th), math.sin(th)]), np.array([math.sin(th), -math.cos(th)])
    lms = []
    for j in range(int(rng.integers(3, 7))):
        z = rng.uniform(5, 25)
        lat = z * math.tan(rng.uniform(-0.6, 0.6))
        lms.append(Landmark(j * 7 + int(rng.integers(0, 7)), (*(np.array(pose[:2]) + z * fwd + lat * right),
                                                              rng.uniform(1.0, 4.0)), "m", 1))
    world = World(landmarks=tuple(lms))
    ren = StereoRenderer(world, rig, noise_std=1.0, seed=k)
    return pose, world, ren, ren.render(pose)


def _pair(world, pose):
    return StereoRenderer(world, RIG, noise_std=1.0, seed=5).render(pose)


@pytest.fixture(scope="module", params=range(len(SCENES)), ids=lambda i: f"scene{i}")
def scene(request):
    pose, placements = SCENES[request.param]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    return pose, world, left, right, _front_end(world).localize(left, right)


def test_same_landmarks_ranges_and_fix_as_the_python_pipeline(scene):
    pose, world, left, right, cc = scene
    py = LanBLoc(world, RIG, ranging="corners", backend="python").localize(left, right)
    assert cc.search == _core.SearchMode.WHOLE_FRAME and cc.search_reason == "no prediction given"
    assert str(cc.status) == py.status == "ok", (cc.reason, py.reason)
    assert [o.landmark_id for o in cc.observations] == [o.landmark_id for o in py.observations]
    assert sorted(o.landmark_id for o in cc.observations) == sorted(lm.id for lm in world.landmarks)
    for q, o in zip(cc.observations, py.observations):
        assert q.ok and o.ok
        # ΔZ = Z²·Δd/(f·B), carried to the horizontal range as the pipeline's σ is (s/Z)·(s/ρ)
        bound = o.depth ** 2 * VERSION_PX / RIG.fB * (o.slant_range / o.depth) * (o.slant_range / o.range)
        assert abs(q.range - o.range) <= bound + 1e-5, (o.landmark_id, q.range, o.range, bound)
        assert abs(q.bearing - o.bearing) <= VERSION_PX / RIG.focal_length_px
        assert q.sigma == pytest.approx(o.sigma, rel=0.02)       # σ ∝ Z², Z within the bound
        assert q.bearing_sigma == pytest.approx(o.bearing_sigma, rel=1e-12)
        np.testing.assert_allclose(q.anchor, o.anchor, rtol=0, atol=1e-12)
    # the same trilateration on nearly the same ranges: the fixes agree, and both are near the truth
    assert np.linalg.norm(cc.position - py.position) < 0.05
    assert np.linalg.norm(cc.position - np.array(pose[:2])) < 0.3
    assert np.all(np.linalg.eigvalsh(cc.covariance) > 0) and cc.gdop == pytest.approx(cc.localization.gdop)


def test_ranging_follows_the_corner_model(scene):
    """Each range from the observation's own numbers: Z = f·B/d, s = Z·‖ray‖, ρ = sqrt(s² − Δh²),
    σ_ρ = Z²·σ_d/(f·B)·(s/Z)·(s/ρ) (σ_d: the corner-noise model); the bearing from the centre's column."""
    _, _, _, _, cc = scene
    for o in cc.observations:
        Z = RIG.fB / o.disparity
        assert o.depth == pytest.approx(Z, rel=1e-6)           # float disparity map in the core's depth()
        u, v = o.centre
        s = Z * math.sqrt(((u - RIG.cx) / RIG.focal_length_px) ** 2 + ((v - RIG.cy) / RIG.focal_length_px) ** 2 + 1)
        assert o.slant_range == pytest.approx(s, rel=1e-6)
        rho = math.sqrt(s * s - (o.anchor[2] - RIG.camera_height_m) ** 2)
        assert o.range == pytest.approx(rho, rel=1e-6)
        cl = np.asarray(o.corners_left)
        side = float(np.mean(np.linalg.norm(np.roll(cl, -1, 0) - cl, axis=1)))
        # the corner-noise model, ×5 for a marker under 30 px a side
        sigma_d = _core.corner_disparity_sigma(_core.LanBLocSettings(), o.corners_used, 1.0, side)
        assert sigma_d == _core.corner_disparity_sigma(_core.LanBLocSettings(), o.corners_used) * (5 if side < 30 else 1)
        assert o.sigma == pytest.approx(Z * Z * sigma_d / RIG.fB * (s / Z) * (s / rho), rel=1e-6)
        assert o.bearing == pytest.approx(math.atan2(-(u - RIG.cx), RIG.focal_length_px), abs=1e-12)


def _inside(corners, boxes) -> bool:
    return any(b[0] <= corners[:, 0].min() and corners[:, 0].max() < b[2] and
               b[1] <= corners[:, 1].min() and corners[:, 1].max() < b[3] for b in boxes)


def test_windows_from_a_correct_prediction_find_what_the_whole_frame_finds(scene):
    pose, _, left, right, whole = scene
    fe = _front_end(_scene(*SCENES[[s[0] for s in SCENES].index(pose)]))
    P = np.diag([0.3 ** 2, 0.3 ** 2, math.radians(2.0) ** 2])
    res = fe.localize(left, right, np.array(pose), P)
    assert res.search == _core.SearchMode.WINDOWS and res.search_reason == ""
    assert [o.landmark_id for o in res.observations] == [o.landmark_id for o in whole.observations]
    for a, b in zip(res.observations, whole.observations):
        assert _inside(a.corners_left, [w.box for w in res.windows if not w.right])
        np.testing.assert_allclose(a.corners_left, b.corners_left, atol=1e-3)
        assert a.range == pytest.approx(b.range, abs=1e-4)
    np.testing.assert_allclose(res.position, whole.position, atol=1e-3)
    # the windows (their union) are at most max_window_fraction of the frame
    mask = np.zeros((RIG.height, RIG.width), bool)
    for w in res.windows:
        if not w.right:
            mask[int(w.box[1]):int(w.box[3]), int(w.box[0]):int(w.box[2])] = True
    assert mask.mean() <= 0.5


def test_a_wrong_heading_misses_the_markers_outside_the_windows():
    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    fe = _front_end(world)
    whole = {o.landmark_id: o for o in fe.localize(left, right).observations}
    wrong = np.array(pose) + [0.0, 0.0, math.radians(20.0)]
    res = fe.localize(left, right, wrong, np.diag([0.3 ** 2, 0.3 ** 2, math.radians(2.0) ** 2]))
    assert res.search == _core.SearchMode.WINDOWS
    found = {o.landmark_id for o in res.observations}
    outside = {i for i, o in whole.items() if not _inside(o.corners_left, res.left_regions)}
    assert outside, "the 20 degree error should move some window off its marker"
    assert not found & outside                      # a marker outside every searched region is not detected
    assert found == set(whole) - outside            # every marker inside one is
    # the searched regions are the windows, merged where they overlap
    for w in res.windows:
        if not w.right:
            assert _inside(np.array([w.box[:2], np.array(w.box[2:]) - 1]), res.left_regions)
    assert str(res.status) in ("ok", "too_few_ranges")


def test_too_uncertain_or_no_prediction_searches_the_whole_frame(scene):
    pose, _, left, right, whole = scene
    # heading σ = 30°: each window spans the frame's width (3σ ≈ ±550 px); its height stays the board's
    fe = _front_end(_scene(*SCENES[[s[0] for s in SCENES].index(pose)]), max_window_fraction=0.25)
    res = fe.localize(left, right, np.array(pose), np.diag([4.0, 4.0, math.radians(30.0) ** 2]))
    assert res.search == _core.SearchMode.WHOLE_FRAME and "too uncertain" in res.search_reason
    share = float(res.search_reason.split("windows cover ")[1].split()[0])
    assert 0.25 < share <= 1.0
    assert not res.windows
    np.testing.assert_allclose(res.position, whole.position, rtol=0, atol=0)
    windows, mode, reason = fe.search_windows(np.array(pose), np.diag([4.0, 4.0, math.radians(30.0) ** 2]))
    assert mode == _core.SearchMode.WHOLE_FRAME and reason == res.search_reason and windows


def test_window_sigma_is_the_projected_pose_covariance():
    """σ of the predicted marker centre against Monte Carlo over poses drawn from the covariance,
    projected with the renderer's own camera model."""
    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    fe = _front_end(world)
    P = np.array([[0.04, 0.01, 0.0], [0.01, 0.09, 0.002], [0.0, 0.002, math.radians(1.0) ** 2]])
    windows, mode, _ = fe.search_windows(np.array(pose), P)
    assert mode == _core.SearchMode.WINDOWS
    rng = np.random.default_rng(1)
    poses = rng.multivariate_normal(pose, P, size=4000)
    renderer = StereoRenderer(world, RIG)
    by_id = {lm.id: lm for lm in world.landmarks}
    for w in windows:
        lm = by_id[w.landmark_id]
        point = np.array([[*lm.position[:2], lm.height]])
        cam = "right" if w.right else "left"
        uv0, _ = renderer.project(pose, point, cam)
        np.testing.assert_allclose(w.predicted_centre, uv0[0], atol=1e-9)
        uv = np.array([renderer.project(p, point, cam)[0][0] for p in poses])
        np.testing.assert_allclose(w.sigma_px, uv.std(axis=0), rtol=0.06)


def test_statuses_say_why():
    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    away = _front_end(world).localize(*_pair(world, (pose[0], pose[1], pose[2] + math.pi)))
    assert str(away.status) == "no_landmarks" and "no landmark recognised" in away.reason
    two = _scene(pose, {k: placements[k] for k in (1, 2)})
    res = _front_end(two).localize(*_pair(two, pose))
    assert str(res.status) == "too_few_ranges" and res.reason.startswith("2 usable range(s), 3 needed")
    # markers outside the map are reported, not ranged
    res = _front_end(_scene(pose, {k: placements[k] for k in (1, 2, 3)})).localize(left, right)
    assert sorted(res.unmapped) == [4, 5] and [o.landmark_id for o in res.observations] == [1, 2, 3]
    # a corner row mismatch beyond max_row_error_px rejects the range with the reason
    res = _front_end(world, max_row_error_px=1e-6).localize(left, right)
    assert str(res.status) == "too_few_ranges" and all("off their epipolar lines" in o.reason
                                                       for o in res.observations if not o.ok)
    res = _front_end(world, max_range_m=9.0).localize(left, right)
    far = [o for o in res.observations if not o.ok]
    assert far and all("beyond resolvable range" in o.reason and o.depth != o.depth for o in far)


def test_bad_input_names_the_value():
    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    fe = _front_end(world)
    with pytest.raises(ValueError, match="left image is 320x480 px but the rig is 640x480"):
        fe.localize(left[:, :320], right)
    with pytest.raises(ValueError, match="right image must be .* grey"):
        fe.localize(left, np.dstack([right] * 3))
    with pytest.raises(ValueError, match="dictionary = 'DICT_9X9_1': unknown"):
        _front_end(world, dictionary="DICT_9X9_1")
    with pytest.raises(ValueError, match="landmark id 100 is not in dictionary DICT_4X4_100"):
        _front_end(_scene(pose, {100: (7.0, 0.0, 2.0)}))
    with pytest.raises(ValueError, match="min_landmarks"):
        _front_end(world, min_landmarks=2)
    with pytest.raises(ValueError, match="max_window_fraction"):
        _front_end(world, max_window_fraction=1.5)
    with pytest.raises(ValueError, match="prediction.covariance"):
        fe.localize(left, right, np.array(pose), -np.eye(3))
    with pytest.raises(ValueError, match="prediction.pose"):
        fe.localize(left, right, np.array([np.nan, 0.0, 0.0]), np.eye(3))
    with pytest.raises(ValueError, match="given together"):
        fe.localize(left, right, np.array(pose))
    cam = _core.RectifiedCamera()
    with pytest.raises(ValueError):
        _core.LanBLocFrontEnd(_core.LanBLocRig(cam, 1.5, 0.0), {1: (0.0, 0.0, 1.0)})
    with pytest.raises(ValueError, match="landmark 1 has a non-finite position"):
        _core.LanBLocFrontEnd(fe.rig, {1: (np.nan, 0.0, 1.0)})


def test_settings_are_declared_parameters():
    names = [p.name for p in _core.LanBLocSettings.params()]
    assert {"corner_sigma_d", "max_row_error_px", "min_landmarks", "window_sigmas", "max_window_fraction",
            "trilateration.outlier_threshold"} <= set(names)
    s = _core.LanBLocSettings()
    s.set_param("window_sigmas", 2.0)
    assert s.window_sigmas == 2.0
    with pytest.raises(ValueError, match="window_sigmas"):
        s.set_param("window_sigmas", -1.0)


# --------------------------------------------------------------------------- the C++ example

def _write_pgm(path, img):
    h, w = img.shape
    path.write_bytes(b"P5\n# rendered by safenav.vision.render\n%d %d\n255\n" % (w, h) + img.tobytes())


def _config(world, prediction=None) -> str:
    r = RIG
    lines = [f"camera {r.focal_length_px!r} {r.cx!r} {r.cy!r} {r.baseline_m!r} 0 {r.width} {r.height}",
             f"rig {r.camera_height_m!r} {r.pitch_rad!r}", "dictionary DICT_4X4_100", "marker_size_m 1.5"]
    lines += [f"landmark {lm.id} {lm.position[0]!r} {lm.position[1]!r} {lm.height!r}" for lm in world.landmarks]
    if prediction is not None:
        lines.append("prediction " + " ".join(repr(float(v)) for v in prediction))
    return "\n".join(lines) + "\n"


def _fields(line: str) -> dict:
    return dict(kv.split("=", 1) for kv in line.split() if "=" in kv)


@pytest.fixture(scope="module")
def example_exe(example_build):  # noqa: F811
    build = example_build
    link = _link_command(build, "lanbloc_frames").split()
    assert any("libsafenav_core.so" in tok for tok in link), link
    assert not [tok for tok in link if "opencv" in tok.lower()], link   # OpenCV stays inside the core
    return build / "lanbloc_frames"


@pytest.mark.parametrize("k", range(len(SCENES)))
def test_example_reads_pgm_pairs_and_prints_the_fix(example_exe, tmp_path, k):
    pose, placements = SCENES[k]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    _write_pgm(tmp_path / "left.pgm", left)
    _write_pgm(tmp_path / "right.pgm", right)
    fe = _front_end(world)
    for prediction, mode in ((None, "whole_frame"), ((*pose, 0.3, math.radians(2.0)), "windows")):
        ref = fe.localize(left, right) if prediction is None else \
            fe.localize(left, right, np.array(pose), np.diag([0.3 ** 2, 0.3 ** 2, math.radians(2.0) ** 2]))
        (tmp_path / "rig.txt").write_text(_config(world, prediction))
        proc = subprocess.run([str(example_exe), str(tmp_path / "rig.txt"), str(tmp_path / "left.pgm"),
                               str(tmp_path / "right.pgm")], capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        lines = proc.stdout.splitlines()
        fix = _fields(next(line for line in lines if line.startswith("fix ")))
        assert fix["status"] == "ok" and fix["search"] == mode
        xy = np.array([float(fix["x"]), float(fix["y"])])
        assert np.linalg.norm(xy - np.array(pose[:2])) < 0.3                 # the truth
        np.testing.assert_allclose(xy, ref.position, atol=2e-6)             # the bound front end (%.6f)
        obs = [_fields(line) for line in lines if line.startswith("observation ")]
        assert [int(o["id"]) for o in obs] == [o.landmark_id for o in ref.observations]
        assert int(fix["ranges"]) == len(placements)


def test_example_ranges_with_sgbm_and_ranges_boxes_of_ones_own(example_exe, tmp_path):
    """``ranging sgbm``: the core's markers ranged by SGBM box medians; ``box`` lines: a detector of
    one's own, its boxes ranged the same way (no marker detection); both equal the binding."""
    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    _write_pgm(tmp_path / "left.pgm", left)
    _write_pgm(tmp_path / "right.pgm", right)
    fe = _front_end(world, ranging=_core.LanBLocRanging.SGBM)
    ref = fe.localize(left, right)
    boxes = [(o.landmark_id, o.box) for o in ref.observations]
    for extra, want in (("ranging sgbm\n", ref),
                        ("".join(f"box {i} {b[0]!r} {b[1]!r} {b[2]!r} {b[3]!r}\n" for i, b in boxes),
                         _front_end(world).localize_boxes(left, right, boxes))):
        (tmp_path / "rig.txt").write_text(_config(world) + extra)
        proc = subprocess.run([str(example_exe), str(tmp_path / "rig.txt"), str(tmp_path / "left.pgm"),
                               str(tmp_path / "right.pgm")], capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        lines = proc.stdout.splitlines()
        fix = _fields(next(line for line in lines if line.startswith("fix ")))
        assert fix["status"] == "ok"
        np.testing.assert_allclose([float(fix["x"]), float(fix["y"])], want.position, atol=2e-6)
        obs = [_fields(line) for line in lines if line.startswith("observation ")]
        np.testing.assert_allclose([float(o["range"]) for o in obs], [o.range for o in want.observations], atol=2e-6)
    (tmp_path / "rig.txt").write_text(_config(world) + "ranging dense\n")
    proc = subprocess.run([str(example_exe), str(tmp_path / "rig.txt"), str(tmp_path / "left.pgm"),
                           str(tmp_path / "right.pgm")], capture_output=True, text=True)
    assert proc.returncode == 2 and "'ranging'" in proc.stderr


def test_example_reports_bad_input(example_exe, tmp_path):
    pose, placements = SCENES[1]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    _write_pgm(tmp_path / "l.pgm", left)
    _write_pgm(tmp_path / "r.pgm", right[:, :320].copy())
    (tmp_path / "c.txt").write_text(_config(world))
    exe = str(example_exe)
    proc = subprocess.run([exe, str(tmp_path / "c.txt"), str(tmp_path / "l.pgm"), str(tmp_path / "r.pgm")],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and "right image is 320x480 px but the rig is 640x480 px" in proc.stderr
    (tmp_path / "bad.txt").write_text("camera 350 319.5\n")
    proc = subprocess.run([exe, str(tmp_path / "bad.txt"), str(tmp_path / "l.pgm"), str(tmp_path / "l.pgm")],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and "line 1" in proc.stderr and "'camera'" in proc.stderr
    proc = subprocess.run([exe, str(tmp_path / "c.txt"), str(tmp_path / "missing.pgm"), str(tmp_path / "l.pgm")],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and "cannot open" in proc.stderr
    # no landmark in view: no fix, exit status 1 with the reason
    _write_pgm(tmp_path / "away.pgm", _pair(world, (pose[0], pose[1], pose[2] + math.pi))[0])
    proc = subprocess.run([exe, str(tmp_path / "c.txt"), str(tmp_path / "away.pgm"), str(tmp_path / "away.pgm")],
                          capture_output=True, text=True)
    assert proc.returncode == 1 and "status=no_landmarks" in proc.stdout


def test_a_pitched_rig_ranges_and_predicts_windows_as_python():
    """Pitch enters the bearing (the centre's ray at heading 0), the slant range and the windows'
    projection; with the camera looking up 0.08 rad, both pipelines and the windows still agree."""
    rig = StereoRig(pitch_rad=0.08)
    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    left, right = StereoRenderer(world, rig, noise_std=1.0, seed=5).render(pose)
    py = LanBLoc(world, rig, ranging="corners", backend="python").localize(left, right)
    fe = _front_end(world, rig)
    cc = fe.localize(left, right)
    assert str(cc.status) == py.status == "ok"
    assert [o.landmark_id for o in cc.observations] == [o.landmark_id for o in py.observations]
    for q, o in zip(cc.observations, py.observations):
        bound = o.depth ** 2 * VERSION_PX / rig.fB * (o.slant_range / o.depth) * (o.slant_range / o.range)
        assert abs(q.range - o.range) <= bound + 1e-5 and abs(q.bearing - o.bearing) <= VERSION_PX / rig.focal_length_px
    res = fe.localize(left, right, np.array(pose), np.diag([0.3 ** 2, 0.3 ** 2, math.radians(2.0) ** 2]))
    assert res.search == _core.SearchMode.WINDOWS
    assert [o.landmark_id for o in res.observations] == [o.landmark_id for o in cc.observations]
    renderer = StereoRenderer(world, rig)
    for w in res.windows:
        lm = next(lm for lm in world.landmarks if lm.id == w.landmark_id)
        uv, _ = renderer.project(pose, [[*lm.position[:2], lm.height]], "right" if w.right else "left")
        np.testing.assert_allclose(w.predicted_centre, uv[0], atol=1e-9)


def test_one_front_end_serves_several_threads():
    """localize releases the GIL and writes no shared state: threads on one front end get the
    single-threaded results."""
    from concurrent.futures import ThreadPoolExecutor

    frames = []
    for pose, placements in SCENES:
        world = _scene(pose, placements)
        frames.append((world, pose, *_pair(world, pose)))
    world = World(landmarks=tuple(lm for f in frames for lm in f[0].landmarks))
    fe = _front_end(world)
    P = np.diag([0.3 ** 2, 0.3 ** 2, math.radians(2.0) ** 2])
    jobs = [(left, right, np.array(pose) if k % 2 else None, P if k % 2 else None)
            for k, (_, pose, left, right) in enumerate(frames * 4)]
    serial = [fe.localize(*j) for j in jobs]
    with ThreadPoolExecutor(4) as pool:
        parallel = list(pool.map(lambda j: fe.localize(*j), jobs))
    for a, b in zip(serial, parallel):
        assert str(a.status) == str(b.status) and a.search == b.search
        np.testing.assert_array_equal(a.position, b.position)
        assert [o.range for o in a.observations] == [o.range for o in b.observations]

"""The camera loop through the core's LanBLoc front end: ``Localizer.observe_frame`` searches
where the filter's own prediction says (equal to planning with the prediction, localizing and
fixing by hand), a wrong estimate costs detections, a lost or uncertain one searches the whole
frame; the renderer draws the planned regions as the whole frame has them (ground and
background included); and ``Navigator.run_frames`` closes the loop, deterministically."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import safenav
from safenav import _core
from safenav import navigation as nv
from safenav.vision.camera_loop import CameraFrames, front_end
from safenav.vision.render import StereoRenderer
from safenav.vision.rig import StereoRig
from safenav.world import Landmark, World
from test_lanbloc_cpp import RIG, SCENES, _pair, _scene
from test_lanbloc_sgbm import BoxesOnly

POSE, PLACEMENTS = SCENES[0]


@pytest.fixture(scope="module")
def scene():
    world = _scene(POSE, PLACEMENTS)
    left, right = _pair(world, POSE)
    return world, left, right, front_end(world, RIG, marker_size_m=1.5)


def _localizer(world, fe, pose, P_pose, speed=0.0):
    ids = [lm.id for lm in world.landmarks]
    loc = _core.Localizer(_core.LocalizerSettings(), np.array([lm.position[:2] for lm in world.landmarks]), ids)
    P = np.diag([P_pose[0, 0], P_pose[1, 1], 0.01, P_pose[2, 2]])
    loc.initialize(0.0, np.array([pose[0], pose[1], speed, pose[2]]), P)
    loc.set_front_end(fe)
    return loc


def _pose_cov(x, P):
    i = [0, 1, 3]
    return x[i], P[np.ix_(i, i)]


def test_observe_frame_is_the_front_end_with_the_filters_prediction_then_fix(scene):
    world, left, right, fe = scene
    P3 = np.diag([0.2 ** 2, 0.2 ** 2, math.radians(1.5) ** 2])
    a, b = (_localizer(world, fe, POSE, P3, speed=1.0) for _ in range(2))
    for loc in (a, b):
        loc.motion(0.1, 1.0, 0.0)
    # by hand: the filter's prediction to t, the front end's plan from it, localize, fix
    x, P = b.predict_to(0.3)
    plan = fe.plan(*_pose_cov(x, P))
    fix = fe.localize_plan(left, right, plan)
    want = b.fix(0.3, *fix.position, fix.covariance)
    got = a.observe_frame(0.3, left, right)
    assert got.plan.mode == _core.SearchMode.WINDOWS and got.plan.reason == ""
    assert got.plan.left_regions == plan.left_regions and got.plan.right_regions == plan.right_regions
    np.testing.assert_array_equal(got.plan.prediction[0], _pose_cov(x, P)[0])
    assert str(got.fix.status) == "ok" and got.fix.search == _core.SearchMode.WINDOWS
    np.testing.assert_array_equal(got.fix.position, fix.position)
    assert got.update.status == want.status == _core.InputStatus.APPLIED and got.update.nis == want.nis
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.P, b.P)
    assert [s.status for s in got.landmarks] == [_core.InputStatus.APPLIED] * len(got.fix.observations)
    # every marker the whole frame finds is found in the windows of a right estimate
    whole = fe.localize(left, right)
    assert [o.landmark_id for o in got.fix.observations] == [o.landmark_id for o in whole.observations]


def test_landmark_updates_gate_each_range_and_bearing(scene):
    world, left, right, fe = scene
    P3 = np.diag([0.2 ** 2, 0.2 ** 2, math.radians(1.5) ** 2])
    a, b = (_localizer(world, fe, POSE, P3) for _ in range(2))
    got = a.observe_frame(0.0, left, right, _core.FrameUpdate.LANDMARKS)
    assert got.plan.mode == _core.SearchMode.WINDOWS
    for o, s in zip(got.fix.observations, got.landmarks):
        assert o.ok
        want = b.observe(0.0, o.landmark_id, o.range, o.bearing, o.sigma, o.bearing_sigma)
        assert s.status == want.status and s.nis == pytest.approx(want.nis, rel=1e-12)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)
    assert got.update.applied


def test_a_wrong_estimate_costs_detections(scene):
    world, left, right, fe = scene
    whole = {o.landmark_id for o in fe.localize(left, right).observations}
    # confident and 20 degrees off: the windows sit beside the markers
    wrong = (POSE[0], POSE[1], POSE[2] + math.radians(20.0))
    loc = _localizer(world, fe, wrong, np.diag([0.2 ** 2, 0.2 ** 2, math.radians(1.5) ** 2]))
    got = loc.observe_frame(0.0, left, right)
    assert got.plan.mode == _core.SearchMode.WINDOWS
    found = {o.landmark_id for o in got.fix.observations}
    assert found < whole
    assert str(got.fix.status) != "ok" or got.update.status != _core.InputStatus.APPLIED or len(found) < len(whole)


def test_lost_or_uncertain_estimates_search_the_whole_frame(scene):
    world, left, right, fe = scene
    whole = fe.localize(left, right)
    lost = _localizer(world, fe, POSE, np.diag([30.0 ** 2, 30.0 ** 2, 1.0]))
    got = lost.observe_frame(0.0, left, right)
    assert got.plan.mode == _core.SearchMode.WHOLE_FRAME and "too uncertain" in got.plan.reason
    np.testing.assert_array_equal(got.fix.position, whole.position)
    ids = [lm.id for lm in world.landmarks]
    fresh = _core.Localizer(_core.LocalizerSettings(), np.array([lm.position[:2] for lm in world.landmarks]), ids)
    fresh.set_front_end(fe)
    plan = fresh.frame_plan(0.0)
    assert plan.mode == _core.SearchMode.WHOLE_FRAME and "not started" in plan.reason and plan.prediction is None
    # a frame older than the filter: no prediction for it
    late = _localizer(world, fe, POSE, np.diag([0.04, 0.04, 0.001]))
    late.motion(1.0, 0.0, 0.0)
    assert "older than the filter" in late.frame_plan(0.5).reason


def test_bad_frame_input_is_named(scene):
    world, left, right, fe = scene
    loc = _localizer(world, fe, POSE, np.diag([0.04, 0.04, 0.001]))
    with pytest.raises(ValueError, match="left image is 320x480"):
        loc.observe_frame(0.0, left[:, :320], right)
    with pytest.raises(ValueError, match="frame time t = nan"):
        loc.frame_plan(float("nan"))
    bare = _core.Localizer(_core.LocalizerSettings())
    with pytest.raises(ValueError, match="no front end"):
        bare.frame_plan(0.0)
    other = _core.Localizer(_core.LocalizerSettings(), np.array([[0.0, 0.0]]), [99])
    other.initialize(0.0, np.array([POSE[0], POSE[1], 0.0, POSE[2]]), np.diag([0.04, 0.04, 0.01, 0.001]))
    other.set_front_end(fe)
    assert other.observe_frame(0.0, left, right).update.applied      # a fix needs no map ids
    with pytest.raises(ValueError, match="front end landmark 1 is not in the localizer's map"):
        other.observe_frame(0.0, left, right, _core.FrameUpdate.LANDMARKS)


def test_regions_are_drawn_as_the_whole_frame_draws_them():
    world = _scene(POSE, PLACEMENTS)
    r = StereoRenderer(world, RIG, noise_std=0.0)
    left, right = r.render(POSE)
    boxes = [(0, 0, RIG.width, RIG.height)]
    l2, r2 = r.render_regions(POSE, boxes, boxes)
    np.testing.assert_array_equal(l2, left)
    np.testing.assert_array_equal(r2, right)
    # a window below the horizon (ground texture) and one on a marker: the whole frame's pixels
    boxes = [(10, 400, 200, 470), (300, 150, 420, 260)]
    l3, r3 = r.render_regions(POSE, boxes, boxes[:1])
    for x0, y0, x1, y1 in boxes:
        d = np.abs(l3[y0:y1, x0:x1].astype(int) - left[y0:y1, x0:x1])
        assert d.max() <= 1 and d.mean() < 0.01
    assert l3[:100, 500:].max() == 0 and r3[150:260, 300:420].max() == 0      # nothing outside
    assert left[400:470, 10:200].std() > 5                                      # the ground is textured there


def test_camera_frames_run_the_loop_deterministically():
    sc = safenav.default_scenario()
    path = np.asarray(nv.plan_safe_path(sc, "P3", iterations=1500).path)
    nav = nv.make_navigator(sc, path, method="centroid", position_every=40, record=False)
    runs = []
    for _ in range(2):
        src = CameraFrames.from_scenario(sc, seed=5)
        runs.append((src.run(nav, 5), src.stats))
    (a, sa), (b, sb) = runs
    assert a.success, a.reason
    assert a.steps == b.steps and a.position_fixes == b.position_fixes and a.metrics["truth_ade"] == \
        b.metrics["truth_ade"]
    assert a.position_fixes > 0 and sa["windows"] > 0
    # one frame at the start (whole frame, no estimate yet) and one every 40 steps
    assert sa["frames"] == 1 + a.steps // 40
    # each later frame gave a fix (applied, or rejected by the gate) or a dropout; rejected counts the IMU's too
    assert a.position_fixes + a.dropouts <= a.steps // 40 <= a.position_fixes + a.dropouts + a.rejected


def test_the_scenarios_camera_ranging_selects_the_front_ends_ranging():
    """``camera.ranging = "sgbm"``: the camera loop's front end ranges each marker by the
    paper's SGBM box median; the default keeps the corners; a keyword overrides the scenario."""
    sc = safenav.default_scenario()
    d = sc.to_dict()
    d["camera"]["ranging"] = "sgbm"
    sgbm = safenav.Scenario.from_dict(d)
    assert CameraFrames.from_scenario(sc, 640).front_end.settings.ranging == _core.LanBLocRanging.CORNERS
    src = CameraFrames.from_scenario(sgbm, 640, seed=5)
    assert src.front_end.settings.ranging == _core.LanBLocRanging.SGBM
    assert CameraFrames.from_scenario(sgbm, 640, ranging=_core.LanBLocRanging.CORNERS).front_end.settings.ranging \
        == _core.LanBLocRanging.CORNERS
    path = np.asarray(nv.plan_safe_path(sc, "P3", iterations=1500).path)
    nav = nv.make_navigator(sgbm, path, method="centroid", position_every=40, record=False)
    r = src.run(nav, 5)
    assert r.success and r.position_fixes > 0, r.reason


def test_the_loops_localizer_names_landmarks_as_the_front_end_does():
    """The navigator's localizer carries the world's ids (1 … 39 in the default scenario, not the
    map's rows), so a landmark sighting updates the landmark it names; a front end whose ids or
    positions are not the map's is refused by name, and bad ids are named."""
    sc = safenav.default_scenario()
    ids = [lm.id for lm in sc.world.landmarks]
    assert ids != list(range(len(ids)))                      # the case a mapping by rows would get wrong
    path = np.asarray(nv.plan_safe_path(sc, "P3", iterations=1500).path)
    nav = nv.make_navigator(sc, path, method="centroid", position_every=40, record=False)
    assert list(nav.sensors.landmark_ids) == ids
    src = CameraFrames.from_scenario(sc, seed=5)
    assert src.run(nav, 5).success

    def navigator(landmark_ids, landmarks=None):
        se = nav.sensors
        se.landmark_ids = landmark_ids
        if landmarks is not None:
            se.landmarks = landmarks
        return _core.Navigator(nav.problem, nav.settings, se)

    with pytest.raises(ValueError, match=r"front end landmark id 1 at .* is not in the map's ids"):
        src.run(navigator([i + 100 for i in ids]), 5)
    with pytest.raises(ValueError, match=r"front end landmark id 1 is at .* the map's landmark 1 at"):
        src.run(navigator([]), 5)                            # the default ids 0 … 38: id 1 is row 1's
    moved = np.array(nav.sensors.landmarks)
    moved[[0, 1]] = moved[[1, 0]]                            # ids 1 and 2 at each other's place
    with pytest.raises(ValueError, match=r"front end landmark id 1 is at .* the map's landmark 1 at"):
        src.run(navigator(ids, moved), 5)
    with pytest.raises(ValueError, match=r"sensors.landmark_ids: 38 ids for 39 landmarks"):
        navigator(ids[:-1])
    with pytest.raises(ValueError, match=r"sensors.landmark_ids: id 1 repeats"):
        navigator([1] + ids[:-1])


@pytest.mark.parametrize("k", range(len(SCENES)))
def test_lanbloc_core_backend_is_the_front_end_under_the_python_api(k):
    from safenav.vision.lanbloc import LanBLoc

    pose, placements = SCENES[k]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    core = LanBLoc(world, RIG, ranging="corners", backend="core").localize(left, right)
    py = LanBLoc(world, RIG, ranging="corners", backend="python").localize(left, right)
    fe = front_end(world, RIG).localize(left, right)
    assert core.status == str(fe.status) == py.status == "ok"
    # the same sightings as the front end's, solved by the shared last step: the front end's fix
    assert [o.landmark_id for o in core.observations] == [o.landmark_id for o in fe.observations]
    assert [o.range for o in core.observations] == [o.range for o in fe.observations]
    np.testing.assert_allclose(core.position, fe.position, rtol=0, atol=1e-9)
    np.testing.assert_allclose(core.covariance, fe.covariance, rtol=1e-9, atol=1e-15)
    # the Python pipeline's landmarks, and its fix within the two OpenCV versions' corner difference
    assert [o.landmark_id for o in core.observations] == [o.landmark_id for o in py.observations]
    assert np.linalg.norm(core.position - py.position) < 0.05
    # landmark faults act on the core's ranges as on the Python pipeline's
    faults = _core.LandmarkFaults(1.0, 0.0, 1.0, 0.0)
    dropped = LanBLoc(world, RIG, ranging="corners", backend="core").localize(left, right, faults=faults,
                                                                              position=np.array(pose[:2]))
    assert dropped.status == "too_few_ranges" and dropped.dropped == len(fe.observations)
    with pytest.raises(ValueError, match="ranging = 'corners' needs a fiducial detector .marker corners., "
                                         "not BoxesOnly"):
        LanBLoc(world, RIG, BoxesOnly(world), ranging="corners", backend="core")


def test_the_default_backend_is_the_core_where_it_serves():
    """backend="auto": the default detector runs in the core, with either ranging (the result is the
    core backend's, bit for bit); a detector passed in keeps the Python pipeline; a bad name is named."""
    from safenav.vision.detect import FiducialDetector
    from safenav.vision.lanbloc import LanBLoc

    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    auto = LanBLoc(world, RIG, ranging="corners")
    assert auto.backend == "core"
    a, c = auto.localize(left, right), LanBLoc(world, RIG, ranging="corners", backend="core").localize(left, right)
    assert a.status == c.status == "ok"
    assert np.array_equal(a.position, c.position) and np.array_equal(a.covariance, c.covariance)
    assert [o.range for o in a.observations] == [o.range for o in c.observations]
    assert LanBLoc(world, RIG, FiducialDetector(world), ranging="corners").backend == "python"
    assert LanBLoc(world, RIG).backend == "core"                         # SGBM too
    assert LanBLoc(world, RIG, FiducialDetector(world)).backend == "python"
    with pytest.raises(ValueError, match="backend = 'gpu': must be 'auto', 'python' or 'core'"):
        LanBLoc(world, RIG, backend="gpu")


@settings(max_examples=60, deadline=None)
@given(d=st.floats(3.0, 29.0), bearing=st.floats(-0.55, 0.55), height=st.floats(0.3, 5.0),
       yaw=st.one_of(st.none(), st.floats(-math.pi, math.pi)), th=st.floats(-math.pi, math.pi),
       pitch=st.sampled_from([0.0, -0.08, 0.1]))
def test_a_window_holds_its_board_at_any_yaw(d, bearing, height, yaw, th, pitch):
    """With a certain prediction (σ ≈ 0) and no margin, each landmark's window is the projected
    bound of its upright board at any yaw (the prism around the board's cylinder): the board the
    renderer draws, facing the camera or at a fixed yaw, lies inside it in both images (its
    footprint is the corners' box floored − 1 px and ceiled + 2 px, the window's ceiled + 1)."""
    rig = StereoRig(width=1280, height=720, focal_length_px=700.0, pitch_rad=pitch)
    pose = (100.0, 100.0, th)
    lm = Landmark(7, (pose[0] + d * math.cos(th + bearing), pose[1] + d * math.sin(th + bearing), height), "m", 1)
    world = World(landmarks=(lm,))
    ren = StereoRenderer(world, rig, facing="camera" if yaw is None else {7: yaw}, occlusion=False)
    fe = front_end(world, rig, window_margin_px=0.0)
    plan = fe.plan(np.array(pose), np.diag([1e-12, 1e-12, 1e-14]))
    frame = ren.frame(pose, 0)
    for cam, right in (("left", False), ("right", True)):
        fp = frame.footprints(cam).get(7)
        if fp is None:
            continue
        (w,) = [w for w in plan.windows if w.right == right and w.landmark_id == 7] or [None]
        assert w is not None, (cam, fp)
        x0, y0, x1, y1 = w.box
        assert x0 <= fp[0] + 1 and y0 <= fp[1] + 1 and x1 >= fp[2] - 1 and y1 >= fp[3] - 1, (cam, w.box, fp)
        inside = fp[0] > 0 and fp[1] > 0 and fp[2] < rig.width and fp[3] < rig.height
        # and tight beyond a few board sides (nearer, a turned board's near edge is much closer than
        # its centre, and the bound must hold it): a ball around the board would be twice the area
        if yaw is None and inside and d >= 8.0:
            assert (x1 - x0) * (y1 - y0) <= 1.4 * (fp[2] - fp[0] - 3) * (fp[3] - fp[1] - 3) + 100, (cam, w.box, fp)


@settings(max_examples=60, deadline=None)
@given(x=st.floats(-20.0, 20.0), y=st.floats(-20.0, 20.0), th=st.floats(-math.pi, math.pi),
       sx=st.floats(0.0, 6.0), st_=st.floats(0.0, 0.3), fraction=st.floats(0.0, 0.6))
def test_the_uncertainty_switch_counts_the_windows_union_exactly(x, y, th, sx, st_, fraction):
    """The plan searches the whole frame exactly when the union of the left image's windows covers
    more than max_window_fraction of it: the share it reports is the pixel count of a mask of the
    windows (overlaps counted once), for many landmarks in and out of view, at any uncertainty."""
    rig = StereoRig(width=640, height=360, focal_length_px=350.0)
    rng = np.random.default_rng(3)
    world = World(landmarks=tuple(Landmark(i, (*rng.uniform(75, 125, 2), rng.uniform(0.5, 3.0)), "m", 1)
                                  for i in range(12)))
    fe = front_end(world, rig, max_window_fraction=fraction)
    pose, cov = np.array([100.0 + x, 100.0 + y, th]), np.diag([sx ** 2, sx ** 2, st_ ** 2])
    windows, mode, reason = fe.search_windows(pose, cov)
    mask = np.zeros((rig.height, rig.width), bool)
    for w in windows:
        if not w.right:
            x0, y0, x1, y1 = (int(v) for v in w.box)
            mask[y0:y1, x0:x1] = True
    share = mask.mean()
    assert (mode == _core.SearchMode.WHOLE_FRAME) == (share > fraction), (share, fraction, reason)
    if mode == _core.SearchMode.WHOLE_FRAME:
        assert f"windows cover {share:.3g} of the frame" in reason


@pytest.mark.parametrize("seed", [3, 11])
def test_the_camera_loops_sighting_faults_are_the_python_pipelines(seed):
    """apply_sighting_faults (the core camera loop's landmark faults) on a frame's core sightings, all
    at once, equals LanBLoc's Python faults (LandmarkRanging.apply_faults, one sighting per call) on
    the same sightings as Python's: the same dropped, relabelled (id, anchor, true id) and outlier
    ranges, flag for flag, whichever other sightings the frame holds."""
    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    lb = safenav.vision.LanBLoc(world, RIG, ranging="corners", backend="core")
    fix = lb.pipelines["core"].front_end.localize(left, right)
    assert sum(o.ok for o in fix.observations) >= 4
    faults = nv.LandmarkFaults(dropout_probability=0.3, outlier_probability=0.4, outlier_magnitude=4.0,
                               misassociation_probability=0.4)
    position = np.array(pose[:2]) + 0.2
    ranger = lb.ranger
    ids = [lm.id for lm in world.landmarks]
    anchors = {k: tuple(v[0]) for k, v in ranger.landmarks.items()}
    landmarks = np.array([anchors[i][:2] for i in ids])
    for frame_seed in range(seed, seed + 40, 4):
        kept, counts = _core.apply_sighting_faults(faults, list(fix.observations), landmarks, ids, anchors, position,
                                                   ranger.max_range_m, frame_seed)
        py_in = lb.localize(left, right).observations       # the same sightings, as Python's dataclasses
        assert [o.landmark_id for o in py_in] == [o.landmark_id for o in fix.observations]
        py, dropped = ranger.apply_faults(py_in, faults, position, frame_seed)
        assert counts["dropped"] == dropped and counts["observations"] == sum(o.ok for o in py_in)
        assert [o.landmark_id for o in kept] == [o.landmark_id for o in py]
        assert [o.faults for o in kept] == [o.faults for o in py]
        assert [o.true_landmark_id for o in kept] == [-1 if o.true_landmark_id is None else o.true_landmark_id
                                                      for o in py]
        np.testing.assert_array_equal([o.range for o in kept], [o.range for o in py])
        np.testing.assert_array_equal(np.array([o.anchor for o in kept]), np.array([o.anchor for o in py]))
        assert counts["outliers"] == sum(bool(o.faults & 4) for o in kept)
        assert counts["misassociated"] == sum(bool(o.faults & 2) for o in kept)


def _faulty_camera_trial(sc, path, seed, **faults):
    from dataclasses import replace
    fsc = replace(sc, noise=replace(sc.noise, fix_model="ranges", **faults))
    nav = nv.make_navigator(fsc, path, method="centroid", position_every=20, record=False)
    return CameraFrames.from_scenario(fsc, seed=seed).run(nav, seed)


def test_the_camera_loop_applies_the_scenarios_landmark_faults_in_the_core():
    """With the scenario's landmark faults on, the core camera loop drops, corrupts and relabels the
    frames' ranged sightings before trilateration and counts them: all dropped leaves no fix;
    dropouts at 30 % drop a binomial share; no faults count none and equal the scenario's own loop."""
    sc = safenav.default_scenario()
    path = np.asarray(nv.plan_safe_path(sc, "P3", iterations=1500).path)
    # the scenario as given (fix_model 'profile', no faults) against 'ranges' with zero faults: the
    # camera loop ignores the fix model, and zero faults draw nothing
    plain = nv.make_navigator(sc, path, method="centroid", position_every=20, record=False)
    clean = CameraFrames.from_scenario(sc, seed=7).run(plain, 7)
    assert clean.observations > 20 and clean.dropped == clean.outliers == clean.misassociated == 0
    assert clean.faults_through == 0
    none = _faulty_camera_trial(sc, path, 7)
    assert (none.steps, none.observations, none.position_fixes, none.metrics["truth_ade"]) == \
        (clean.steps, clean.observations, clean.position_fixes, clean.metrics["truth_ade"])

    lost = _faulty_camera_trial(sc, path, 7, dropout_probability=1.0)
    assert lost.observations > 0 and lost.dropped == lost.observations
    assert lost.position_fixes == 0 and lost.faults_through == 0

    part = _faulty_camera_trial(sc, path, 7, dropout_probability=0.3)
    n, k = part.observations, part.dropped
    assert n > 20
    from scipy.stats import binomtest
    ci = binomtest(k, n).proportion_ci(0.999)
    assert ci.low <= 0.3 <= ci.high

    # gross faults (5 m outliers, wrong ids) are caught by the trilateration's outlier test or the gates
    bad = _faulty_camera_trial(sc, path, 7, outlier_probability=0.5, misassociation_probability=0.5)
    assert bad.outliers > 0 and bad.misassociated > 0 and bad.ranges_rejected + bad.rejected > 0
    assert bad.faults_through <= bad.outliers + bad.misassociated
    again = _faulty_camera_trial(sc, path, 7, outlier_probability=0.5, misassociation_probability=0.5)
    assert (again.steps, again.outliers, again.misassociated, again.faults_through, again.metrics["truth_ade"]) == \
        (bad.steps, bad.outliers, bad.misassociated, bad.faults_through, bad.metrics["truth_ade"])
    # outliers of 2 cm pass every test: the filter takes them, and faults_through counts them
    mild = _faulty_camera_trial(sc, path, 7, outlier_probability=0.5, outlier_magnitude=0.02)
    assert mild.outliers > 0 and 0 < mild.faults_through <= mild.outliers


def test_the_camera_loop_disputes_a_start_frame_taken_elsewhere():
    """The camera loop's start fix meets the measurement loop's check (ours, the gate on): a first
    frame taken 9 m beside P1's start, with five markers close in front of it, gives a fix where it
    was taken; the loop disputes it against the rough start and starts halfway between them, with
    a covariance that holds both ends.  The papers' loop starts from the fix as it is."""
    from dataclasses import replace

    sc = safenav.default_scenario()
    path = np.asarray(nv.plan_safe_path(sc, "P1", iterations=1500).path)
    x0 = np.asarray(nv.make_navigator(sc, path, record=False, max_steps=1).nominal_trajectory())[0]
    th = x0[3]
    fwd, right = np.array([math.cos(th), math.sin(th)]), np.array([math.sin(th), -math.cos(th)])
    taken = x0[:2] + (0.0, -9.0)
    cluster = 1 + max(lm.cluster for lm in sc.world.landmarks)
    near = tuple(Landmark(60 + k, (*(taken + z * fwd + lat * right), h), f"class{k}", cluster)
                 for k, (z, lat, h) in PLACEMENTS.items())
    sc = replace(sc, world=replace(sc.world, landmarks=sc.world.landmarks + near))
    s0 = 1.0                                           # unfixed_start_std() of the LanBLoc source
    for paper in (False, True):
        nav = nv.make_navigator(sc, path, method="centroid", position_every=40, max_steps=2, paper=paper)
        src = CameraFrames.from_scenario(sc, seed=3)

        def frames(truth, step, plan):
            t = np.asarray(truth, dtype=float)
            return src(np.r_[taken, t[2:]] if step == 0 else t, step, plan)

        r = nav.run_frames(3, src.front_end, frames)
        start, est = r.truth[0, :2], r.estimate[0, :2]
        if paper:
            assert r.start_disputed == 0
            assert np.linalg.norm(est - taken) < 0.1       # the fix, as it came
            continue
        assert r.start_disputed == 1
        rough = 2.0 * est - taken                          # the prior's mean is (z + rough) / 2, z at `taken`
        assert np.linalg.norm(rough - start) < 5.0 * s0 + 0.2
        half = np.linalg.norm(taken - rough) / 2.0         # R + σ0² I + ddᵀ/4 holds both ends
        assert r.position_std[0] >= math.hypot(half, s0) - 0.1

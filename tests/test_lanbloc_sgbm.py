"""The paper's SGBM ranging in the C++ front end (``LanBLocSettings.ranging = SGBM``,
``LanBLocFrontEnd.localize_boxes``; [SafeNav §IV-A]): on the same boxes it equals
the Python pipeline's SGBM ranging (``FullFramePipeline.disparity`` on the band of
rows, ``LandmarkRanging.observe``) bit for bit, whatever the boxes (hypothesis,
including boxes that leave the image and tiny ones); with the core's own ArUco it
finds the Python pipeline's landmarks and fix; ``LanBLoc(..., backend="core")``
ranges a non-fiducial detector's boxes (a YOLO model's) in the core, equal to the
Python pipeline; bad boxes, unmapped ids and a front end without a dictionary are
named."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from safenav import _core
from safenav.vision.detect import Detection, Detector, FiducialDetector
from safenav.vision.lanbloc import LanBLoc
from test_lanbloc_cpp import RIG, SCENES, _front_end, _pair, _scene, random_frame

SGBM = _core.LanBLocRanging.SGBM   # (the front ends below take the rig's max_range_m, as LanBLoc does)


class BoxesOnly(Detector):
    """A detector that gives boxes and no corners, as a YOLO model does (the markers' boxes,
    found by ArUco in Python)."""

    name = "boxes-only"

    def __init__(self, world):
        self._aruco = FiducialDetector(world)

    def detect(self, image):
        return [Detection(d.landmark_id, d.class_name, d.box, 0.9) for d in self._aruco.detect(image)]


def _same(core, py):
    """A core sighting equals a Python one, bit for bit."""
    assert core.landmark_id == py.landmark_id and bool(core.ok) == bool(py.ok) and core.reason == py.reason
    for name in ("range", "sigma", "slant_range", "depth", "disparity", "bearing", "bearing_sigma"):
        a, b = getattr(core, name), getattr(py, name)
        assert (math.isnan(a) and math.isnan(b)) or a == b, (name, a, b)
    assert core.n_valid == py.n_valid


@pytest.fixture(scope="module")
def frames():
    rng = np.random.default_rng(11)
    return [random_frame(rng, k) for k in range(5)]


@pytest.mark.parametrize("row_band, margin", [(True, 24), (True, 0), (False, 24)])
def test_the_cores_sgbm_ranging_is_the_python_pipelines_on_the_same_boxes(frames, row_band, margin):
    for pose, world, _, (left, right) in frames:
        lb = LanBLoc(world, RIG, ranging="sgbm", backend="python", row_band=row_band, band_margin_px=margin)
        dets = lb.ranger.known(lb.detector.detect(left))
        assert dets
        fe = _front_end(world, ranging=SGBM, max_range_m=RIG.max_range_m, row_band=row_band, band_margin_px=margin)
        fix = fe.localize_boxes(left, right, [(d.landmark_id, d.box) for d in dets])
        disparity = lb.disparity(left, right, [d.box for d in dets])
        py = [lb.observe(d, disparity) for d in dets]
        assert len(fix.observations) == len(py)
        for c, p in zip(fix.observations, py):
            _same(c, p)
            assert tuple(c.box) == tuple(p.box)
        want = lb.ranger.solve(dets, tuple(py), {}, 0.0, None, None, 0)
        assert str(fix.status) == want.status
        if fix.ok:
            np.testing.assert_allclose(fix.position, want.position, rtol=0, atol=1e-9)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_boxes_range_as_the_python_pipeline_ranges_them(frames, data):
    """Boxes anywhere that reach into the image's rows, from one pixel to wider than the image, on
    pixel edges or between them: the core's band, disparity and box medians are Python's."""
    pose, world, _, (left, right) = frames[data.draw(st.integers(0, len(frames) - 1))]
    ids = sorted(lm.id for lm in world.landmarks)
    n = data.draw(st.integers(1, len(ids)))
    coord = st.one_of(st.integers(-50, 700).map(float), st.floats(-50.0, 700.0))
    boxes = []
    for lid in ids[:n]:
        x0, y0 = data.draw(coord), data.draw(st.floats(-40.0, RIG.height - 2.0))
        w, h = data.draw(st.floats(1.0, 700.0)), data.draw(st.floats(1.0, 300.0))
        boxes.append((lid, (x0, y0, x0 + w, y0 + h)))
    lb = LanBLoc(world, RIG, ranging="sgbm", backend="python")
    fix = _front_end(world, ranging=SGBM, max_range_m=RIG.max_range_m).localize_boxes(left, right, boxes)
    disparity = lb.disparity(left, right, [b for _, b in boxes])
    for c, (lid, b) in zip(fix.observations, boxes):
        _same(c, lb.observe(Detection(lid, "m", b, 1.0), disparity))


def test_boxes_above_the_image_match_the_whole_frame(frames):
    """Boxes that reach no row of the image (found by the property test above: a box 1 px tall at
    y = -40) leave no band: both pipelines match the whole frame, and range the boxes alike."""
    pose, world, _, (left, right) = frames[0]
    lid = min(lm.id for lm in world.landmarks)
    box = (10.0, -40.0, 50.0, -39.0)
    lb = LanBLoc(world, RIG, ranging="sgbm", backend="python")
    disparity = lb.disparity(left, right, [box])
    np.testing.assert_array_equal(disparity, lb.disparity(left, right, []))
    fix = _front_end(world, ranging=SGBM, max_range_m=RIG.max_range_m).localize_boxes(left, right, [(lid, box)])
    _same(fix.observations[0], lb.observe(Detection(lid, "m", box, 1.0), disparity))


@pytest.mark.parametrize("k", range(len(SCENES)))
def test_the_cores_own_detection_finds_the_python_pipelines_landmarks_and_fix(k):
    pose, placements = SCENES[k]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    py = LanBLoc(world, RIG, ranging="sgbm", backend="python").localize(left, right)
    core = LanBLoc(world, RIG, ranging="sgbm").localize(left, right)   # auto: the core
    fe = _front_end(world, ranging=SGBM, max_range_m=RIG.max_range_m).localize(left, right)
    assert core.status == str(fe.status) == py.status == "ok"
    assert [o.landmark_id for o in core.observations] == [o.landmark_id for o in py.observations]
    assert [o.range for o in core.observations] == [o.range for o in fe.observations]
    np.testing.assert_allclose(core.position, fe.position, rtol=0, atol=1e-9)
    # the boxes differ by the two OpenCV versions' corners (< 0.1 px): the box medians barely move
    assert np.linalg.norm(core.position - py.position) < 0.05
    e = core.position - np.array(pose[:2])   # SGBM's box medians (σ_d = 0.5 px): within the fix's covariance
    assert e @ np.linalg.solve(core.covariance, e) < 13.8   # χ²₂ at 99.9 %
    for o in fe.observations:   # the box is the corners' bounding box, the bearing its centre's
        c = np.asarray(o.corners_left)
        assert tuple(o.box) == (c[:, 0].min(), c[:, 1].min(), c[:, 0].max(), c[:, 1].max())
        assert tuple(o.centre) == (0.5 * (o.box[0] + o.box[2]), 0.5 * (o.box[1] + o.box[3]))


def test_a_detector_of_ones_own_is_ranged_in_the_core_as_in_python():
    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    det = BoxesOnly(world)
    core = LanBLoc(world, RIG, det, ranging="sgbm", backend="core")
    py = LanBLoc(world, RIG, det, ranging="sgbm")
    assert core.backend == "core" and py.backend == "python"
    a, b = core.localize(left, right), py.localize(left, right)
    assert a.status == b.status == "ok"
    for c, p in zip(a.observations, b.observations):
        _same(c, p)
        assert c.score == p.score == 0.9 and c.class_name == p.class_name
    assert np.array_equal(a.position, b.position) and np.array_equal(a.covariance, b.covariance)


def test_bad_boxes_unmapped_ids_and_no_dictionary_are_named():
    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    fe = _front_end(world, ranging=SGBM, max_range_m=RIG.max_range_m)
    for box in [(10.0, 10.0, 10.0, 50.0), (10.0, math.nan, 30.0, 50.0), (10.0, 60.0, 30.0, 50.0)]:
        with pytest.raises(ValueError, match=r"box of landmark 1 \(.*\) must be finite with x_min < x_max"):
            fe.localize_boxes(left, right, [(1, box)])
    fix = fe.localize_boxes(left, right, [(999, (10.0, 10.0, 50.0, 50.0))])
    assert list(fix.unmapped) == [999] and str(fix.status) == "no_landmarks"
    with pytest.raises(ValueError, match="right image is 639x480 px but the rig is 640x480 px"):
        fe.localize_boxes(left, right[:, 1:], [(1, (10.0, 10.0, 50.0, 50.0))])
    # no dictionary: boxes only, any integer id; detection is refused, naming why
    boxes_only = _front_end(world, ranging=SGBM, max_range_m=RIG.max_range_m, dictionary="")
    world_ids = {lm.id: (*lm.position[:2], lm.height) for lm in world.landmarks}
    big = _core.LanBLocFrontEnd(boxes_only.rig, {k + 5000: v for k, v in world_ids.items()}, boxes_only.settings)
    dets = FiducialDetector(world).detect(left)
    fix = big.localize_boxes(left, right, [(d.landmark_id + 5000, d.box) for d in dets])
    ref = fe.localize_boxes(left, right, [(d.landmark_id, d.box) for d in dets])
    assert fix.ok and np.array_equal(fix.position, ref.position)
    with pytest.raises(ValueError, match="settings.dictionary is empty: this front end detects no markers"):
        big.localize(left, right)
    with pytest.raises(ValueError, match="landmark id 5001 is not in dictionary DICT_4X4_100"):
        _core.LanBLocFrontEnd(fe.rig, {5001: (0.0, 0.0, 1.0)}, fe.settings)
    s = _core.LanBLocSettings()
    s.sgbm.block_size = 4
    with pytest.raises(ValueError, match="sgbm.block_size = 4 must be odd"):
        s.validate()
    s = _core.LanBLocSettings()
    s.box_shrink = 0.5
    with pytest.raises(ValueError, match="box_shrink = 0.5: must be < 0.5"):
        s.validate()

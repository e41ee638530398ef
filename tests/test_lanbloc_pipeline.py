"""The LanBLoc pipeline on rendered stereo pairs: detection of every
visible marker, ranges, bearings and the fix within a bound derived from the
geometry, the statuses, bad input, and the camera-in-the-loop source on a
stretch of the default scenario's path P2."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import safenav
from safenav.vision.detect import FiducialDetector
from safenav.vision.lanbloc import STATUSES, CameraLoopSource, LanBLoc
from safenav.vision.render import StereoRenderer, StereoRig
from safenav.vision.stereo import RectifiedCamera, StereoCalibration
from safenav.world import Landmark, World

RIG = StereoRig()           # 640x480, f = 350 px, B = 0.3 m, h = 1.5 m: f·B = 105 px·m
PIXEL_LOCK_PX = 0.5         # worst-case error of a box-median SGBM disparity on a marker (see below)


def _scene(pose, placements):
    """Landmarks at (depth, lateral to the right, height) from the vehicle at ``pose``."""
    th = pose[2]
    fwd = np.array([math.cos(th), math.sin(th)])
    right = np.array([math.sin(th), -math.cos(th)])
    lms = tuple(Landmark(k, (*(np.array(pose[:2]) + z * fwd + lat * right), hgt), f"class{k}", 1)
                for k, (z, lat, hgt) in placements.items())
    return World(landmarks=lms)


SCENES = [
    ((40.0, 60.0, 0.5), {1: (7.0, -3.0, 2.5), 2: (10.0, 2.0, 1.8), 3: (13.0, -0.5, 4.0), 4: (16.0, 6.0, 3.0),
                         5: (11.0, -8.5, 1.2)}),
    ((120.0, 30.0, -2.2), {7: (6.0, 1.5, 1.5), 8: (12.0, -3.5, 2.2), 9: (15.0, 3.5, 5.0)}),
]


@pytest.mark.parametrize("pose, placements", SCENES)
def test_pipeline_detects_every_visible_marker_and_localizes_within_the_geometric_bound(pose, placements):
    """Bound, derived from the geometry.

    * Disparity: on a marker, SGBM's matching cost is flat inside the large
      black and white cells, so its subpixel interpolation is weak and the
      box median locks onto (near) whole pixels: |δd| ≤ 0.5 px (measured
      along the default scenario's paths, ``bench/bench_vision.py``: 0.18 px
      RMS, 99th percentile 0.48 px; the 1 px maximum is a part-hidden box).
    * Depth Z = f·B/d: |δZ| ≤ Z²·|δd|/(f·B) to first order.
    * Slant distance s = Z·‖ray‖ (ray fixed by the box centre): |δs| = |δZ|·s/Z.
    * Horizontal range ρ = sqrt(s² − Δh²): |δρ| = |δs|·s/ρ.
    * Fix: weighted least squares linearised at the truth, δp = A·δρ with
      A = (GᵀWG)⁻¹GᵀW, G the unit vectors from the landmarks to the vehicle and
      W = diag(σ_i⁻²), σ_i ∝ Z_i²·s_i²/(Z_i·ρ_i), the pipeline's weights.  The
      worst case over the box |δρ_i| ≤ b_i is attained at a vertex:
      max over sign vectors ε of ‖A·(ε ∘ b)‖.
    * 10 % on top for the linearisations (second-order terms of d → Z and of
      the least squares, and the box centre's sub-pixel offset from the
      marker's projected centre).
    """
    world = _scene(pose, placements)
    renderer = StereoRenderer(world, RIG)
    left, right = renderer.render(pose)
    visible = renderer.visible(pose, min_side_px=12)
    assert sorted(visible) == sorted(placements)                      # the scene is as designed
    lanbloc = LanBLoc(world, RIG, trilateration=dict(reject_outliers=False))
    res = lanbloc.localize(left, right)
    assert res.ok, res.reason
    assert sorted(d.landmark_id for d in res.detections) == sorted(visible)
    assert {d.class_name for d in res.detections} == {f"class{k}" for k in placements}

    p = np.array(pose[:2])
    C = np.array([*p, RIG.camera_height_m])
    anchors, b, weights, G = [], [], [], []
    for o in res.observations:
        a = o.anchor
        rho = float(np.hypot(*(a[:2] - p)))
        s = float(np.linalg.norm(a - C))
        Z = float((a[:2] - p) @ [math.cos(pose[2]), math.sin(pose[2])])
        bound = Z ** 2 * PIXEL_LOCK_PX / RIG.fB * (s / Z) * (s / rho)
        assert o.ok and abs(o.range - rho) <= 1.1 * bound, (o.landmark_id, o.range, rho, bound)
        # the pipeline's σ is the same propagation with σ_d, from its measured depth
        assert o.sigma == pytest.approx(o.depth ** 2 * lanbloc.sigma_d / RIG.fB * (o.slant_range / o.depth)
                                        * (o.slant_range / o.range), rel=1e-9)
        anchors.append(a[:2])
        b.append(bound)
        weights.append(1.0 / (Z * s * s / rho) ** 2)
        G.append((p - a[:2]) / rho)
    G, W, b = np.array(G), np.diag(weights), np.array(b)
    A = np.linalg.solve(G.T @ W @ G, G.T @ W)
    worst = max(np.linalg.norm(A @ (np.array(eps) * b)) for eps in itertools.product((-1, 1), repeat=len(b)))
    err = float(np.linalg.norm(res.position - p))
    assert err <= 1.1 * worst, (err, worst)
    assert worst < 2.0   # the bound says something at these distances
    # the covariance is the trilateration's (JᵀWJ)⁻¹ and is a proper covariance
    assert np.all(np.linalg.eigvalsh(res.covariance) > 0)
    assert res.localization.ok and res.gdop == pytest.approx(res.localization.gdop)


def test_bearings_and_range_model_feed_a_filter():
    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    left, right = StereoRenderer(world, RIG).render(pose)
    res = LanBLoc(world, RIG).localize(left, right)
    ids, anchors, bearings, sig = res.bearing_measurements()
    p = np.array(pose[:2])
    true = np.arctan2(anchors[:, 1] - p[1], anchors[:, 0] - p[0]) - pose[2]
    # the box centre is within ~1 px of the marker centre's projection: 1 px = 1/f rad
    np.testing.assert_allclose(np.angle(np.exp(1j * (bearings - true))), 0.0, atol=1.5 / RIG.focal_length_px)
    np.testing.assert_allclose(sig, 1.0 / RIG.focal_length_px)
    model, z = res.range_model()
    x_true = np.array([*p, 2.0, pose[2]])
    np.testing.assert_allclose(model.predict(x_true), np.hypot(*(anchors - p).T), rtol=0, atol=1e-12)
    assert model.dim == len(z) == res.n_ranges == 5
    np.testing.assert_allclose(np.sqrt(np.diag(model.R)), res.range_measurements()[3])
    # one EKF update with the ranges pulls a 2 m-off prior to the truth
    ekf = safenav.Ekf(safenav.BmmParams(), x_true + [2.0, -1.0, 0, 0], np.diag([4.0, 4.0, 0.1, 0.01]))
    upd = ekf.update(model, z)
    assert upd.accepted and np.linalg.norm(ekf.x[:2] - p) < 0.6
    # the same ranges into the particle filter
    prior = np.diag([4.0, 4.0, 0.1, 0.01])
    pf = safenav.ParticleFilter(safenav.BmmParams(), x_true + [2.0, -1.0, 0, 0], prior, n_particles=4000, seed=3)
    assert pf.update(model, z).accepted and np.linalg.norm(pf.x[:2] - p) < 0.6


def test_the_position_fix_feeds_a_filter_as_a_position_measurement():
    """The other mode: the fix and its covariance as a POSITION measurement, into the EKF and the PF."""
    from safenav.measurement import MeasurementKind, MeasurementModel

    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    res = LanBLoc(world, RIG).localize(*StereoRenderer(world, RIG).render(pose))
    assert res.ok, res.reason
    p = np.array(pose[:2])
    x_true = np.array([*p, 2.0, pose[2]])
    model = MeasurementModel(MeasurementKind.POSITION, res.covariance)
    np.testing.assert_allclose(model.predict(x_true), p, atol=1e-12)
    prior = np.diag([4.0, 4.0, 0.1, 0.01])
    ekf = safenav.Ekf(safenav.BmmParams(), x_true + [2.0, -1.0, 0, 0], prior)
    assert ekf.update(model, res.position).accepted
    # the Kalman update of the position block: x⁺ = x + P(P + R)⁻¹(z − x), P⁺ = P − P(P + R)⁻¹P
    x0, P0, Rf = (x_true + [2.0, -1.0, 0, 0])[:2], prior[:2, :2], res.covariance
    K = P0 @ np.linalg.inv(P0 + Rf)
    np.testing.assert_allclose(ekf.x[:2], x0 + K @ (res.position - x0), atol=1e-9)
    np.testing.assert_allclose(ekf.P[:2, :2], P0 - K @ P0, atol=1e-9)
    pf = safenav.ParticleFilter(safenav.BmmParams(), x_true + [2.0, -1.0, 0, 0], prior, n_particles=4000, seed=3)
    assert pf.update(model, res.position).accepted
    assert np.linalg.norm(pf.x[:2] - ekf.x[:2]) < 0.2     # linear-Gaussian: the PF approximates the same posterior


def test_a_raw_pair_with_a_calibration_is_rectified_to_the_same_fix():
    pose, placements = SCENES[1]
    world = _scene(pose, placements)
    left, right = StereoRenderer(world, RIG).render(pose)
    a = LanBLoc(world, RIG).localize(left, right)
    cal = RIG.calibration()
    b = LanBLoc(world, cal, camera_height_m=RIG.camera_height_m, max_range_m=RIG.max_range_m).localize(left, right)
    assert a.ok and b.ok
    np.testing.assert_allclose(a.position, b.position, atol=1e-6)
    # the full-image disparity gives the same fix as the row band, to SGBM's band-edge effects
    c = LanBLoc(world, RIG, row_band=False).localize(left, right)
    np.testing.assert_allclose(c.position, a.position, atol=0.05)
    # colour pairs work too
    bgr = StereoRenderer(world, RIG, color=True).render(pose)
    np.testing.assert_allclose(LanBLoc(world, RIG).localize(*bgr).position, a.position, atol=1e-6)


def test_statuses_say_why():
    pose = (50.0, 50.0, 0.0)
    empty = World()
    l, r = StereoRenderer(empty, RIG).render(pose)
    res = LanBLoc(empty, RIG).localize(l, r)
    assert res.status == "no_landmarks" and "no landmark" in res.reason and np.isnan(res.position).all()
    two = _scene(pose, {1: (8.0, -2.0, 2.0), 2: (12.0, 3.0, 2.0)})
    res = LanBLoc(two, RIG).localize(*StereoRenderer(two, RIG).render(pose))
    assert res.status == "too_few_ranges" and "2 usable" in res.reason and res.n_ranges == 2
    # a landmark beyond max_range is recognised but gets no range, with the reason
    three = _scene(pose, {1: (8.0, -2.0, 2.0), 2: (12.0, 3.0, 2.0), 3: (22.0, -10.0, 2.0)})
    res = LanBLoc(three, RIG, max_range_m=15.0).localize(*StereoRenderer(three, RIG).render(pose))
    assert res.status == "too_few_ranges" and len(res.detections) == 3
    far = [o for o in res.observations if o.landmark_id == 3][0]
    assert not far.ok and "range" in far.reason and "landmark 3" in res.reason
    # three landmarks on one line (across the view): the fix is degenerate
    line = _scene(pose, {1: (10.0, -4.0, 2.0), 2: (10.0, 0.5, 2.0), 3: (10.0, 5.0, 2.0)})
    res = LanBLoc(line, RIG).localize(*StereoRenderer(line, RIG).render(pose))
    assert res.status == "degenerate" and res.reason and np.isnan(res.position).all()
    assert set(STATUSES) >= {"ok", "no_landmarks", "too_few_ranges", "degenerate"}


def test_bad_input_names_the_value():
    pose, placements = SCENES[1]
    world = _scene(pose, placements)
    left, right = StereoRenderer(world, RIG).render(pose)
    lb = LanBLoc(world, RIG)
    with pytest.raises(ValueError, match=r"differ in size: \(480, 640\) vs \(480, 639\)"):
        lb.localize(left, right[:, :639])
    with pytest.raises(ValueError, match="empty"):
        lb.localize(left[:0], right[:0])
    with pytest.raises(ValueError, match="320x240 px but the calibration is 640x480"):
        lb.localize(left[:240, :320].copy(), right[:240, :320].copy())
    with pytest.raises(ValueError, match="uint8"):
        lb.localize(left.astype(float), right.astype(float))
    K = RIG.K.copy()
    K[0, 0] = np.nan
    with pytest.raises(ValueError, match="K1"):
        StereoCalibration(K, np.zeros(5), RIG.K, np.zeros(5), np.eye(3), [-0.3, 0, 0], (640, 480))
    with pytest.raises(ValueError):
        RectifiedCamera(float("nan"), 319.5, 239.5, 0.3)
    with pytest.raises(ValueError, match="camera_height_m"):
        LanBLoc(world, RIG.rectified_camera(), camera_height_m=float("nan"))
    with pytest.raises(ValueError, match="camera_height_m is required"):
        LanBLoc(world, RIG.rectified_camera())
    with pytest.raises(ValueError, match="min_landmarks"):
        LanBLoc(world, RIG, min_landmarks=2)
    # a recognised landmark that the map does not know
    partial = World(landmarks=tuple(lm for lm in world.landmarks if lm.id != 9))
    unmapped = LanBLoc(partial, RIG, FiducialDetector())
    with pytest.raises(ValueError, match="landmark id 9"):
        unmapped.localize(left, right)
    skip = LanBLoc(partial, RIG, FiducialDetector(), unknown_landmark="skip").localize(left, right)
    assert sorted(d.landmark_id for d in skip.detections) == [7, 8]
    with pytest.raises(ValueError, match="landmarks"):
        LanBLoc({1: (0.0, float("nan"))}, RIG)
    with pytest.raises(ValueError, match="id 'a' must be a non-negative integer"):
        LanBLoc({"a": (0.0, 1.0)}, RIG)
    with pytest.raises(ValueError, match="landmarks = 5"):
        LanBLoc(5, RIG)
    with pytest.raises(ValueError, match="band_margin_px = nan"):
        LanBLoc(world, RIG, band_margin_px=float("nan"))
    with pytest.raises(ValueError, match="unknown option 'max_gdp'"):
        LanBLoc(world, RIG, trilateration=dict(max_gdp=50.0))


def test_camera_loop_source_on_a_stretch_of_path_P2():
    """The last 32 m of P2's first leg (cluster 4 -> cluster 1), every 2 m: the default
    scenario's landmarks stand in clusters, so a forward camera sees 3+ of them only on the
    approach to a cluster (between clusters the source drops out; see docs/lanbloc.md)."""
    sc = safenav.default_scenario()
    src = CameraLoopSource(sc.world, occlusion=False)   # with occlusion, 4 fixes (boulders hide cluster 1)
    assert src.name == "lanbloc-camera" and src.emulated is False
    poly = sc.world.path_polyline(sc.path_types[1])
    a, b = poly[0], poly[1]
    length = float(np.linalg.norm(b - a))
    th = math.atan2(*(b - a)[::-1])
    fixes, nees = 0, []
    for k, d in enumerate(np.arange(length - 32.0, length - 4.0, 2.0)):
        p = a + (b - a) * d / length
        out = src(np.array([p[0], p[1], 1.5, th]), k)
        last = src.last
        assert src.last_step == k and last.status in STATUSES
        culled = {src.renderer.landmarks[i].id for i in src.renderer.culled((p[0], p[1], th))}
        assert {dd.landmark_id for dd in last.detections} <= culled
        if out is None:
            assert not last.ok and last.reason
            continue
        z, R = out
        assert z.shape == (2,) and R.shape == (2, 2) and np.all(np.linalg.eigvalsh(R) > 0)
        e = z - p
        nees.append(float(e @ np.linalg.solve(R, e)))
        fixes += 1
    assert fixes >= 8                        # measured 9 of 14 (2560x1440, by region)
    assert max(nees) < 13.8                  # chi2(2) 99.9 %: no fix is inconsistent with its R
    assert np.mean(nees) < 4.0               # consistent on average (2 expected; σ_d = 0.2 px is cautious)
    assert src.stats["calls"] == 14 and sum(v for k, v in src.stats.items() if k != "calls") == 14
    with pytest.raises(ValueError, match="true_state"):
        src(np.array([1.0, 2.0, 3.0]), 0)


def test_measurement_sources_are_selectable_and_the_emulations_say_so():
    """The navigation experiments' position sources: LanBLoc at the measurement
    level with the paper's RMSE (0.0142 m X, 0.039 m Y) as the default, the
    camera loop (this module), and the paper's comparison methods as error
    profiles labelled as emulations."""
    from safenav import navigation as nv

    lanbloc = nv.position_source("lanbloc")
    assert tuple(lanbloc.std) == (0.0142, 0.039) and not lanbloc.emulated
    assert nv.make_navigator.__kwdefaults__["source"] == "lanbloc"
    for name, label in (("deeploc-gps", "DeepLoc-GPS"), ("deeploc-ekf-gps", "DeepLoc-EKF-GPS"),
                        ("sensor-fusion", "Sensor Fusion")):
        s = nv.position_source(name)
        assert s.emulated and s.label == f"{label} (emulated)" and "emulated" in s.note
    assert CameraLoopSource.name == "lanbloc-camera" and not CameraLoopSource.emulated
    with pytest.raises(ValueError, match="unknown position source"):
        nv.position_source("gps")


# --------------------------------------------------------------------------- the pipeline's parts

def test_one_pipeline_per_input_sharing_one_ranging_step():
    """LanBLoc is a front: a pair goes to the whole-frame pipeline, a StereoFrame to the region
    pipeline, and both use the one ranging and trilateration step.  Built by hand from the parts,
    each pipeline gives the same result, number for number."""
    from safenav.vision import FullFramePipeline, LandmarkRanging, RegionPipeline

    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    renderer = StereoRenderer(world, RIG)
    left, right = renderer.render(pose)
    frame = renderer.frame(pose, noise_seed=5)
    lb = LanBLoc(world, RIG, ranging="corners", backend="python", trilateration=dict(reject_outliers=False))
    full, regions = lb.pipelines["full"], lb.pipelines["regions"]
    assert isinstance(full, FullFramePipeline) and isinstance(regions, RegionPipeline)
    assert full.ranger is regions.ranger is lb.ranger and full.detector is regions.detector
    ranger = LandmarkRanging(world, RIG, trilateration=dict(reject_outliers=False))
    detector = FiducialDetector(world)
    for via_lanbloc, by_hand in (
            (lb.localize(left, right), FullFramePipeline(ranger, detector, ranging="corners").localize(left, right)),
            (lb.localize(frame, None), RegionPipeline(ranger, detector, ranging="corners").localize(frame))):
        assert via_lanbloc.ok and by_hand.ok
        np.testing.assert_array_equal(via_lanbloc.position, by_hand.position)
        np.testing.assert_array_equal(via_lanbloc.covariance, by_hand.covariance)
        assert [(o.landmark_id, o.range, o.sigma, o.bearing) for o in via_lanbloc.observations] == \
               [(o.landmark_id, o.range, o.sigma, o.bearing) for o in by_hand.observations]
    assert lb.localize_frame(frame).position.tolist() == lb.localize(frame, None).position.tolist()
    with pytest.raises(ValueError, match="right must be None"):
        lb.localize(frame, right)


def test_lanbloc_reads_its_settings_from_the_parts():
    pose, placements = SCENES[1]
    world = _scene(pose, placements)
    lb = LanBLoc(world, RIG, sigma_d=0.3, row_band=False, detect_side_px=40.0, min_landmarks=4)
    assert (lb.sigma_d, lb.row_band, lb.detect_side_px, lb.min_landmarks) == (0.3, False, 40.0, 4)
    assert lb.camera_height_m == RIG.camera_height_m and lb.camera is lb.ranger.camera
    for part, names in LanBLoc._SETTINGS.items():
        owner = lb.ranger if part == "ranger" else lb.pipelines[part]
        for name in names:
            assert getattr(lb, name) is getattr(owner, name), name
    with pytest.raises(AttributeError, match="no attribute 'sigma_x'"):
        lb.sigma_x


def test_a_sighting_is_not_the_cores_landmark_observation():
    """The vision result per landmark is a LandmarkSighting; the name LandmarkObservation belongs to
    the core's localizer input (localizer.hpp) only."""
    import safenav.vision as vision
    from safenav.vision import LandmarkSighting

    assert not hasattr(vision, "LandmarkObservation")
    assert "LandmarkObservation" not in vision.__all__
    pose, placements = SCENES[1]
    world = _scene(pose, placements)
    res = LanBLoc(world, RIG).localize(*StereoRenderer(world, RIG).render(pose))
    assert res.observations and all(isinstance(o, LandmarkSighting) for o in res.observations)


def test_the_parts_name_bad_settings():
    from safenav.vision import FullFramePipeline, LandmarkRanging, RegionPipeline

    pose, placements = SCENES[1]
    ranger = LandmarkRanging(_scene(pose, placements), RIG)
    with pytest.raises(ValueError, match="detector = 'aruco'"):
        FullFramePipeline(ranger, "aruco")
    with pytest.raises(ValueError, match="ranging = 'lidar'"):
        RegionPipeline(ranger, FiducialDetector(), ranging="lidar")
    with pytest.raises(ValueError, match="detect_side_px = 8"):
        RegionPipeline(ranger, FiducialDetector(), detect_side_px=8)
    with pytest.raises(ValueError, match="min_correlation = 2"):
        LanBLoc(_scene(pose, placements), RIG, min_correlation=2)

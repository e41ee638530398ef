"""Stereo ranging (LanBLoc, SafeNav IV-A): rectification and SGBM against
OpenCV's Python bindings, depth Z = f·B/(d + doffs), box-median ranges on
synthetic layered scenes with known disparity, calibration files, bad input."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from safenav.vision.stereo import BoxRange, RectifiedCamera, StereoCalibration, StereoMatcher

K1 = np.array([[620.0, 0.0, 318.0], [0.0, 615.0, 243.0], [0.0, 0.0, 1.0]])
K2 = np.array([[610.0, 0.0, 325.0], [0.0, 612.0, 238.0], [0.0, 0.0, 1.0]])
D1 = np.array([-0.12, 0.05, 0.001, -0.0005, 0.0])
D2 = np.array([-0.10, 0.04, -0.0008, 0.0004, 0.0])
R, _ = cv2.Rodrigues(np.array([0.01, -0.02, 0.005]))
T = np.array([-0.12, 0.003, 0.002])
SIZE = (640, 480)


def calibration() -> StereoCalibration:
    return StereoCalibration(K1=K1, D1=D1, K2=K2, D2=D2, R=R, T=T, image_size=SIZE)


def texture(rng, h, w):
    img = rng.integers(0, 256, (h, w)).astype(np.uint8)
    return cv2.GaussianBlur(img, (3, 3), 0.8)


def layered_pair(rng, h=240, w=320, d_back=10, d_front=30, box=(150, 80, 230, 160)):
    """Fronto-parallel background at disparity d_back and a foreground patch at
    d_front: left(x) = right(x − d)."""
    back = texture(rng, h, w + d_back)
    left = back[:, :w].copy()
    right = back[:, d_back:d_back + w].copy()
    x0, y0, x1, y1 = box
    front = texture(rng, y1 - y0, x1 - x0)
    left[y0:y1, x0:x1] = front
    right[y0:y1, x0 - d_front:x1 - d_front] = front
    return left, right


CAM = RectifiedCamera(f=500.0, cx=160.0, cy=120.0, baseline=0.2, doffs=2.5, width=320, height=240)


# ---------------------------------------------------------------------------
# disparity, depth and box ranges
# ---------------------------------------------------------------------------

def test_box_range_on_layered_scene_recovers_both_depths():
    left, right = layered_pair(np.random.default_rng(0))
    m = StereoMatcher(CAM, num_disparities=48, block_size=5)
    d = m.disparity(left, right)
    assert d.dtype == np.float32 and d.shape == (240, 320)
    fb = CAM.f * CAM.baseline
    front = m.box_range(d, (150, 80, 230, 160))
    back = m.box_range(d, (260, 20, 310, 70))
    for res, disp in ((front, 30), (back, 10)):
        assert res.ok, res.reason
        assert res.disparity == pytest.approx(disp, abs=0.1)
        assert res.range == pytest.approx(fb / (disp + CAM.doffs), rel=0.01)
        assert res.sigma == pytest.approx(res.range**2 * 0.5 / fb, rel=1e-12)  # σ_Z = Z²σ_d/(fB)
    # the box centre back-projects through the pinhole at depth Z
    u, v = (150 + 230) / 2, (80 + 160) / 2
    np.testing.assert_allclose(front.point, [(u - CAM.cx) * front.range / CAM.f,
                                             (v - CAM.cy) * front.range / CAM.f, front.range])
    assert front.horizontal_distance == pytest.approx(math.hypot(front.point[0], front.point[2]))
    assert front.bearing == pytest.approx(math.atan2(-front.point[0], front.point[2]))
    assert front.distance == pytest.approx(np.linalg.norm(front.point))


@pytest.mark.parametrize("d0, sigma_d", [(10.0, 0.1), (40.0, 0.5)])
def test_sigma_z_is_the_first_order_propagation_of_the_disparity_error(d0, sigma_d):
    """Z = f·B/(d + doffs), so dZ/dd = −f·B/(d + doffs)² = −Z²/(f·B) and a
    disparity error of σ_d gives σ_Z ≈ Z²·σ_d/(f·B).  Monte Carlo: shift the
    whole box's disparity by δ ~ N(0, σ_d²) and compare the spread of the
    ranges with the σ the matcher reports (second-order terms are
    (σ_d/(d + doffs))² ≤ 0.2 % here; the sample std of 4000 draws has a
    relative standard error of 1.1 %)."""
    m = StereoMatcher(CAM)
    rng = np.random.default_rng(9)
    d = np.full((CAM.height, CAM.width), np.nan, np.float32)
    box = (100, 60, 140, 100)
    ranges, sigmas = [], []
    for delta in sigma_d * rng.standard_normal(4000):
        d[60:100, 100:140] = d0 + delta
        r = m.box_range(d, box, sigma_d=sigma_d)
        assert r.ok, r.reason
        ranges.append(r.range)
        sigmas.append(r.sigma)
    z0 = CAM.f * CAM.baseline / (d0 + CAM.doffs)
    assert np.mean(ranges) == pytest.approx(z0, rel=2e-3)
    assert np.std(ranges) == pytest.approx(z0 ** 2 * sigma_d / (CAM.f * CAM.baseline), rel=0.05)
    assert np.std(ranges) == pytest.approx(np.median(sigmas), rel=0.05)


def test_median_is_robust_to_a_minority_of_wrong_pixels():
    left, right = layered_pair(np.random.default_rng(1))
    m = StereoMatcher(CAM, num_disparities=48)
    d = m.disparity(left, right)
    d[80:100, 150:230] = 5.0  # 25 % of the box wildly wrong
    res = m.box_range(d, (150, 80, 230, 160))
    assert res.disparity == pytest.approx(30, abs=0.1)


def test_depth_is_f_b_over_d_plus_doffs_and_nan_where_invalid():
    m = StereoMatcher(CAM)
    d = np.full((240, 320), np.nan, np.float32)
    d[0, :4] = [0.0, 10.0, -2.5, -3.0]
    z = m.depth(d)
    fb = CAM.f * CAM.baseline
    np.testing.assert_allclose(z[0, :2], [fb / 2.5, fb / 12.5], rtol=1e-6)
    assert np.isnan(z[0, 2:4]).all() and np.isnan(z[1:]).all()
    np.testing.assert_allclose(CAM.depth_of(CAM.disparity_of(7.3)), 7.3)


def test_box_range_reports_why_there_is_no_range():
    left, right = layered_pair(np.random.default_rng(2))
    m = StereoMatcher(CAM, num_disparities=48)
    d = m.disparity(left, right)
    res = m.box_range(d, (0, 0, 30, 30))  # SGBM leaves the first num_disparities columns invalid
    assert not res.ok and res.reason.startswith("too few valid pixels") and math.isnan(res.range)
    res = m.box_range(d, (260, 20, 310, 70), min_disparity=20.0)  # d + doffs = 12.5 < 20 px
    assert not res.ok and res.reason.startswith("beyond resolvable range")
    res = m.box_range(d, (260, 20, 310, 70), max_range=1.0)
    assert not res.ok and "max_range" in res.reason
    res = m.box_range(d, (400, 300, 420, 320))
    assert not res.ok and "outside the image" in res.reason
    assert CAM.resolvable_range(20.0) == pytest.approx(CAM.f * CAM.baseline / 20)


def test_disparity_is_opencv_stereo_sgbm_with_the_same_parameters():
    left, right = layered_pair(np.random.default_rng(3))
    params = dict(min_disparity=2, num_disparities=48, block_size=7, P1=200, P2=900, disp12_max_diff=2,
                  pre_filter_cap=31, uniqueness_ratio=5, speckle_window_size=50, speckle_range=1)
    ours = StereoMatcher(CAM, mode="sgbm_3way", **params).disparity(left, right)
    ref = cv2.StereoSGBM_create(minDisparity=2, numDisparities=48, blockSize=7, P1=200, P2=900, disp12MaxDiff=2,
                                preFilterCap=31, uniquenessRatio=5, speckleWindowSize=50, speckleRange=1,
                                mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY).compute(left, right)
    expect = np.where(ref < 2 * 16, np.nan, ref / 16.0)
    np.testing.assert_array_equal(np.isnan(ours), np.isnan(expect))
    np.testing.assert_allclose(ours[~np.isnan(ours)], expect[~np.isnan(expect)])


def test_sgbm_params_round_trip_and_defaults():
    m = StereoMatcher(CAM, block_size=7, mode="hh")
    p = m.sgbm_params
    assert p["block_size"] == 7 and p["mode"] == "hh" and p["num_disparities"] == 64
    with pytest.raises(ValueError, match="num_disparities = 40"):
        StereoMatcher(CAM, num_disparities=40)
    with pytest.raises(ValueError, match="block_size = 4"):
        StereoMatcher(CAM, block_size=4)
    with pytest.raises(ValueError, match="unknown SGBM parameter"):
        StereoMatcher(CAM, numDisparities=64)
    with pytest.raises(ValueError, match="mode = 'fast'"):
        StereoMatcher(CAM, mode="fast")


# ---------------------------------------------------------------------------
# rectification
# ---------------------------------------------------------------------------

def test_rectification_matches_opencv():
    m = StereoMatcher(calibration())
    R1, R2, P1, P2, Q, *_ = cv2.stereoRectify(K1, D1, K2, D2, SIZE, R, T.reshape(3, 1), flags=cv2.CALIB_ZERO_DISPARITY, alpha=0)
    rect = m.rectification
    for name, ref in (("R1", R1), ("R2", R2)):
        np.testing.assert_allclose(rect[name], ref, rtol=1e-9, atol=1e-9, err_msg=name)
    # alpha = 0 picks the focal length from iteratively undistorted border
    # points; Debian's OpenCV 4.6 (ours) and pip's 5.0 differ there by ~2e-5.
    for name, ref in (("P1", P1), ("P2", P2), ("Q", Q)):
        np.testing.assert_allclose(rect[name], ref, rtol=1e-4, atol=1e-9, err_msg=name)
    P1, P2 = rect["P1"], rect["P2"]  # the maps themselves are compared bit for bit below
    rng = np.random.default_rng(4)
    left, right = texture(rng, 480, 640), texture(rng, 480, 640)
    lr, rr = m.rectify(left, right)
    ref_l = cv2.remap(left, *cv2.initUndistortRectifyMap(K1, D1, R1, P1, SIZE, cv2.CV_16SC2), cv2.INTER_LINEAR)
    ref_r = cv2.remap(right, *cv2.initUndistortRectifyMap(K2, D2, R2, P2, SIZE, cv2.CV_16SC2), cv2.INTER_LINEAR)
    assert np.abs(lr.astype(int) - ref_l).max() <= 1 and np.abs(rr.astype(int) - ref_r).max() <= 1
    color = np.dstack([left] * 3)
    lc, _ = m.rectify(color, color)
    assert lc.shape == (480, 640, 3) and np.array_equal(lc[:, :, 1], m.rectify(left, left)[0])


def test_rectified_rig_puts_matches_on_one_row_and_gives_true_depth():
    """Project 3D points through the raw (distorted, rotated) rig; after
    rectify_points both views share rows and f·B/(x_l − x_r + doffs) is the
    depth in the rectified left frame."""
    m = StereoMatcher(calibration())
    cam = m.camera
    rng = np.random.default_rng(5)
    X = np.column_stack([rng.uniform(-1.5, 1.5, 50), rng.uniform(-1, 1, 50), rng.uniform(2, 12, 50)])
    pl, _ = cv2.projectPoints(X.reshape(-1, 1, 3), np.zeros((3, 1)), np.zeros((3, 1)), K1, D1)
    pr, _ = cv2.projectPoints(X.reshape(-1, 1, 3), cv2.Rodrigues(R)[0], T.reshape(3, 1), K2, D2)
    ql = m.rectify_points(pl.reshape(-1, 2), "left")
    qr = m.rectify_points(pr.reshape(-1, 2), "right")
    np.testing.assert_allclose(ql[:, 1], qr[:, 1], atol=1e-3)
    z = cam.depth_of(ql[:, 0] - qr[:, 0])
    z_true = (m.rectification["R1"] @ X.T)[2]
    np.testing.assert_allclose(z, z_true, rtol=1e-4)
    assert cam.baseline == pytest.approx(np.linalg.norm(T), rel=1e-9) and cam.doffs == 0.0


def test_rectified_camera_matcher_does_not_warp():
    m = StereoMatcher(CAM)
    left, right = layered_pair(np.random.default_rng(6))
    lr, rr = m.rectify(left, right)
    assert not m.needs_rectification
    np.testing.assert_array_equal(lr, left)
    np.testing.assert_array_equal(rr, right)
    np.testing.assert_array_equal(m.compute(left, right), m.disparity(left, right))
    Q = m.rectification["Q"]
    w = Q @ np.array([10.0, 20.0, 12.0, 1.0])  # (x, y, d, 1) → homogeneous 3D
    assert w[2] / w[3] == pytest.approx(CAM.f * CAM.baseline / (12.0 + CAM.doffs))


# ---------------------------------------------------------------------------
# calibration files
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("ext", ["yml", "xml", "json"])
def test_calibration_round_trip(tmp_path, ext):
    c = calibration()
    c.save(tmp_path / f"rig.{ext}")
    back = StereoCalibration.load(tmp_path / f"rig.{ext}")
    for name in ("K1", "D1", "K2", "D2", "R", "T"):
        np.testing.assert_array_equal(getattr(back, name), getattr(c, name), err_msg=name)
    assert back.image_size == SIZE
    fs = cv2.FileStorage(str(tmp_path / f"rig.{ext}"), cv2.FILE_STORAGE_READ)  # OpenCV reads our file
    np.testing.assert_array_equal(fs.getNode("K1").mat(), K1)
    fs.release()


@pytest.mark.parametrize("ext", ["yml", "xml", "json"])
def test_calibration_without_distortion_round_trips(tmp_path, ext):
    """Zero distortion coefficients (allowed: 0, 4, 5, 8, 12 or 14) are saved as an
    empty matrix and must load back as such, not as a missing node."""
    c = StereoCalibration(K1=K1, D1=None, K2=K2, D2=np.zeros(0), R=R, T=T, image_size=SIZE)
    c.save(tmp_path / f"rig.{ext}")
    back = StereoCalibration.load(tmp_path / f"rig.{ext}")
    assert back.D1.shape == (0,) and back.D2.shape == (0,)
    np.testing.assert_array_equal(back.K2, K2)
    np.testing.assert_array_equal(back.T, T)


def test_loads_opencv_stereo_calib_sample_files(tmp_path):
    """OpenCV's stereo_calib sample writes M1 D1 M2 D2 to intrinsics.yml and R T R1 ... to extrinsics.yml."""
    fs = cv2.FileStorage(str(tmp_path / "intrinsics.yml"), cv2.FILE_STORAGE_WRITE)
    for k, v in (("M1", K1), ("D1", D1.reshape(1, -1)), ("M2", K2), ("D2", D2.reshape(1, -1))):
        fs.write(k, v)
    fs.release()
    fs = cv2.FileStorage(str(tmp_path / "extrinsics.yml"), cv2.FILE_STORAGE_WRITE)
    fs.write("R", R)
    fs.write("T", T.reshape(3, 1))
    fs.write("imageSize", np.array(SIZE, dtype=np.int32))
    fs.release()
    c = StereoCalibration.load(tmp_path / "intrinsics.yml", tmp_path / "extrinsics.yml")
    np.testing.assert_array_equal(c.K2, K2)
    np.testing.assert_array_equal(c.T, T)
    assert c.image_size == SIZE
    with pytest.raises(ValueError, match="no R node"):
        StereoCalibration.load(tmp_path / "intrinsics.yml")


def test_bad_calibration_names_the_field(tmp_path):
    good = dict(K1=K1, D1=D1, K2=K2, D2=D2, R=R, T=T, image_size=SIZE)
    cases = [
        (dict(K2=np.where(np.eye(3, dtype=bool), np.nan, K2)), r"K2\[0, 0\] = nan"),
        (dict(D1=[0.1, np.nan, 0, 0, 0]), r"D1\[1\] = nan"),
        (dict(T=[np.nan, 0, 0]), r"T\[0\] = nan"),
        (dict(D2=[0.1, 0.2, 0.3]), "D2 has 3 coefficients"),
        (dict(R=2 * np.eye(3)), "R is not a rotation"),
        (dict(T=[0.12, 0, 0]), "camera 2 is left of camera 1"),
        (dict(T=[0.0, 0.1, 0]), "vertical stereo"),
        (dict(image_size=(640, 0)), "image_size"),
        (dict(K1=np.eye(2)), r"K1 must have shape \(3, 3\)"),
    ]
    for change, match in cases:
        with pytest.raises(ValueError, match=match):
            StereoCalibration(**{**good, **change})
    with pytest.raises(ValueError, match="does not exist"):
        StereoCalibration.load(tmp_path / "missing.yml")
    (tmp_path / "junk.yml").write_text("this is not : [ opencv")
    with pytest.raises(ValueError, match="junk.yml"):
        StereoCalibration.load(tmp_path / "junk.yml")
    with pytest.raises(ValueError, match="baseline = -1"):
        RectifiedCamera(f=500, cx=1, cy=1, baseline=-1)
    with pytest.raises(ValueError, match="f = nan"):
        RectifiedCamera(f=np.nan, cx=1, cy=1, baseline=1)
    with pytest.raises(ValueError, match="width = 10.5 must be an integer"):
        RectifiedCamera(f=500, cx=1, cy=1, baseline=1, width=10.5)
    with pytest.raises(ValueError, match="f = '500' must be a number"):
        RectifiedCamera(f="500", cx=1, cy=1, baseline=1)


# ---------------------------------------------------------------------------
# bad images and boxes
# ---------------------------------------------------------------------------

def test_bad_images_name_the_value():
    m = StereoMatcher(CAM)
    img = np.zeros((240, 320), np.uint8)
    with pytest.raises(ValueError, match=r"differ in shape: \(240, 320\) vs \(240, 300\)"):
        m.disparity(img, img[:, :300])
    with pytest.raises(ValueError, match="right is empty"):
        m.rectify(img, np.zeros((0, 0), np.uint8))
    with pytest.raises(ValueError, match="left_rect must have dtype uint8, got float64"):
        m.disparity(img.astype(float), img)
    with pytest.raises(ValueError, match="shape"):
        m.disparity(np.zeros((240, 320, 3, 1), np.uint8), np.zeros((240, 320, 3, 1), np.uint8))
    with pytest.raises(ValueError, match="numpy uint8 array, got list"):
        m.disparity([[1]], img)
    with pytest.raises(ValueError, match="does not match the calibration's 320x240"):
        m.disparity(img[:200], img[:200])
    with pytest.raises(ValueError, match="does not match the calibration's 640x480"):
        StereoMatcher(calibration()).rectify(img, img)
    with pytest.raises(ValueError, match="StereoCalibration or a RectifiedCamera"):
        StereoMatcher({"f": 1})


def test_bad_boxes_and_disparities_name_the_value():
    m = StereoMatcher(CAM)
    d = np.zeros((240, 320), np.float32)
    with pytest.raises(ValueError, match="is empty"):
        m.box_range(d, (10, 10, 5, 20))
    with pytest.raises(ValueError, match=r"box\[2\] = nan"):
        m.box_range(d, (10, 10, np.nan, 20))
    with pytest.raises(ValueError, match=r"disparity must have shape \(240, 320\)"):
        m.box_range(d[:10], (0, 0, 5, 5))
    with pytest.raises(ValueError, match="sigma_d = 0"):
        m.box_range(d, (0, 0, 5, 5), sigma_d=0.0)
    with pytest.raises(ValueError, match=r"min_valid_pixels = nan: must be an integer in \[1, 100000000\]"):
        m.box_range(d, (0, 0, 5, 5), min_valid_pixels=float("nan"))
    with pytest.raises(TypeError, match="sigma_d: 'x' is not a number"):
        m.box_range(d, (0, 0, 5, 5), sigma_d="x")
    with pytest.raises(ValueError, match=r"max_range = nan: must be in \(0, inf\] m"):
        m.box_range(d, (0, 0, 5, 5), max_range=float("nan"))
    assert isinstance(m.box_range(d, (100, 100, 120, 120)), BoxRange)

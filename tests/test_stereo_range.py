"""SGBM's disparity search from geometry (``disparity_range``,
``StereoMatcher.for_depth_range``) and Middlebury-style scoring counted two
ways (``disparity_scores``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings, strategies as st

from safenav.vision.stereo import (DISPARITY_MARGIN_PX, RectifiedCamera, StereoCalibration, StereoMatcher,
                                   disparity_range, disparity_scores)


def cam(f=700.0, baseline=0.12, doffs=0.0, width=640, height=480):
    return RectifiedCamera(f=f, cx=(width - 1) / 2, cy=(height - 1) / 2, baseline=baseline, doffs=doffs,
                           width=width, height=height)


# ---------------------------------------------------------------------------
# disparity_range: hand-computed cases
# ---------------------------------------------------------------------------

def test_far_at_infinity_without_doffs_starts_at_zero():
    # f·B = 84: d(1 m) = 84 → 84 + 2 (margin) = 86 → need 87 disparities 0..86 → 96
    assert DISPARITY_MARGIN_PX == 2
    assert disparity_range(cam(), 1.0) == (0, 96)
    assert disparity_range(cam(), 1.0, margin_px=0) == (0, 96)        # 85 → 96
    assert disparity_range(cam(), 2.0, margin_px=0) == (0, 48)        # d = 42 → 43 → 48


def test_doffs_shifts_both_ends():
    c = cam(f=1000.0, baseline=0.2, doffs=10.0)          # f·B = 200
    # d(2) = 100 − 10 = 90 → 92; d(5) = 40 − 10 = 30; 92 − 30 + 1 = 63 → 64
    assert disparity_range(c, 2.0, 5.0) == (30, 64)
    # far = ∞: d(∞) = −doffs = −10; 92 + 10 + 1 = 103 → 112
    assert disparity_range(c, 2.0) == (-10, 112)
    # a fractional doffs is floored at infinity: ⌊−10.5⌋ = −11; ⌈100 − 10.5⌉ = 90 → 92; 92 + 11 + 1 = 104 → 112
    assert disparity_range(cam(f=1000.0, baseline=0.2, doffs=10.5), 2.0) == (-11, 112)
    # the Middlebury motorcycle's doffs: 31.086 px
    mc = RectifiedCamera(f=994.978, cx=311.193, cy=254.877, baseline=0.193001, doffs=31.086, width=741, height=500)
    lo, num = disparity_range(mc, 2.0, 6.0)
    assert lo == math.floor(994.978 * 0.193001 / 6.0 - 31.086) == 0
    d_near = math.ceil(994.978 * 0.193001 / 2.0 - 31.086) + 2              # ⌈64.93⌉ + 2 = 67
    assert num == 16 * math.ceil((d_near - lo + 1) / 16) == 80


def test_num_disparities_rounds_up_to_a_multiple_of_16():
    c = cam(f=1000.0, baseline=0.2)                     # f·B = 200, doffs = 0
    assert disparity_range(c, 200 / 15, margin_px=0) == (0, 16)     # d = 15: 0..15 is 16 disparities
    assert disparity_range(c, 200 / 15.01, margin_px=0) == (0, 32)  # d = 15.01 → 16: 17 disparities → 32
    assert disparity_range(c, 200 / 31, margin_px=0) == (0, 32)     # d = 31 → 32
    assert disparity_range(c, 200 / 31, margin_px=1) == (0, 48)     # 33 → 48
    for near in np.linspace(0.5, 20, 37):
        lo, num = disparity_range(c, float(near), margin_px=3)
        need = math.ceil(200 / near) + 3 - lo + 1
        assert num % 16 == 0 and need <= num < need + 16


def test_near_exactly_on_a_disparity_boundary():
    """d(near) exactly an integer k: k is searched, and no extra disparity is
    opened by float round-off (84/1.75 and 84/(84/47) are not exact)."""
    c = cam()                                           # f·B = 84
    assert disparity_range(c, 1.75, margin_px=0) == (0, 64)         # d = 48: 0..48 is 49 → 64
    assert disparity_range(c, 84 / 47, margin_px=0) == (0, 48)      # d = 47: 0..47 is 48 → 48
    assert disparity_range(c, 84 / 63, margin_px=0) == (0, 64)      # d = 63: exactly the fixed 64's last
    assert disparity_range(c, 84 / 64, margin_px=0) == (0, 80)      # d = 64: one past it
    lo, num = disparity_range(c, 84 / 47, margin_px=0)
    assert lo <= c.disparity_of(84 / 47) < lo + num


def test_accepts_a_calibration_or_a_matcher():
    K = np.array([[700.0, 0, 319.5], [0, 700.0, 239.5], [0, 0, 1]])
    calib = StereoCalibration(K, np.zeros(5), K, np.zeros(5), np.eye(3), np.array([-0.12, 0, 0]), (640, 480))
    rect = StereoMatcher(calib).camera                  # what stereoRectify makes of it (doffs = 0)
    assert rect.doffs == pytest.approx(0.0, abs=1e-9)
    assert disparity_range(calib, 1.0, 10.0) == disparity_range(rect, 1.0, 10.0)
    assert disparity_range(StereoMatcher(calib), 1.0) == disparity_range(rect, 1.0)
    m = StereoMatcher.for_depth_range(calib, 1.0, 10.0, block_size=3)
    assert m.needs_rectification
    lo, num = disparity_range(rect, 1.0, 10.0, block_size=3)
    assert (m.sgbm_params["min_disparity"], m.sgbm_params["num_disparities"]) == (lo, num) == (8, 80)
    assert m.sgbm_params["block_size"] == 3


def test_explicit_sgbm_params_override_the_range():
    m = StereoMatcher.for_depth_range(cam(), 1.0, num_disparities=32, mode="sgbm_3way")
    assert (m.sgbm_params["min_disparity"], m.sgbm_params["num_disparities"]) == (0, 32)
    m = StereoMatcher.for_depth_range(cam(), 1.0, 10.0, min_disparity=2)
    assert (m.sgbm_params["min_disparity"], m.sgbm_params["num_disparities"]) == (2, 80)
    assert m.sgbm_params["mode"] == "sgbm"


# ---------------------------------------------------------------------------
# disparity_range: every depth of interest is searched
# ---------------------------------------------------------------------------

@settings(max_examples=300, deadline=None)
@given(f=st.floats(50.0, 5000.0), baseline=st.floats(0.01, 2.0), doffs=st.floats(-100.0, 100.0),
       near=st.floats(0.05, 100.0), ratio=st.one_of(st.just(math.inf), st.floats(1.0001, 1000.0)),
       margin=st.integers(0, 8))
@example(f=243.9375, baseline=0.05078125, doffs=0.0, near=0.05078125, ratio=243.9375, margin=0)  # 1/(1/far) > far
def test_every_depth_in_range_maps_inside_the_search(f, baseline, doffs, near, ratio, margin):
    c = RectifiedCamera(f=f, cx=100.0, cy=100.0, baseline=baseline, doffs=doffs, width=1 << 30, height=200)
    far = near * ratio
    lo, num = disparity_range(c, near, far, margin_px=margin)
    assert num > 0 and num % 16 == 0
    # depths across [near, far], evenly in inverse depth, and both ends
    inv = np.linspace(1.0 / near, 0.0 if math.isinf(far) else 1.0 / far, 101)
    with np.errstate(divide="ignore"):
        # 1/(1/far) can round past far: clip to the range the contract is about
        z = np.concatenate([[near, far], np.clip(1.0 / inv, near, far)])
    d = c.disparity_of(z)
    assert np.all(d >= lo) and np.all(d < lo + num), (lo, num, d.min(), d.max())
    # and the search is no wider than the rounding to 16 needs
    need = math.ceil(f * baseline / near - doffs) + margin - lo + 1
    assert num < need + 16


# ---------------------------------------------------------------------------
# for_depth_range end to end: a shift beyond 64 px
# ---------------------------------------------------------------------------

def _shifted_pair(shift, width=420, height=120, seed=3):
    """A random texture and the same texture ``shift`` px to the left: every
    left pixel x matches right pixel x − shift (disparity ``shift``)."""
    import cv2

    rng = np.random.default_rng(seed)
    tex = rng.integers(0, 256, (height, width + shift), dtype=np.uint8)
    tex = cv2.GaussianBlur(tex, (0, 0), 1.0)
    return np.ascontiguousarray(tex[:, :width]), np.ascontiguousarray(tex[:, shift:shift + width])


def test_for_depth_range_recovers_a_100px_disparity_that_64_cannot():
    c = cam(f=500.0, baseline=0.1, width=420, height=120)   # f·B = 50: 100 px is Z = 0.5 m
    left, right = _shifted_pair(100)
    truth = 100.0
    assert c.depth_of(truth) == pytest.approx(0.5)

    fixed = StereoMatcher(c, num_disparities=64).disparity(left, right)
    ok_fixed = np.abs(fixed - truth) <= 0.5
    assert ok_fixed.sum() == 0                       # 100 is outside 0..63: nothing right

    m = StereoMatcher.for_depth_range(c, 0.4, 5.0)   # d 10..125 (+2) → min 10, 128 disparities
    assert (m.sgbm_params["min_disparity"], m.sgbm_params["num_disparities"]) == (10, 128)
    d = m.disparity(left, right)
    band = m.sgbm_params["min_disparity"] + m.sgbm_params["num_disparities"]
    inner = d[8:-8, band + 8:-8]                     # right of SGBM's unmatched left band, off the borders
    assert np.isnan(d[:, :band - 1]).all()           # the left band the wider search costs
    assert np.mean(np.abs(inner - truth) <= 0.5) > 0.95
    assert np.nanmedian(np.abs(inner - truth)) < 0.1
    z = m.depth(d)
    assert np.nanmedian(z[8:-8, band + 8:-8]) == pytest.approx(0.5, rel=2e-3)


# ---------------------------------------------------------------------------
# scoring two ways
# ---------------------------------------------------------------------------

def test_scores_two_ways_on_known_counts():
    nan = np.nan
    gt = np.array([[10, 10, 10, 10, 10],
                   [20, 20, 20, 20, 20],
                   [30, 30, 30, nan, nan],
                   [40, 40, 40, 40, nan]], dtype=np.float32)       # G = 17 pixels with ground truth
    d = np.array([[10.0, 10.4, 11.5, 13.0, nan],                   # errors 0, .4, 1.5, 3; 1 unmatched
                  [20.0, 25.0, 20.0, nan, nan],                    # 0, 5, 0; 2 unmatched
                  [30.0, 30.0, 29.0, 7.0, nan],                    # 0, 0, 1; (7.0 has no ground truth)
                  [40.0, 40.0, 44.0, 40.0, 40.0]], dtype=np.float32)  # 0, 0, 4, 0; (no ground truth)
    s = disparity_scores(d, gt)
    assert (s.n_ground_truth, s.n_matched) == (17, 14)
    assert s.density == pytest.approx(14 / 17)
    # matched errors: 0 ×8, .4, 1 (29 vs 30), 1.5, 3, 4, 5 — "bad" is error > t
    over = {0.5: 5, 1.0: 4, 2.0: 3, 4.0: 1}
    for t, n in over.items():
        assert s.bad(t, "matched") == pytest.approx(n / 14)
        assert s.bad(t, "all") == pytest.approx((n + 3) / 17)   # + the 3 unmatched
    assert s.mae == pytest.approx((0.4 + 1 + 1.5 + 3 + 4 + 5) / 14, rel=1e-6)
    row = s.as_dict()
    assert row["bad2_all"] == pytest.approx(6 / 17) and row["bad2_matched"] == pytest.approx(3 / 14)
    assert row["bad0.5_all"] == pytest.approx(8 / 17)
    # inf in the ground truth means "unknown", like NaN
    gt_inf = np.where(np.isnan(gt), np.inf, gt)
    assert disparity_scores(d, gt_inf) == s


def test_scores_with_nothing_matched():
    gt = np.full((3, 4), 5.0, np.float32)
    s = disparity_scores(np.full((3, 4), np.nan, np.float32), gt)
    assert s.n_matched == 0 and s.density == 0.0
    assert all(b == 1.0 for b in s.bad_all)
    assert all(math.isnan(b) for b in s.bad_matched) and math.isnan(s.mae)


# ---------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("near, far, match", [
    (0.0, math.inf, "near_m = 0.0"), (-1.0, math.inf, "near_m = -1.0"), (math.nan, math.inf, "near_m = nan"),
    (math.inf, math.inf, "near_m = inf"), (True, math.inf, "near_m = True"), ("1", math.inf, "near_m = '1'"),
    (2.0, 2.0, "far_m = 2.0 must be > near_m = 2.0"), (2.0, 1.0, "far_m = 1.0"), (2.0, math.nan, "far_m = nan"),
    (2.0, None, "far_m = None"),
])
def test_bad_depths_raise_naming_the_value(near, far, match):
    with pytest.raises(ValueError, match=match.replace("(", r"\(")):
        disparity_range(cam(), near, far)
    with pytest.raises(ValueError, match=match.replace("(", r"\(")):
        StereoMatcher.for_depth_range(cam(), near, far)


def test_bad_options_raise():
    with pytest.raises(ValueError, match="margin_px = -1"):
        disparity_range(cam(), 1.0, margin_px=-1)
    with pytest.raises(ValueError, match="margin_px = 1.5"):
        disparity_range(cam(), 1.0, margin_px=1.5)
    with pytest.raises(ValueError, match="block_size = 4 must be odd"):
        disparity_range(cam(), 1.0, block_size=4)
    with pytest.raises(ValueError, match="block_size = 4 must be odd"):
        StereoMatcher.for_depth_range(cam(), 1.0, block_size=4)
    with pytest.raises(ValueError, match="camera must be a RectifiedCamera"):
        disparity_range("rig", 1.0)
    # f·B = 84: near 0.1 m is d = 840 px, wider than the 640-px image
    with pytest.raises(ValueError, match=r"near_m = 0.1 needs disparities 0..842 px .* leaves 0 of the "
                                         r"image's 640 columns"):
        disparity_range(cam(), 0.1)
    with pytest.raises(ValueError, match="unknown SGBM parameter"):
        StereoMatcher.for_depth_range(cam(), 1.0, num_disparity=64)


def test_bad_scoring_input_raises():
    gt = np.ones((3, 4), np.float32)
    with pytest.raises(ValueError, match="differ in shape"):
        disparity_scores(np.ones((3, 5), np.float32), gt)
    with pytest.raises(ValueError, match="no known pixel"):
        disparity_scores(gt, np.full((3, 4), np.nan, np.float32))
    with pytest.raises(ValueError, match="2-D float array"):
        disparity_scores(np.ones((3, 4), np.int16), gt)
    with pytest.raises(ValueError, match="infinite"):
        disparity_scores(np.full((3, 4), np.inf, np.float32), gt)
    with pytest.raises(ValueError, match="thresholds"):
        disparity_scores(gt, gt, thresholds=(-1.0,))
    s = disparity_scores(gt, gt)
    with pytest.raises(ValueError, match="threshold = 3.0 was not scored"):
        s.bad(3.0)
    with pytest.raises(ValueError, match="counting = 'some'"):
        s.bad(2.0, "some")

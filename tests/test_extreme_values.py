"""Extreme but valid values give finite results (the rule of the public API:
refuse with a named error, or return something finite).  The cases are the
ones a hostile fuzz of the API found returning inf with no error."""

from __future__ import annotations

import math

import numpy as np
import pytest

from safenav.vision.localization import horizontal_range
from safenav.vision.stereo import RectifiedCamera, StereoMatcher


@pytest.mark.parametrize("s, dh", [(1e155, 1.0), (1e300, 1e299), (3e200, 3e200), (1.7e308, 1.0), (2.0, 1e200)])
def test_horizontal_range_never_overflows(s, dh):
    h, sigma = horizontal_range(s, dh, 0.0, sigma=0.5)
    exact = math.sqrt(s - dh) * math.sqrt(s + dh) if s > dh else 0.0   # √(s−Δh)·√(s+Δh) cannot overflow
    assert math.isfinite(h) and math.isfinite(sigma)
    assert h == pytest.approx(exact, rel=1e-14, abs=0.0)


def test_horizontal_range_keeps_ordinary_values_bit_for_bit():
    s = np.array([3.0, 10.5, 25.0, 1.0])
    dh = np.array([1.2, 0.4, 2.0, 2.0])
    np.testing.assert_array_equal(horizontal_range(s, dh), np.sqrt(np.maximum(s * s - dh * dh, 0.0)))


CAM = RectifiedCamera(f=500.0, cx=160.0, cy=120.0, baseline=0.2, doffs=2.5, width=320, height=240)


@pytest.mark.parametrize("box", [(-1e308, 100, 200, 180), (100, -1e308, 200, 1e308), (-1e308, -1e308, 1e308, 1e308)])
def test_box_range_of_a_box_reaching_far_outside_the_image_is_finite(box):
    d = np.full((CAM.height, CAM.width), 20.0, dtype=np.float32)
    r = StereoMatcher(CAM, num_disparities=48, block_size=5).box_range(d, box)
    assert r.ok, r.reason
    assert r.range == pytest.approx(CAM.f * CAM.baseline / (20.0 + CAM.doffs))
    assert np.all(np.isfinite(r.point))
    # the bearing is the in-image part's centre
    x0, y0 = max(box[0], 0.0), max(box[1], 0.0)
    x1, y1 = min(box[2], CAM.width), min(box[3], CAM.height)
    assert r.point[0] == pytest.approx((0.5 * (x0 + x1) - CAM.cx) * r.range / CAM.f)
    assert r.point[1] == pytest.approx((0.5 * (y0 + y1) - CAM.cy) * r.range / CAM.f)

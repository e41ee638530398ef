"""Ranging a fiducial from its corners (``_core.corner_disparity``, the one rule that the C++ front
end and ``LandmarkRanging.observe_corners`` both call): exact corners give the exact disparity and
centre from four corners and from the three whose rows agree; the corner-noise model's σ is the
spread of the centre's disparity under corner errors with the measured correlation (Monte Carlo);
on rendered frames the measured errors fit the model; and a camera frame with too few ranges for a
fix still updates the filter with its landmarks (``FrameUpdate.FIX_OR_LANDMARKS``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from safenav import _core
from safenav.vision.detect import Detection
from safenav.vision.ranging import LandmarkRanging
from safenav.vision.render import StereoRenderer
from test_lanbloc_cpp import RIG, SCENES, _front_end, _pair, _scene
from test_lanbloc_loop import _localizer

F, CX, CY, B = 1000.0, 640.0, 360.0, 0.3


def _camera(doffs: float = 0.0):
    c = _core.RectifiedCamera()
    c.f, c.cx, c.cy, c.baseline, c.doffs, c.width, c.height = F, CX, CY, B, doffs, 1280, 720
    return c


def _marker(centre, yaw: float, half: float = 0.75):
    """A square marker's 3-D corners (TL, TR, BR, BL) in the left camera frame (y down), turned by
    ``yaw`` about the vertical, and the images of its corners and centre in both cameras."""
    c = np.asarray(centre, float)
    a = np.array([math.cos(yaw), 0.0, math.sin(yaw)]) * half
    up = np.array([0.0, -half, 0.0])
    P = np.array([c - a + up, c + a + up, c + a - up, c - a - up])

    def proj(X, right=False):
        X = X - ([B, 0.0, 0.0] if right else 0.0)
        return np.column_stack([F * X[:, 0] / X[:, 2] + CX, F * X[:, 1] / X[:, 2] + CY])

    return proj(P), proj(P, True), proj(c[None])[0], F * B / c[2]


@pytest.mark.parametrize("centre,yaw", [((1.0, 0.2, 15.0), 0.4), ((-3.0, -0.5, 8.0), -0.7), ((0.5, 1.0, 25.0), 0.1)])
def test_exact_corners_give_the_exact_centre_and_disparity(centre, yaw):
    left, right, c, d = _marker(centre, yaw)
    s = _core.LanBLocSettings()
    four = _core.corner_disparity(left, right, _camera(), s)
    assert four.ok and four.corners_used == 4 and four.dropped_corner == -1
    assert four.disparity == pytest.approx(d, abs=1e-9)               # the plane is exact for a plane
    np.testing.assert_allclose(four.centre, c, atol=1e-9)              # diagonals: the homography's centre
    assert four.sigma == pytest.approx(s.corner_sigma_d, rel=1e-15)
    for k in range(4):   # one corner hidden differently in the two images: off its row by 1.9 px
        r = right.copy()
        r[k, 1] += 1.9 if k % 2 else -1.9
        three = _core.corner_disparity(left, r, _camera(), s)
        assert three.ok and three.corners_used == 3 and three.dropped_corner == k, three.reason
        assert three.disparity == pytest.approx(d, abs=1e-9)           # the 3-D midpoint of the other diagonal
        np.testing.assert_allclose(three.centre, c, atol=1e-9)
        assert three.sigma == pytest.approx(s.corner_sigma_d * math.sqrt(2 / (1 + s.corner_edge_correlation)))
    r = right.copy()
    r[[0, 2], 1] += 1.5
    two = _core.corner_disparity(left, r, _camera(), s)
    assert not two.ok and "off their epipolar lines" in two.reason and "2 corners" in two.reason
    # doffs enters as in Z = f·B/(d + doffs)
    shifted = _core.corner_disparity(left, right - [5.0, 0.0], _camera(doffs=-5.0), s)
    assert shifted.disparity == pytest.approx(d + 5.0, abs=1e-9)


def test_bad_input_is_named():
    s = _core.LanBLocSettings()
    with pytest.raises(ValueError, match="corners_used = 2"):
        _core.corner_disparity_sigma(s, 2)
    with pytest.raises(ValueError, match="scale = -1"):
        _core.corner_disparity_sigma(s, 4, -1.0)
    left, right, *_ = _marker((0.0, 0.0, 10.0), 0.0)
    left[1, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        _core.corner_disparity(left, right, _camera(), s)
    with pytest.raises(ValueError, match="corner_edge_correlation"):
        s.set_param("corner_edge_correlation", 1.5)


@pytest.mark.parametrize("drop", [None, 2])
def test_sigma_is_the_spread_under_correlated_corner_errors(drop):
    """Monte Carlo: corner disparity errors σ_c each, correlated ρ on each vertical edge (0–3, 1–2)
    and independent across, as measured; the centre's disparity spreads by corner_disparity_sigma."""
    s = _core.LanBLocSettings()
    s.corner_square_sigmas = 0.0   # the propagation alone (σ_c here is larger than the model's)
    rho = s.corner_edge_correlation
    left, right, _, d = _marker((0.5, 0.3, 12.0), 0.3)
    C = np.eye(4)
    C[0, 3] = C[3, 0] = C[1, 2] = C[2, 1] = rho
    sigma_c = 0.06
    rng = np.random.default_rng(1)
    e = rng.multivariate_normal(np.zeros(4), sigma_c ** 2 * C, size=4000)
    out = []
    for ei in e:
        r = right.copy()
        r[:, 0] -= ei
        if drop is not None:
            r[drop, 1] += 3.0
        out.append(_core.corner_disparity(left, r, _camera(), s).disparity - d)
    want = sigma_c * math.sqrt((1 + rho) / 4)   # the four's spread for per-corner σ_c
    if drop is not None:
        want *= math.sqrt(2 / (1 + rho))
    assert np.std(out) == pytest.approx(want, rel=0.05)
    model = _core.corner_disparity_sigma(s, 3 if drop is not None else 4)
    assert model / s.corner_sigma_d == pytest.approx(want / (sigma_c * math.sqrt((1 + rho) / 4)), rel=1e-12)


@settings(max_examples=150, deadline=None)
@given(x=st.floats(-0.5, 0.5), y=st.floats(-0.3, 0.3), z=st.floats(4.0, 30.0), yaw=st.floats(-1.0, 1.0),
       k=st.integers(0, 3), shift=st.floats(1.0, 15.0), sign=st.sampled_from([-1.0, 1.0]),
       image=st.sampled_from(["left", "right"]))
def test_square_check_never_ranges_a_corner_moved_along_its_row(x, y, z, yaw, k, shift, sign, image):
    """A corner hidden behind a nearer board in one image moves along its row, which the row check
    cannot see.  Exact corners (boards on and off the optical axis, facing the camera or turned,
    4-30 m) pass the square check with all four; with one corner moved 1-15 px along its row in
    either image the marker is ranged only from the other three (exactly) or not at all."""
    left, right, c, d = _marker((x * z, y * z, z), yaw)
    s = _core.LanBLocSettings()
    four = _core.corner_disparity(left, right, _camera(), s)
    assert four.ok and four.corners_used == 4, four.reason
    moved = (left if image == "left" else right).copy()
    moved[k, 0] += sign * shift
    out = _core.corner_disparity(*((moved, right) if image == "left" else (left, moved)), _camera(), s)
    if out.ok:
        assert out.corners_used == 3 and out.dropped_corner == k, out.reason
        # the midpoint of the other diagonal's two corners, both exact (the left centre moves with
        # a moved left corner, but the triangulated midpoint does not)
        assert out.disparity == pytest.approx(d, abs=1e-6)
    else:
        assert "square" in out.reason or "plane" in out.reason, out.reason


def test_square_check_rarely_rejects_the_models_own_noise():
    """Corner disparity errors drawn from the noise model itself (per-corner σ_c, correlation ρ on
    the vertical edges): the check (6 σ) rejects or drops a corner of under 0.5 % of 4000 markers."""
    s = _core.LanBLocSettings()
    rho = s.corner_edge_correlation
    sigma_c = s.corner_sigma_d * 2 / math.sqrt(1 + rho)
    C = np.eye(4)
    C[0, 3] = C[3, 0] = C[1, 2] = C[2, 1] = rho
    rng = np.random.default_rng(3)
    flagged = 0
    for i in range(4000):
        z = rng.uniform(4.0, 30.0)
        left, right, _, _ = _marker((rng.uniform(-0.5, 0.5) * z, rng.uniform(-0.3, 0.3) * z, z),
                                    rng.uniform(-1.0, 1.0))
        r = right.copy()
        r[:, 0] -= rng.multivariate_normal(np.zeros(4), sigma_c ** 2 * C)
        out = _core.corner_disparity(left, r, _camera(), s)
        flagged += not (out.ok and out.corners_used == 4)
    assert flagged <= 20, flagged


def test_python_ranging_calls_the_same_rule():
    """LandmarkRanging.observe_corners: the core's disparity, centre and σ (also for three corners)."""
    world = _scene(*SCENES[0])
    ranger = LandmarkRanging(world, RIG)
    cam = _core.RectifiedCamera()
    cam.f, cam.cx, cam.cy, cam.baseline, cam.doffs, cam.width, cam.height = (
        RIG.focal_length_px, RIG.cx, RIG.cy, RIG.baseline_m, 0.0, RIG.width, RIG.height)
    left, right, _, _ = _marker((0.5, 0.2, 9.0), 0.2)
    left = left * 0.35 + [100.0, 120.0]     # into the 640x480 image (any corners will do)
    right = right * 0.35 + [100.0, 120.0]
    right[3, 1] += 1.7
    lm = world.landmarks[0]
    det = lambda c: Detection(lm.id, lm.class_name, (0, 0, 1, 1), 1.0, corners=c)   # noqa: E731
    o = ranger.observe_corners(det(left), det(right))
    cd = _core.corner_disparity(left, right, cam, ranger.corner_settings)
    assert o.ok and cd.corners_used == 3 and o.n_valid == 3
    assert o.disparity == cd.disparity
    Z = RIG.fB / cd.disparity
    assert o.depth == pytest.approx(Z, rel=1e-12)
    assert o.sigma > Z * Z * cd.sigma / RIG.fB     # σ_Z, then along the ray and to the ground


def test_rendered_corner_errors_fit_the_model():
    """The front end's centre disparities on rendered frames (pixel noise σ = 1, the optics' blur)
    against the truth: their mean squared error over the model's σ² is near 1 (not a cautious or a
    bold model), for markers of at least 30 px a side, the model's domain (docs/lanbloc_cpp.md)."""
    z2 = []
    for pose, placements in SCENES:
        world = _scene(pose, placements)
        ren = StereoRenderer(world, RIG, noise_std=1.0, seed=11)
        fe = _front_end(world)
        for k in range(4):
            p = (pose[0] + 0.4 * k, pose[1] - 0.3 * k, pose[2] + 0.01 * k)
            left, right = ren.render(p)
            corners = ren.marker_corners(p)
            for o in fe.localize(left, right).observations:
                cl = np.asarray(o.corners_left)
                side = np.mean(np.linalg.norm(np.roll(cl, -1, 0) - cl, axis=1))
                if not o.ok or o.landmark_id not in corners or side < 30.0:
                    continue
                _, Z = ren.project(p, corners[o.landmark_id].mean(axis=0)[None], "left")
                Zc = float(Z[0])
                z2.append(((o.disparity - RIG.fB / Zc) /
                           _core.corner_disparity_sigma(_core.LanBLocSettings(), o.corners_used)) ** 2)
    assert len(z2) >= 30
    assert 0.3 < np.mean(z2) < 3.0


@pytest.mark.parametrize("min_landmarks", [3, 50])
def test_fix_or_landmarks(min_landmarks):
    """FIX_OR_LANDMARKS is FIX when the frame gives a fix, else LANDMARKS (each range and bearing
    through the gated observe()): a frame with too few ranges for a fix still informs the filter."""
    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    fe = _front_end(world, min_landmarks=min_landmarks)
    P3 = np.diag([0.2 ** 2, 0.2 ** 2, math.radians(1.5) ** 2])
    a, b = (_localizer(world, fe, pose, P3) for _ in range(2))
    got = a.observe_frame(0.0, left, right, _core.FrameUpdate.FIX_OR_LANDMARKS)
    want = b.observe_frame(0.0, left, right, _core.FrameUpdate.FIX if min_landmarks == 3 else
                           _core.FrameUpdate.LANDMARKS)
    assert got.fix.ok == (min_landmarks == 3)
    assert got.update.status == want.update.status == _core.InputStatus.APPLIED
    assert [s.status for s in got.landmarks] == [s.status for s in want.landmarks]
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.P, b.P)
    if min_landmarks == 50:   # the landmarks moved the estimate: not a no-op
        c = _localizer(world, fe, pose, P3)
        assert not np.array_equal(c.P, a.P)

"""Trilateration and bearing triangulation (LanBLoc's position fix, SafeNav
IV-A): exactness, covariance against Monte Carlo, agreement with scipy's
least_squares, outlier rejection, failure statuses and bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import optimize, stats

from safenav.vision.localization import horizontal_range, triangulate_bearings, trilaterate

SQUARE = np.array([[0.0, 0.0], [40.0, 0.0], [40.0, 30.0], [0.0, 30.0], [20.0, 45.0]])


def ranges_to(anchors, p):
    return np.linalg.norm(anchors - p, axis=1)


def bearings_to(anchors, p):
    return np.arctan2(anchors[:, 1] - p[1], anchors[:, 0] - p[0])


def test_exact_on_noiseless_ranges_over_random_geometries():
    rng = np.random.default_rng(1)
    n_ok = 0
    for _ in range(200):
        n = rng.integers(3, 9)
        anchors = rng.uniform(-50, 50, (n, 2))
        p = rng.uniform(-60, 60, 2)
        res = trilaterate(anchors, ranges_to(anchors, p), 0.1)
        if res.status == "degenerate":  # only allowed for genuinely bad geometry
            assert res.gdop > 100 or "ambiguous" in res.reason or "collinear" in res.reason
            continue
        assert res.ok, res.reason
        n_ok += 1
        np.testing.assert_allclose(res.position, p, atol=1e-9)
        assert res.inliers.all()
    assert n_ok > 180


def test_exact_on_noiseless_bearings_and_relative_bearings():
    rng = np.random.default_rng(2)
    for _ in range(100):
        n = rng.integers(2, 7)
        anchors = rng.uniform(-50, 50, (n, 2))
        p = rng.uniform(-60, 60, 2)
        b = bearings_to(anchors, p)
        res = triangulate_bearings(anchors, b, 0.01)
        if not res.ok:
            assert res.status == "degenerate", res.reason
            continue
        np.testing.assert_allclose(res.position, p, atol=1e-9)
        heading = rng.uniform(-np.pi, np.pi)
        rel = np.angle(np.exp(1j * (b - heading)))
        np.testing.assert_allclose(triangulate_bearings(anchors, rel, 0.01, heading=heading).position, p, atol=1e-9)


def _gauss_newton_covariance(anchors, p, sigmas):
    u = (p - anchors) / np.linalg.norm(p - anchors, axis=1)[:, None]
    return np.linalg.inv(u.T @ np.diag(sigmas**-2.0) @ u), np.sqrt(np.trace(np.linalg.inv(u.T @ u)))


def test_covariance_and_gdop_are_the_normal_equations():
    p = np.array([12.0, 9.0])
    sig = np.array([0.1, 0.2, 0.05, 0.3, 0.1])
    res = trilaterate(SQUARE, ranges_to(SQUARE, p), sig)
    cov, gdop = _gauss_newton_covariance(SQUARE, p, sig)
    np.testing.assert_allclose(res.covariance, cov, rtol=1e-10)
    assert res.gdop == pytest.approx(gdop, rel=1e-10)


def test_empirical_covariance_matches_returned_covariance():
    """Monte Carlo: 3000 noisy fixes; the sample covariance matches (Jᵀ W J)⁻¹
    and the NEES eᵀ P⁻¹ e averages 2 (chi-square, 2 dof)."""
    rng = np.random.default_rng(3)
    p = np.array([15.0, 10.0])
    sig = np.array([0.2, 0.1, 0.3, 0.15, 0.25])
    r0 = ranges_to(SQUARE, p)
    n = 3000
    est = np.empty((n, 2))
    nees = np.empty(n)
    for k in range(n):
        res = trilaterate(SQUARE, r0 + sig * rng.standard_normal(5), sig, reject_outliers=False)
        assert res.ok, res.reason
        est[k] = res.position
        e = res.position - p
        nees[k] = e @ np.linalg.solve(res.covariance, e)
    cov_true, _ = _gauss_newton_covariance(SQUARE, p, sig)
    emp = np.cov(est.T)
    # Each variance has relative standard error sqrt(2/n) ≈ 2.6 %; allow ~4 σ.
    np.testing.assert_allclose(np.diag(emp), np.diag(cov_true), rtol=0.1)
    corr_emp = emp[0, 1] / np.sqrt(emp[0, 0] * emp[1, 1])
    corr_true = cov_true[0, 1] / np.sqrt(cov_true[0, 0] * cov_true[1, 1])
    assert abs(corr_emp - corr_true) < 4 / np.sqrt(n)
    # second-order bias O(σ²/range) is far below the 4-standard-error band here
    assert np.all(np.abs(est.mean(axis=0) - p) < 4 * np.sqrt(np.diag(cov_true) / n))
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], 2 * n) / n
    assert lo < nees.mean() < hi


def test_agrees_with_scipy_least_squares():
    rng = np.random.default_rng(4)
    for _ in range(30):
        anchors = rng.uniform(0, 50, (6, 2))
        p = rng.uniform(5, 45, 2)
        sig = rng.uniform(0.05, 0.5, 6)
        z = ranges_to(anchors, p) + sig * rng.standard_normal(6)
        res = trilaterate(anchors, z, sig, reject_outliers=False)
        if not res.ok:
            continue
        ref = optimize.least_squares(lambda q: (z - ranges_to(anchors, q)) / sig, res.position + 1.0,
                                     xtol=1e-15, ftol=1e-15, gtol=1e-15)
        np.testing.assert_allclose(res.position, ref.x, atol=1e-7)
        assert res.chi2 == pytest.approx(2 * ref.cost, rel=1e-6, abs=1e-12)


def test_bearing_fit_agrees_with_scipy_least_squares():
    rng = np.random.default_rng(5)
    anchors = SQUARE
    p = np.array([18.0, 12.0])
    sig = np.full(5, 0.02)
    z = bearings_to(anchors, p) + sig * rng.standard_normal(5)
    res = triangulate_bearings(anchors, z, sig, reject_outliers=False)
    assert res.ok
    ref = optimize.least_squares(lambda q: np.angle(np.exp(1j * (z - bearings_to(anchors, q)))) / sig,
                                 p + 2.0, xtol=1e-15, ftol=1e-15, gtol=1e-15)
    np.testing.assert_allclose(res.position, ref.x, atol=1e-7)


@pytest.mark.parametrize("bad", [[1], [0, 3], [2, 4]])
def test_outliers_are_rejected(bad):
    rng = np.random.default_rng(6)
    anchors = np.vstack([SQUARE, [[-10.0, 20.0], [50.0, 15.0]]])
    p = np.array([22.0, 14.0])
    sig = np.full(len(anchors), 0.1)
    z = ranges_to(anchors, p) + sig * rng.standard_normal(len(anchors))
    z[bad] += np.array([6.0, -4.0])[: len(bad)]
    res = trilaterate(anchors, z, sig)
    assert res.ok, res.reason
    expect = np.ones(len(anchors), bool)
    expect[bad] = False
    np.testing.assert_array_equal(res.inliers, expect)
    assert f"{len(bad)} of {len(anchors)}" in res.reason
    assert np.linalg.norm(res.position - p) < 4 * np.sqrt(np.trace(res.covariance))
    plain = trilaterate(anchors, z, sig, reject_outliers=False)
    assert np.linalg.norm(plain.position - p) > 5 * np.linalg.norm(res.position - p)


def test_one_outlier_among_exactly_four_ranges():
    """Four ranges, one of them off by 3-8 m (well beyond 3σ).  Three ranges in
    2D leave one degree of freedom to check, so the outlier shows unless the
    geometry lets another triple fit as well.  Whenever a range is rejected it
    must be the bad one and the fix within 4σ of the truth; a triple that fits
    elsewhere as well must give 'degenerate' (ambiguous), never a wrong point
    marked ok.  The outlier passes unnoticed only where a wrong point fits all
    four ranges (rare: under 2 % of the draws)."""
    rng = np.random.default_rng(12)
    rejected = ambiguous = unnoticed = 0
    for _ in range(300):
        anchors = rng.uniform(0, 40, (4, 2))
        p = rng.uniform(5, 35, 2)
        sig = np.full(4, 0.1)
        z = ranges_to(anchors, p) + sig * rng.standard_normal(4)
        bad = int(rng.integers(4))
        z[bad] = max(z[bad] + rng.choice([-1.0, 1.0]) * rng.uniform(3, 8), 0.5)
        res = trilaterate(anchors, z, sig)
        if not res.ok:
            assert res.status == "degenerate", res.reason
            ambiguous += res.reason.startswith("ambiguous outliers")
            continue
        if res.inliers.all():
            unnoticed += 1
            continue
        expect = np.ones(4, bool)
        expect[bad] = False
        np.testing.assert_array_equal(res.inliers, expect)
        assert np.linalg.norm(res.position - p) < 4 * np.sqrt(np.trace(res.covariance))
        rejected += 1
    # measured: 249 rejected correctly, 37 ambiguous outliers, 13 mirror-ambiguous, 1 unnoticed
    assert rejected >= 230 and ambiguous >= 20 and unnoticed <= 6, (rejected, ambiguous, unnoticed)


def test_two_triples_that_fit_two_positions_are_ambiguous():
    """Anchors 0 and 1 on the x axis are equidistant from p = (10, 8) and its
    mirror image q = (10, −8); range 2 is measured to p and range 3 to q.  The
    triples {0, 1, 2} and {0, 1, 3} fit p and q exactly: which range is the
    outlier cannot be told, so the fix is degenerate, not p or q."""
    anchors = np.array([[0.0, 0.0], [25.0, 0.0], [30.0, 20.0], [-5.0, -15.0]])
    p, q = np.array([10.0, 8.0]), np.array([10.0, -8.0])
    z = np.r_[ranges_to(anchors[:3], p), np.linalg.norm(anchors[3] - q)]
    res = trilaterate(anchors, z, 0.1)
    assert res.status == "degenerate" and "ambiguous" in res.reason and np.isnan(res.position).all()
    assert "10" in res.reason and "-8" in res.reason          # both candidate positions are named
    for drop, want in ((3, p), (2, q)):                        # each triple alone is a clean fix
        keep = [i for i in range(4) if i != drop]
        np.testing.assert_allclose(trilaterate(anchors[keep], z[keep], 0.1).position, want, atol=1e-9)


def test_bearing_outlier_is_rejected():
    p = np.array([18.0, 12.0])
    z = bearings_to(SQUARE, p)
    z[2] += 0.5
    res = triangulate_bearings(SQUARE, z, 0.01)
    assert res.ok and not res.inliers[2] and res.inliers.sum() == 4
    np.testing.assert_allclose(res.position, p, atol=1e-9)


def test_sampled_minimal_sets_are_deterministic_per_seed():
    rng = np.random.default_rng(7)
    anchors = rng.uniform(0, 100, (30, 2))
    p = np.array([50.0, 50.0])
    z = ranges_to(anchors, p) + 0.1 * rng.standard_normal(30)
    z[:5] += 8.0
    a = trilaterate(anchors, z, 0.1, max_subsets=50, seed=3)
    b = trilaterate(anchors, z, 0.1, max_subsets=50, seed=3)
    assert a.ok and not a.inliers[:5].any() and a.inliers[5:].sum() >= 24
    np.testing.assert_array_equal(a.position, b.position)


def test_too_few():
    res = trilaterate(SQUARE[:2], [10.0, 20.0], 0.1)
    assert res.status == "too_few" and "3 ranges are needed, got 2" in res.reason
    assert np.isnan(res.position).all()
    res = triangulate_bearings(SQUARE[:1], [0.3], 0.01)
    assert res.status == "too_few" and "2 bearings" in res.reason


def test_collinear_and_near_collinear_anchors_are_degenerate():
    p = np.array([10.0, 7.0])
    line = np.array([[0.0, 0.0], [10.0, 0.0], [25.0, 0.0], [40.0, 0.0]])
    res = trilaterate(line, ranges_to(line, p), 0.1)
    assert res.status == "degenerate" and "collinear" in res.reason and np.isnan(res.position).all()
    # 1 cm off the line over 40 m: the mirror point fits within the noise
    near = line + np.array([[0, 0], [0, 0.01], [0, -0.01], [0, 0]])
    res = trilaterate(near, ranges_to(near, p) + [0.05, -0.05, 0.02, 0.0], 0.1)
    assert res.status == "degenerate" and "ambiguous" in res.reason
    # the same line with 1 mm ranges and a vehicle far from it is determined...
    res = trilaterate(near + [[0, 0], [0, 5], [0, -5], [0, 0]], ranges_to(near + [[0, 0], [0, 5], [0, -5], [0, 0]], p),
                      0.001)
    assert res.ok
    # ...but a vehicle on the anchors' line has huge GDOP
    p_on = np.array([60.0, 0.02])
    tri = np.array([[0.0, 0.0], [20.0, 0.05], [40.0, -0.05]])
    res = trilaterate(tri, ranges_to(tri, p_on), 0.01)
    assert res.status == "degenerate" and "GDOP" in res.reason and res.gdop > 100


def test_parallel_bearings_are_degenerate():
    anchors = np.array([[10.0, 0.0], [20.0, 0.0], [30.0, 0.0]])
    res = triangulate_bearings(anchors, [0.0, 0.0, 0.0], 0.01)  # vehicle on the anchors' line
    assert res.status == "degenerate" and "parallel" in res.reason
    # lines that cross behind the vehicle
    res = triangulate_bearings(np.array([[10.0, 0.0], [0.0, 10.0]]), [np.pi, -np.pi / 2], 0.01)
    assert res.status == "degenerate" and "points away" in res.reason


def test_did_not_converge_is_reported():
    rng = np.random.default_rng(8)
    z = ranges_to(SQUARE, [15.0, 10.0]) + rng.standard_normal(5)
    res = trilaterate(SQUARE, z, 1.0, max_iterations=1, reject_outliers=False)
    assert res.status == "did_not_converge" and "max_iterations = 1" in res.reason


@pytest.mark.parametrize("kwargs, match", [
    (dict(anchors=[[0, 0], [1, np.nan], [2, 3]]), r"anchors\[\(1, 1\)\] = nan"),
    (dict(ranges=[1.0, -2.0, 3.0]), r"ranges\[1\] = -2"),
    (dict(ranges=[1.0, np.inf, 3.0]), r"ranges\[1\] = inf"),
    (dict(ranges=[1.0, 2.0]), r"ranges must have shape \(3,\)"),
    (dict(sigmas=[0.1, 0.0, 0.1]), r"sigmas\[1\] = 0"),
    (dict(sigmas=[0.1, 0.1]), r"sigmas must have shape"),
    (dict(anchors=[[0, 0, 0]]), r"anchors must have shape \(N, 2\)"),
    (dict(outlier_threshold=-1), "outlier_threshold = -1"),
    (dict(seed=-1), "seed must be"),
    (dict(profile_probability=1.0), "profile_probability = 1"),
    (dict(profile_probability=-0.1), "profile_probability = -0.1"),
])
def test_bad_input_names_the_value(kwargs, match):
    args = dict(anchors=[[0, 0], [10, 0], [0, 10]], ranges=[5.0, 7.0, 8.0], sigmas=0.1)
    args.update(kwargs)
    a, r, s = args.pop("anchors"), args.pop("ranges"), args.pop("sigmas")
    with pytest.raises(ValueError, match=match):
        trilaterate(a, r, s, **args)


# Three anchors nearly in line with the vehicle, the first 1.2–2.2 m from it (world 23's landmarks
# 18–20 seen from its P1): the ranges' cost has a curved valley across that line.
THIN = np.array([[81.7, 41.6], [85.0, 51.1], [90.7, 59.8]])
CHI2_99 = -2.0 * np.log(0.01)  # χ²₂ at 0.99


def _profile_rise(anchors, z, sig, p, cost0, point, other, span):
    """Reference: the cost minimised over point + t·other, |t| ≤ span (2001-point grid, then a
    bounded scalar minimisation around the best), less cost0."""
    def cost(t):
        q = point + t * other
        return float(np.sum(((z - np.linalg.norm(anchors - q, axis=1)) / sig) ** 2))
    ts = np.linspace(-span, span, 2001)
    best = ts[np.argmin([cost(t) for t in ts])]
    h = 2 * span / 2000
    res = optimize.minimize_scalar(cost, bounds=(best - h, best + h), method="bounded", options={"xatol": 1e-12})
    return min(res.fun, cost(best)) - cost0


def test_profile_widening_makes_a_curved_valley_consistent():
    """Monte Carlo: the linear covariance puts > 8 % of the fixes outside its 99 % ellipse here;
    widened to the profile, < 3 %.  The position itself is the same."""
    rng = np.random.default_rng(11)
    for p in ([81.3, 40.1], [80.9, 39.6]):
        p = np.asarray(p)
        r0, sig = ranges_to(THIN, p), np.full(3, 0.05)
        out_lin, out_wid, n = 0, 0, 0
        for _ in range(1500):
            z = r0 + sig * rng.standard_normal(3)
            wid, lin = trilaterate(THIN, z, sig), trilaterate(THIN, z, sig, profile_probability=0)
            if not wid.ok or wid.chi2 > stats.chi2.ppf(0.99, 1):
                continue
            np.testing.assert_array_equal(wid.position, lin.position)
            e = wid.position - p
            out_lin += e @ np.linalg.solve(lin.covariance, e) > CHI2_99
            out_wid += e @ np.linalg.solve(wid.covariance, e) > CHI2_99
            n += 1
        assert n > 1000
        assert out_lin / n > 0.08 and out_wid / n < 0.03, (p, out_lin / n, out_wid / n)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(3, 6), st.sampled_from(["spread", "thin", "close"]))
def test_profile_widening_only_widens_along_the_linear_axes(seed, n, shape):
    """Generated geometries (well spread, anchors nearly in line with the position, an anchor
    within 2 m): the widened covariance keeps the linear one's eigenvectors and never narrows it.
    An axis along which the reference profile rises by less than χ²₂(0.99)/1.1 at the linear
    contour is widened; one along which it rises by more is left as it is, unless the other axis
    was widened (a later round probes from the wider contour)."""
    rng = np.random.default_rng(seed)
    p = rng.uniform(-20, 20, 2)
    if shape == "spread":
        anchors = p + rng.uniform(8, 30, n)[:, None] * np.c_[np.cos(a := rng.uniform(0, 2 * np.pi, n)), np.sin(a)]
    else:
        d = rng.uniform(0, 2 * np.pi)
        along = rng.uniform(1.2 if shape == "close" else 5, 30, n)
        ang = d + rng.uniform(-0.15, 0.15, n)
        anchors = p + along[:, None] * np.c_[np.cos(ang), np.sin(ang)]
    sig = np.full(n, rng.uniform(0.02, 0.3))
    z = np.abs(ranges_to(anchors, p) + sig * rng.standard_normal(n))
    wid = trilaterate(anchors, z, sig, reject_outliers=False)
    lin = trilaterate(anchors, z, sig, reject_outliers=False, profile_probability=0)
    assert wid.status == lin.status
    if not wid.ok:
        return
    lam, V = np.linalg.eigh(lin.covariance)
    lam_w = np.diag(V.T @ wid.covariance @ V)
    np.testing.assert_allclose(V.T @ wid.covariance @ V, np.diag(lam_w), atol=1e-9 * lam_w.max())
    assert np.all(lam_w >= lam * (1 - 1e-9))
    cost0 = float(np.sum(((z - ranges_to(anchors, wid.position)) / sig) ** 2))
    for j in range(2):
        rise = min(_profile_rise(anchors, z, sig, wid.position, cost0, wid.position + s * np.sqrt(CHI2_99 * lam[j]) * V[:, j],
                                 V[:, 1 - j], 2 * np.sqrt(CHI2_99 * lam[1 - j])) for s in (-1, 1))
        threshold = CHI2_99 / 1.1
        if abs(rise / threshold - 1) < 0.03:
            continue  # on the boundary: the stopping rule's 1 % and the search's grid decide
        if rise < threshold:
            assert lam_w[j] > lam[j] * 1.01, (j, rise)  # the first round widens it
        else:
            # left as it is, unless a later round (from the other axis's widened contour) widened it
            assert lam_w[j] <= lam[j] * (1 + 1e-12) or lam_w[1 - j] > lam[1 - j] * 1.01, (j, rise)


def test_horizontal_range_feeds_2d_trilateration_of_3d_landmarks():
    """Landmarks at heights, camera at 1.5 m: slant ranges → horizontal ranges → exact 2D fix."""
    heights = np.array([4.0, 0.5, 2.0, 8.0, 1.0])
    cam_h = 1.5
    p = np.array([14.0, 11.0])
    slant = np.sqrt(ranges_to(SQUARE, p) ** 2 + (heights - cam_h) ** 2)
    h, sh = horizontal_range(slant, heights, cam_h, sigma=0.1)
    np.testing.assert_allclose(h, ranges_to(SQUARE, p), rtol=1e-12)
    np.testing.assert_allclose(sh, 0.1 * slant / h)
    np.testing.assert_allclose(trilaterate(SQUARE, h, sh).position, p, atol=1e-9)
    assert horizontal_range(1.0, 3.0, 1.0) == 0.0  # noisy slant shorter than the height difference
    with pytest.raises(ValueError, match="slant_range"):
        horizontal_range(np.nan, 1.0)


@settings(max_examples=200, deadline=None)
@given(ids=st.lists(st.integers(-3, 6), max_size=9))
def test_repeated_landmarks_marks_every_range_whose_id_another_one_has(ids):
    """The core's rule for a landmark seen twice in one frame (both pipelines
    call it): brute force over the ids, the empty frame and one id included."""
    from safenav import _core

    assert _core.repeated_landmarks(ids) == [ids.count(i) > 1 for i in ids]

"""Calibration statistics of the belief against Monte Carlo (safenav.belief:
arc_position, sigma_calibration, pool_calibrations, clopper_pearson;
bench/bench_certified.py).

References: the arc position against a brute-force nearest point on a dense
sampling of the polyline; the per-bin RMS errors against a direct loop over
samples and stages; the Clopper–Pearson bounds against their definition
through the binomial tail and scipy's exact one-sided interval."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import stats

from safenav import _core
from safenav import planning as P
from safenav.belief import arc_position, clopper_pearson, pool_calibrations, propagate_belief, sigma_calibration

PATH = np.array([[5.0, 5.0], [30.0, 5.0], [30.0, 25.0], [10.0, 35.0]])


def test_arc_position_is_the_nearest_point_of_a_dense_sampling():
    rng = np.random.default_rng(3)
    pts = rng.uniform([0.0, 0.0], [40.0, 40.0], (300, 2))
    legs = np.diff(PATH, axis=0)
    s0 = np.r_[0.0, np.cumsum(np.hypot(*legs.T))]
    t = np.linspace(0.0, 1.0, 4001)
    dense = np.vstack([PATH[i] + t[:, None] * legs[i] for i in range(len(legs))])
    dense_s = np.concatenate([s0[i] + t * np.hypot(*legs[i]) for i in range(len(legs))])
    got = arc_position(PATH, pts)
    for p, s in zip(pts, got):
        d = np.hypot(*(dense - p).T)
        near = dense_s[d <= d.min() + 1e-9]
        assert np.min(np.abs(near - s)) < 0.02          # the dense grid's spacing is below 0.01 m
    assert arc_position(PATH, PATH) == pytest.approx(s0)


def _all_legs(path, points):
    """The nearest point over every leg, in leg order (the first of equal
    distances): the search arc_position prunes."""
    a, d = path[:-1], np.diff(path, axis=0)
    s0 = np.r_[0.0, np.cumsum(np.hypot(*d.T))]
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    t = np.clip(np.einsum("mij,ij->mi", points[:, None, :] - a[None], d) / dd, 0.0, 1.0)
    gap = points[:, None, :] - (a[None] + t[..., None] * d[None])
    leg = np.argmin(np.einsum("mij,mij->mi", gap, gap), axis=1)
    return s0[leg] + t[np.arange(len(points)), leg] * np.sqrt(dd[leg])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), legs=st.integers(65, 400), step=st.sampled_from([0.0, 0.01, 0.1, 1.0]),
       grid=st.booleans(), far=st.sampled_from([0.0, 10.0, 1e6]))
def test_arc_position_on_a_long_polyline_is_the_all_legs_search(seed, legs, step, grid, far):
    """A long polyline (more than 64 legs: the pruned search) gives the
    all-legs search's arc bit for bit: random walks with zero-length legs,
    legs that double back over each other (ties), points on its vertices and
    midpoints, on a grid, and far away (where the pruning cannot decide)."""
    rng = np.random.default_rng(seed)
    turns = rng.choice([0.0, np.pi / 2, np.pi, -np.pi / 2], size=legs) if grid else rng.uniform(-np.pi, np.pi, legs)
    lengths = rng.choice([0.0, step, 2 * step + 0.5], size=legs)
    heading = np.cumsum(turns)
    path = np.vstack([[0.0, 0.0], np.cumsum(lengths[:, None] * np.c_[np.cos(heading), np.sin(heading)], axis=0)])
    if grid:
        path = np.round(path * 2) / 2
    mids = 0.5 * (path[:-1] + path[1:])
    lo, hi = path.min(axis=0) - 2.0, path.max(axis=0) + 2.0
    pts = np.vstack([path, mids, rng.uniform(lo, hi, (200, 2)), np.round(rng.uniform(lo, hi, (50, 2))),
                     rng.uniform(lo, hi, (20, 2)) + far])
    ref = _all_legs(path, pts)
    np.testing.assert_array_equal(arc_position(path, pts), ref)
    np.testing.assert_array_equal(arc_position(path, pts, all_legs=True), ref)


def test_arc_position_searches_many_far_points_in_bounded_chunks():
    """Points the pruning cannot decide go to the all-legs search a few
    million entries at a time: 3 000 points far off a 4 000-leg polyline
    (about 1 000 per chunk) give the reference's arcs, bit for bit."""
    rng = np.random.default_rng(7)
    heading = np.cumsum(rng.uniform(-0.3, 0.3, 4000))
    path = np.vstack([[0.0, 0.0], np.cumsum(0.1 * np.c_[np.cos(heading), np.sin(heading)], axis=0)])
    pts = rng.uniform(-1.0, 1.0, (3000, 2)) + 1e6
    ref = np.concatenate([_all_legs(path, pts[i:i + 500]) for i in range(0, len(pts), 500)])
    np.testing.assert_array_equal(arc_position(path, pts), ref)


@pytest.mark.parametrize("along, split", [(False, False), (True, False), (True, True)])
def test_sigma_calibration_matches_a_direct_computation(along, split):
    # A start 1.5 m off (σ), landmarks from the second leg on: the strata spread over bins.
    se = _core.SensorSettings()
    se.landmarks = np.array([[34.0, 14.0], [36.0, 20.0], [24.0, 22.0]])
    se.max_range = 15.0
    prof = propagate_belief(PATH, sensors=se, map=P.make_map(upper=(40.0, 40.0)), speed=2.0,
                            start_cov=np.diag([2.25, 2.25, 0.003, 0.002]), deviation_along=along,
                            deviation_split=split)
    rng = np.random.default_rng(5)
    pos = np.asarray(prof.positions)
    truths, estimates = [], []
    for n in (400, 700, 900):                         # trials of different lengths, off the path by up to 1 m
        x = pos[np.sort(rng.integers(0, len(pos), n))] + rng.normal(0, 0.5, (n, 2))
        truths.append(np.c_[x, np.zeros((n, 2))])
        estimates.append(np.c_[x + rng.normal(0, 0.3, (n, 2)), np.zeros((n, 2))])
    cal = sigma_calibration(prof, truths, estimates, bin_m=7.0)
    nb = len(cal.edges) - 1
    assert cal.edges[0] == 0.0 and cal.edges[-1] >= prof.length and np.allclose(np.diff(cal.edges), 7.0)

    def bin_of(s):
        return min(int(s // 7.0), nb - 1)

    # The prediction: each stratum of each stage spread over where its vehicles are, the unscented
    # rule's centre (1/3 of its weight) and ±√3 along its position spread's axes (1/6 each), each
    # point at the arc of its own position.
    w = np.asarray(prof.strata_weight)
    spos = np.asarray(prof.strata_positions).reshape(len(pos), w.shape[1], 2)
    scov = np.asarray(prof.strata_position_cov).reshape(len(pos), w.shape[1], 3)
    assert np.abs(scov).max() > 0.01                     # some strata's vehicles spread over several metres²
    points, weights, sqs = [], [], []
    for k in range(len(pos)):
        for i in range(w.shape[1]):
            lam, vec = np.linalg.eigh([[scov[k, i, 0], scov[k, i, 1]], [scov[k, i, 1], scov[k, i, 2]]])
            for q, share in [(spos[k, i], 1 / 3)] + [(spos[k, i] + sg * np.sqrt(3 * max(lam[a], 0.0)) * vec[:, a], 1 / 6)
                                                     for a in (0, 1) for sg in (1, -1)]:
                points.append(q), weights.append(share * w[k, i]), sqs.append(share * w[k, i] * prof.strata_msq[k, i])
    tr, ns = np.zeros(nb), np.zeros(nb)
    for a, wt, sq_ in zip(arc_position(pos, np.array(points)), weights, sqs):
        tr[bin_of(a)] += sq_
        ns[bin_of(a)] += wt
    sq, n, hit = np.zeros(nb), np.zeros(nb), np.zeros(nb)
    per_sq, per_n = np.zeros((len(truths), nb)), np.zeros((len(truths), nb))
    for i, (x, xh) in enumerate(zip(truths, estimates)):
        seen = set()
        for a, b in zip(x, xh):
            j = bin_of(arc_position(PATH, a[None, :2])[0])
            sq[j] += np.sum((b[:2] - a[:2]) ** 2)
            n[j] += 1
            per_sq[i, j] += np.sum((b[:2] - a[:2]) ** 2)
            per_n[i, j] += 1
            seen.add(j)
        for j in seen:
            hit[j] += 1
    assert np.array_equal(cal.samples, n) and np.array_equal(cal.trials, hit)
    w = np.argmax(per_sq, axis=0)                     # the trial with the largest squared error per bin
    cols = np.arange(nb)
    with np.errstate(invalid="ignore", divide="ignore"):
        assert np.allclose(cal.worst_share, per_sq[w, cols] / sq, equal_nan=True)
        assert np.allclose(cal.observed_without_worst, np.sqrt((sq - per_sq[w, cols]) / (n - per_n[w, cols])),
                           equal_nan=True)
    assert np.nanmax(cal.worst_share) <= 1.0 and np.nanmin(cal.worst_share) >= 1.0 / len(truths) - 1e-12
    with np.errstate(invalid="ignore", divide="ignore"):
        assert np.allclose(cal.predicted, np.sqrt(tr / ns), equal_nan=True)
    # Binned at the nominal stages instead, the strata along the leg would count where they are not.
    stage_bins = np.minimum(arc_position(PATH, pos) // 7.0, nb - 1).astype(int)
    cov = np.asarray(prof.cov_xy)
    at_stages = np.sqrt(np.bincount(stage_bins, cov[:, 0] + cov[:, 3], nb) / np.bincount(stage_bins, minlength=nb))
    assert (np.nanmax(np.abs(cal.predicted / at_stages - 1)) > 0.02) == along
    with np.errstate(invalid="ignore", divide="ignore"):
        assert np.allclose(cal.observed, np.sqrt(sq / n), equal_nan=True)
        assert np.allclose(cal.ratio, np.sqrt(sq / n) / np.sqrt(tr / ns), equal_nan=True)
    # Batches of trials pooled are the one call with all of them, field for field.
    pooled = pool_calibrations([sigma_calibration(prof, truths[:1], estimates[:1], bin_m=7.0),
                                sigma_calibration(prof, truths[1:], estimates[1:], bin_m=7.0)])
    for f in dataclasses.fields(cal):
        np.testing.assert_array_equal(getattr(pooled, f.name), getattr(cal, f.name), err_msg=f.name)
    assert np.array_equal(cal.trial_sq, per_sq) and np.array_equal(cal.trial_steps, per_n)
    with pytest.raises(ValueError, match="calibration 1 has other bins"):
        pool_calibrations([cal, sigma_calibration(prof, truths, estimates, bin_m=5.0)])
    with pytest.raises(ValueError, match="no calibrations"):
        pool_calibrations([])
    with pytest.raises(ValueError, match="bin_m = 0"):
        sigma_calibration(prof, truths, estimates, bin_m=0)
    with pytest.raises(ValueError, match="trial 0"):
        sigma_calibration(prof, truths[:1], [estimates[0][:-1]])


@pytest.mark.parametrize("along", [False, True])
@pytest.mark.parametrize("split", [False, True])
def test_strata_are_where_their_error_puts_them(along, split):
    """BeliefProfile.strata_*: a blind stretch, so the strata stay one
    Gaussian and are stratified anew from the previous stage's P each step.
    Their weights sum to 1 and their second moments average to the reported
    trace P_xy.  Their vehicles' offsets from the nominal position (each
    stratum's mean offset, and its own spread ``strata_position_cov``) have
    mean 0 and second moment n n^T (n^T P_xy n), n the leg's normal: the
    lateral part of the error (the law of total variance; the unscented
    transform is exact where the position is linear in the error).  With
    the along-track axis too, since a vehicle's progress keeps to the
    nominal's and only its estimate runs ahead (on a straight path, away
    from its ends).  At the Gauss–Hermite nodes the lateral error is all in
    the strata's means, so each stratum's own spread is 0; the cells carry
    their share of it within.  Without the mixture there are none."""
    se = _core.SensorSettings()
    se.landmarks = np.array([[500.0, 500.0]])
    path = np.array([[5.0, 5.0], [35.0, 5.0]]) if along else PATH
    kw = dict(sensors=se, map=P.make_map(upper=(40.0, 40.0)), speed=2.0,
              start_cov=np.diag([0.4, 0.1, 0.003, 0.002]), deviation_split=split)
    prof = propagate_belief(path, deviation_along=along, **kw)
    w = np.asarray(prof.strata_weight)
    assert w.shape == (len(prof.positions), 27 if along else 9) and np.all(w == w[0])
    w = w[0]
    assert np.isclose(w.sum(), 1.0, rtol=1e-14)
    pos = np.asarray(prof.positions)
    cov = np.asarray(prof.cov_xy).reshape(-1, 2, 2)
    d = np.asarray(prof.strata_positions).reshape(len(pos), len(w), 2) - pos[:, None, :]
    c = np.asarray(prof.strata_position_cov).reshape(len(pos), len(w), 3)
    within = np.stack([np.stack([c[..., 0], c[..., 1]], -1), np.stack([c[..., 1], c[..., 2]], -1)], -2)
    np.testing.assert_array_equal(d[0], 0.0)
    np.testing.assert_array_equal(c[0], 0.0)
    msq = np.asarray(prof.strata_msq)
    np.testing.assert_allclose(msq @ w, np.trace(cov, axis1=1, axis2=2), rtol=1e-12)
    h = np.asarray(prof.headings)
    s = arc_position(pos, pos)
    for k in range(1, len(pos)):
        if along and not 5.0 < s[k] < s[-1] - 5.0:
            continue
        np.testing.assert_allclose(w @ d[k], 0.0, atol=1e-12)
        n = np.array([-np.sin(h[k]), np.cos(h[k])])
        lateral = np.outer(n, n) * (n @ cov[k - 1] @ n)
        second = np.einsum("i,ij,ik->jk", w, d[k], d[k])
        inside = np.einsum("i,ijk->jk", w, within[k])
        np.testing.assert_allclose(second + inside, lateral, rtol=1e-9, atol=1e-12)
        if split:
            assert np.trace(inside) > 0.05 * np.trace(lateral)
        else:
            np.testing.assert_allclose(within[k], 0.0, atol=1e-12)
    assert len(np.asarray(propagate_belief(PATH, deviation_mixture=False, **kw).strata_weight)) == 0


def test_strata_spread_their_vehicles_round_a_turn_as_their_errors_do():
    """At a turn a vehicle's true position is not linear in its error: its
    estimate runs ahead by the error's along-track part, so it is at the
    nominal pose that much further along the path, moved by minus its
    error, and a lateral offset becomes an offset along the next leg.  A
    blind 90° turn with the start's σ of 1 m: per stage within 2.5 m of the
    corner, the arcs of the strata's vehicles (each stratum spread by
    ``strata_position_cov``, as sigma_calibration bins it) against 20 000
    errors drawn from the mixture's covariance and put where that rule puts
    them.  Spread, the two distributions' Wasserstein distance is half of
    what it is with each stratum at its mean position."""
    from scipy.stats import wasserstein_distance
    from safenav.belief import _SPREAD_WEIGHTS, _spread_points

    se = _core.SensorSettings()
    se.landmarks = np.array([[500.0, 500.0]])
    path = np.array([[5.0, 5.0], [25.0, 5.0], [25.0, 25.0]])
    prof = propagate_belief(path, sensors=se, map=P.make_map(upper=(40.0, 40.0)), speed=2.0,
                            start_cov=np.diag([1.0, 1.0, 0.003, 0.002]), deviation_along=True)
    pos, h = np.asarray(prof.positions), np.asarray(prof.headings)
    w = np.asarray(prof.strata_weight)
    at = np.asarray(prof.strata_positions).reshape(len(pos), w.shape[1], 2)
    spread = np.asarray(prof.strata_position_cov).reshape(len(pos), w.shape[1], 3)
    cov = np.asarray(prof.covariance).reshape(-1, 4, 4)
    s = arc_position(path, pos)
    ends = np.r_[0.0, np.cumsum(np.hypot(*np.diff(path, axis=0).T))]

    def along(a):                                     # the path's point at arc a
        a = np.clip(a, 0.0, ends[-1])
        i = np.clip(np.searchsorted(ends, a, side="right") - 1, 0, len(path) - 2)
        return path[i] + ((a - ends[i]) / np.diff(ends)[i])[:, None] * (path[i + 1] - path[i])

    rng = np.random.default_rng(0)
    spread_d, mean_d = [], []
    for k in np.flatnonzero(np.abs(s - 20.0) < 2.5):
        e = rng.multivariate_normal(np.zeros(4), cov[k - 1], 20_000)
        ref = arc_position(path, along(s[k] + e[:, :2] @ [np.cos(h[k]), np.sin(h[k])]) - e[:, :2])
        pts = _spread_points(at[k], spread[k]).reshape(-1, 2)
        spread_d.append(wasserstein_distance(arc_position(path, pts), ref, np.outer(w[k], _SPREAD_WEIGHTS).ravel()))
        mean_d.append(wasserstein_distance(arc_position(path, at[k]), ref, w[k]))
    assert len(spread_d) > 10
    assert np.mean(spread_d) < 0.15 and np.mean(spread_d) < 0.6 * np.mean(mean_d), (np.mean(spread_d), np.mean(mean_d))


@pytest.mark.parametrize("k, n", [(0, 10), (0, 100000), (3, 50), (7, 7), (1, 2)])
def test_clopper_pearson_bounds_are_the_binomial_tail_quantiles(k, n):
    lo, hi = clopper_pearson(k, n)
    # definition: the upper bound is the rate at which k or fewer events have probability 5 %,
    # the lower bound the rate at which k or more have probability 5 %
    if k < n:
        assert stats.binom.cdf(k, n, hi) == pytest.approx(0.05, rel=1e-6)
    else:
        assert hi == 1.0
    if k > 0:
        assert stats.binom.sf(k - 1, n, lo) == pytest.approx(0.05, rel=1e-6)
    else:
        assert lo == 0.0
    ci = stats.binomtest(k, n, alternative="less").proportion_ci(0.95, method="exact")
    assert hi == pytest.approx(ci.high, rel=1e-9)
    ci = stats.binomtest(k, n, alternative="greater").proportion_ci(0.95, method="exact")
    assert lo == pytest.approx(ci.low, rel=1e-9, abs=1e-15)
    if k == 0:                                       # the "rule of three": about 3/n for large n
        assert hi == pytest.approx(-np.log(0.05) / n, rel=0.15 if n < 100 else 1e-3)


@pytest.mark.parametrize("k, n, match", [(-1, 5, "k = -1"), (6, 5, "k = 6"), (0, 0, "n = 0"), (1.5, 5, "k = 1.5")])
def test_clopper_pearson_refuses_bad_counts(k, n, match):
    with pytest.raises(ValueError, match=match):
        clopper_pearson(k, n)


def _edge_of_view_world(start_fix: bool):
    """A 140 x 40 m field, path (5, 20) -> (120, 20), and a cluster (50, 35),
    (50, 5), (51, 35.5) in the vehicle's camera (85°, 30 m) from x in
    [25.3, 33.6] but never in the robust camera's (60°, 27 m); with
    ``start_fix`` a cluster ahead of the start gives fixes up to x = 18."""
    from safenav.scenario import Scenario

    lms = [((2, 18), 0), ((2, 22), 0), ((11, 20), 0), ((115, 17), 1), ((115, 23), 1), ((130, 20), 1),
           ((50, 35), 2), ((50, 5), 2), ((51, 35.5), 2)]
    if start_fix:
        lms += [((15, 16), 3), ((15, 24), 3), ((18, 20), 3)]
    return Scenario.from_dict({
        "name": "edge of view", "world": {
            "field": {"x_min": 0.0, "y_min": 0.0, "x_max": 140.0, "y_max": 40.0},
            "landmarks": [{"id": i, "position": [float(x), float(y)], "class": "tower", "cluster": c}
                          for i, ((x, y), c) in enumerate(lms)]},
        "path_types": [{"name": "A", "clusters": [0, 1]}]})


def test_the_expected_belief_predicts_the_fixes_and_errors_the_vehicle_gets():
    """The cluster at the edge of the vehicle's view (_edge_of_view_world):
    a vehicle that tracks its path (fixes up to x = 18) measures a fix at
    nearly every step from x = 26 to 32, as the expected belief (the
    default: the vehicle's camera) predicts, and its Monte Carlo RMS error
    matches the expected belief's within ±25 % in every 10 m bin, while the
    robust belief's is up to five times too large after the cluster (the
    low bins of the certified-missions benchmark).  A vehicle that reaches
    the cluster after 20 m blind from a 1 m start turns hard on its first
    fix and loses the cluster in about half of the steps: why the planner
    and the certificate keep the robust camera."""
    from safenav import navigation as nav
    from safenav import runner
    from safenav.belief import robust_sight
    from safenav.certify import mission_inputs

    path = np.array([[5.0, 20.0], [120.0, 20.0]])
    shares = {}
    for start_fix in (True, False):
        sc = _edge_of_view_world(start_fix)
        kw = mission_inputs(sc, path)
        expected = propagate_belief(path, **kw)
        robust = propagate_belief(path, **robust_sight(), **kw)
        x = np.asarray(expected.positions)[:, 0]
        assert (np.asarray(expected.landmarks)[(x > 26.0) & (x < 33.0)] == 3).all()
        assert (np.asarray(robust.landmarks)[(x > 25.0) & (x < 80.0)] == 0).all()
        navigator = nav.make_navigator(sc, path, record=True)
        runs = [navigator.run(int(s)) for s in runner.trial_seeds(1, 0, 30)]
        truths = [np.asarray(r.truth) for r in runs]
        fixed = np.concatenate([np.isfinite(np.asarray(r.measured)[:, 0])[(t[:, 0] > 26.0) & (t[:, 0] < 32.0)]
                                for r, t in zip(runs, truths)])
        assert fixed.size > 1000
        shares[start_fix] = fixed.mean()
        if start_fix:
            estimates = [np.asarray(r.estimate) for r in runs]
            cal = sigma_calibration(expected, truths, estimates, bin_m=10.0)
            cal_r = sigma_calibration(robust, truths, estimates, bin_m=10.0)
            assert np.all(np.abs(cal.ratio - 1.0) <= 0.25), cal.ratio
            after = (cal.edges[:-1] >= 30.0) & (cal.edges[:-1] < 60.0)   # dead reckoning from the cluster's fixes
            assert np.all(cal_r.ratio[after] < 0.7), cal_r.ratio
    assert shares[True] > 0.9 and shares[False] < 0.8, shares


def test_the_bootstrap_interval_of_the_observed_rms_covers_the_truth_95_percent_of_the_time():
    """SigmaCalibration.observed_low/high: percentile bootstrap over trials.
    Trials of 30 steps each, every step's error 2-D normal with σ = 0.3 and a
    per-trial bias (so steps of a trial are not independent): the bounds hold
    the true RMS at close to their 95 %, and the same trials give the same bounds."""
    from safenav.belief import _bootstrap_rms
    rng = np.random.default_rng(11)
    true_rms = np.sqrt(2 * 0.3 ** 2 + 2 * 0.2 ** 2)
    covered = 0
    for _ in range(300):
        bias = rng.normal(0.0, 0.2, (60, 1, 2))
        e = bias + rng.normal(0.0, 0.3, (60, 30, 2))
        per_sq = np.sum(e ** 2, axis=(1, 2))[:, None]
        per_n = np.full((60, 1), 30.0)
        lo, hi = _bootstrap_rms(per_sq, per_n)
        obs = np.sqrt(per_sq.sum() / per_n.sum())
        assert lo[0] <= obs <= hi[0]
        covered += lo[0] <= true_rms <= hi[0]
    assert 0.89 <= covered / 300 <= 0.99, covered
    again = _bootstrap_rms(per_sq, per_n)
    assert np.array_equal(again[0], lo) and np.array_equal(again[1], hi)
    # One trial far off: the interval reaches from the rest's RMS to well above the whole's.
    per_sq[0] += 900.0
    lo, hi = _bootstrap_rms(per_sq, per_n)
    whole = np.sqrt(per_sq.sum() / per_n.sum())
    assert lo[0] < 0.6 * whole and hi[0] > 1.2 * whole

"""The belief with a fix that may not arrive: dropouts and faulty ranges
(docs/belief_planning.md, "A fix that may not arrive" and "Start").

References: FilterPy's KalmanFilter in two branches per stage, the fix's odds
by enumeration of which ranges survive and are sound, and the exact mean of
the filter's covariance over all arrival sequences (Sinopoli et al. 2004)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from safenav import _core
from safenav import planning as P
from safenav.belief import start_covariance
from test_belief import SPEED, _visible, kalman, np_jacobians, open_map, profile_cov, sensors


def _fix_odds_brute_force(se, n_seen, attempts):
    """A fix's odds in one belief step of ``attempts`` fix attempts, by
    enumeration of which ranges survive and are sound (FixModel.RANGES: a fix
    needs >= max(3, min_landmarks) sound ranges) or, for FixModel.PROFILE,
    from the profile's dropout: (p = P(at least one fix), the expected count
    of each measurement given one)."""
    import itertools

    if se.fix_model == _core.FixModel.RANGES:
        f = se.faults
        q = (1 - f.dropout_probability) * (1 - f.outlier_probability) * (1 - f.misassociation_probability)
        need = max(3, se.min_landmarks)
        fix = in_fix = 0.0
        for sound in itertools.product([0, 1], repeat=n_seen):
            pr = q ** sum(sound) * (1 - q) ** (n_seen - sum(sound))
            if sum(sound) >= need:
                fix += pr
                in_fix += pr * sound[0]      # the first range (all are alike)
    else:
        fix = in_fix = 1 - se.position.dropout_probability
    p = 1 - (1 - fix) ** attempts
    return p, (attempts * in_fix / p if p > 0 else 0.0)


def _reference_intermittent(prof, bmm, se, P0, checker):
    """The covariance recursion with a fix that may not arrive: per stage,
    FilterPy's predict, then two branches, with the fix (its R divided by
    the count given a fix) and the IMU, and with the IMU alone; P is their
    mean weighted by the fix's probability (Sinopoli et al. 2004)."""
    import copy

    kf = kalman.KalmanFilter(dim_x=4, dim_z=1)
    kf.x, kf.P = np.zeros((4, 1)), P0.copy()
    sig2 = np.array([bmm.position_noise, bmm.position_noise, bmm.speed_noise, bmm.heading_noise]) ** 2
    lms = np.asarray(se.landmarks)
    ranges = se.fix_model == _core.FixModel.RANGES
    imu_H, imu_R = np.array([[0.0, 0, 1, 0], [0, 0, 0, 1]]), np.diag([se.imu_speed_std ** 2, se.imu_heading_std ** 2])
    out = [kf.P.copy()]
    for k in range(1, len(prof.time)):
        n = (prof.time[k] - prof.time[k - 1]) / bmm.dt
        p_k = prof.positions[k]
        F, G = np_jacobians(SPEED, prof.headings[k], prof.time[k] - prof.time[k - 1])
        kf.F, kf.Q = F, G @ np.diag(sig2 * n) @ G.T
        kf.predict()
        seen = [i for i in range(len(lms)) if _visible(se, lms[i], p_k, prof.headings[k], checker)]
        can = len(seen) >= (max(3, se.min_landmarks) if ranges else se.min_landmarks)
        p, count = _fix_odds_brute_force(se, len(seen), n / se.position_every) if can else (0.0, 0.0)
        with_fix, without = copy.deepcopy(kf), copy.deepcopy(kf)
        if p > 0 and not ranges:
            with_fix.update(np.zeros((2, 1)), R=se.position.reported_cov() / count, H=np.c_[np.eye(2), np.zeros((2, 2))])
        for i in seen if p > 0 and ranges else ():
            d = lms[i] - p_k
            with_fix.update(np.zeros((1, 1)), R=np.array([[se.range_std ** 2 / count]]),
                            H=np.array([[-d[0], -d[1], 0.0, 0.0]]) / np.hypot(*d))
        for branch in (with_fix, without):
            branch.update(np.zeros((2, 1)), R=imu_R / n, H=imu_H)
        kf.P = p * with_fix.P + (1 - p) * without.P
        out.append(kf.P.copy())
    return np.array(out)


@pytest.mark.parametrize("n_lm, faults", [(3, (0.2, 0.0, 0.0)), (4, (0.2, 0.05, 0.01)), (5, (0.2, 0.05, 0.01)),
                                          (0, None)])
def test_a_fix_that_may_not_arrive_is_the_mean_of_its_two_branches(n_lm, faults):
    """Dropouts and faulty ranges: a step's fix arrives with probability p
    (FixModel.RANGES: >= 3 of the ranges in view survive and are sound, by
    enumeration; FixModel.PROFILE: 1 - dropout), and the belief is the mean
    of the branch with it and the branch without, against FilterPy.  The
    case n_lm = 0 is the profile fix with its own dropout."""
    ranges = faults is not None
    lms = np.array([[20.0 + 6 * np.cos(a), 20.0 + 6 * np.sin(a)] for a in np.linspace(0, 2 * np.pi, max(n_lm, 3) + 1)[:-1]])
    path = np.array([[14.0, 19.0], [22.0, 19.0]])      # 40 steps of the BMM's dt, blind for the first 10
    se = sensors(lms, ranges=ranges, occlusion=False, max_range=7.5)
    if ranges:
        se.faults.dropout_probability, se.faults.outlier_probability, se.faults.misassociation_probability = faults
    else:
        se.position.dropout_probability = 0.3
    m, bmm = open_map(upper=(60, 40)), _core.BmmParams()
    P0 = np.diag([1.0, 1.0, 1e-2, 1e-2])
    prof = P.propagate_belief(path, sensors=se, map=m, bmm=bmm, start_cov=P0, speed=SPEED, deviation_mixture=False)
    assert np.allclose(np.diff(prof.time), bmm.dt)
    landmarks = np.asarray(prof.landmarks)
    assert landmarks[0] < 3 and (landmarks >= 3).sum() > 10    # a blind start, then the fix may come
    ref = _reference_intermittent(prof, bmm, se, P0, _core.ObstacleChecker(m))
    np.testing.assert_allclose(profile_cov(prof), ref, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("faults", [None, (0.2, 0.0, 0.0), (0.2, 0.05, 0.01), (0.0, 0.0, 0.0)])
def test_the_start_prior_is_the_mean_over_the_first_fix(faults):
    """The navigation loop starts from its first fix's covariance when it
    gets one, else from a 1 m σ; the expected prior is their mean weighted by
    the first fix's odds (enumerated).  A range fix's covariance is the
    trilateration's, (Σ c u uᵀ / σ²)⁻¹ over the unit vectors u to the
    landmarks in view, c the count of each range given a fix."""
    lms = np.array([[20.0 + 6 * np.cos(a), 20.0 + 6 * np.sin(a)] for a in np.linspace(0, 2 * np.pi, 5)[:-1]])
    start = np.array([21.0, 19.5])
    se = sensors(lms, ranges=faults is not None, occlusion=False)
    if faults is None:
        se.position.dropout_probability = 0.3
    else:
        se.faults.dropout_probability, se.faults.outlier_probability, se.faults.misassociation_probability = faults
    m = open_map(upper=(60, 40))
    got = start_covariance(se, m, start, 0.3)
    p, count = _fix_odds_brute_force(se, len(lms), 1.0)
    if faults is None:
        R = se.position.reported_cov()
    else:
        u = (lms - start) / np.linalg.norm(lms - start, axis=1)[:, None]
        R = np.linalg.inv(count * u.T @ u / se.range_std ** 2)
    fix, none = np.diag([0.0, 0.0, se.imu_speed_std ** 2, se.imu_heading_std ** 2]), None
    fix[:2, :2] = R
    none = fix.copy()
    none[:2, :2] = np.eye(2)
    np.testing.assert_allclose(got, p * fix + (1 - p) * none, rtol=1e-12, atol=1e-15)
    assert (p == 1.0) == (faults == (0.0, 0.0, 0.0))
    # Without a landmark in view (heading away from them, a 90° camera) there is no fix.
    se.field_of_view = np.pi / 2
    np.testing.assert_allclose(start_covariance(se, m, np.array([40.0, 20.0]), 0.0)[:2, :2], np.eye(2))


@pytest.mark.parametrize("std", [(0.0142, 0.039), (0.6, 0.2)])
def test_the_start_prior_with_the_gate_holds_the_starts_whose_fix_the_loop_disputes(std):
    """With the gate on the loop tests the start fix z against the rough
    start s ~ N(truth, σ₀²I) (navigation.cpp, Trial::dispute_start_fix) and
    starts from (z + s)/2 where they fail it: the fix's part of the prior is
    g R + (1 − g) E[eeᵀ | disputed], checked against that rule drawn."""
    lms = np.array([[20.0 + 6 * np.cos(a), 20.0 + 6 * np.sin(a)] for a in np.linspace(0, 2 * np.pi, 5)[:-1]])
    start, g = np.array([21.0, 19.5]), 0.99
    se = sensors(lms, occlusion=False)
    se.position.std = np.asarray(std)
    m = open_map(upper=(60, 40))
    base = start_covariance(se, m, start, 0.3)
    got = start_covariance(se, m, start, 0.3, g)
    R, s0 = base[:2, :2], max(1.0, max(std))
    np.testing.assert_array_equal(got[2:], base[2:])
    E = (got[:2, :2] - g * R) / (1.0 - g)
    rng = np.random.default_rng(5)
    n = 1_000_000
    a = rng.multivariate_normal(np.zeros(2), R, n)
    b = s0 * rng.standard_normal((n, 2))
    d = a - b
    q = np.einsum("ij,jk,ik->i", d, np.linalg.inv(R + s0 ** 2 * np.eye(2)), d)
    out = q > -2.0 * np.log1p(-g)
    assert abs(out.mean() - (1 - g)) < 4 * np.sqrt(g * (1 - g) / n)
    e = 0.5 * (a + b)[out]
    np.testing.assert_allclose(E, e.T @ e / len(e), rtol=0.05, atol=0.02 * np.trace(E))
    # No fix at the start (heading away from the landmarks, a 90° camera): nothing to dispute.
    se.field_of_view = np.pi / 2
    np.testing.assert_array_equal(start_covariance(se, m, np.array([40.0, 20.0]), 0.0, g),
                                  start_covariance(se, m, np.array([40.0, 20.0]), 0.0))
    for bad in (1.0, -0.1, float("nan")):
        with pytest.raises(ValueError, match="gate_probability"):
            start_covariance(se, m, start, 0.3, bad)


def test_an_intermittent_fix_bounds_the_expected_covariance_from_above():
    """Sinopoli et al. 2004: with fixes that arrive at random, the mean of
    the filter's covariance over the arrival sequences is concave in the
    prior, so the recursion of the mean (the belief's) bounds it from above,
    and equals it one step after a certain prior.  Checked against the exact
    mean over all 2^K arrival sequences of a FilterPy filter, and against
    the averaged-information model, which bounds it from below and misses
    the vehicles still waiting for their first fix."""
    import copy
    import itertools

    lms = np.array([[20.0 + 6 * np.cos(a), 20.0 + 6 * np.sin(a)] for a in np.linspace(0, 2 * np.pi, 4)[:-1]])
    path = np.array([[17.0, 19.0], [19.0, 19.0]])        # every step with the three in view
    se = sensors(lms, occlusion=False, max_range=12.0)
    se.position.dropout_probability = 0.5
    m, bmm = open_map(upper=(60, 40)), _core.BmmParams()
    P0 = np.diag([1.0, 1.0, 1e-2, 1e-2])
    prof = P.propagate_belief(path, sensors=se, map=m, bmm=bmm, start_cov=P0, speed=SPEED, deviation_mixture=False)
    assert (np.asarray(prof.landmarks) == 3).all()
    belief = profile_cov(prof)
    K = min(len(belief) - 1, 8)
    sig2 = np.array([bmm.position_noise, bmm.position_noise, bmm.speed_noise, bmm.heading_noise]) ** 2
    H_fix, R_fix = np.c_[np.eye(2), np.zeros((2, 2))], se.position.reported_cov()
    imu_H, imu_R = np.array([[0.0, 0, 1, 0], [0, 0, 0, 1]]), np.diag([se.imu_speed_std ** 2, se.imu_heading_std ** 2])

    def run(arrivals, info=1.0):
        kf = kalman.KalmanFilter(dim_x=4, dim_z=2)
        kf.x, kf.P = np.zeros((4, 1)), P0.copy()
        out = []
        for k, a in enumerate(arrivals, start=1):
            F, G = np_jacobians(SPEED, prof.headings[k], bmm.dt)
            kf.F, kf.Q = F, G @ np.diag(sig2) @ G.T
            kf.predict()
            if a:
                kf.update(np.zeros((2, 1)), R=R_fix / info, H=H_fix)
            kf.update(np.zeros((2, 1)), R=imu_R, H=imu_H)
            out.append(copy.deepcopy(kf.P))
        return np.array(out)

    mean = sum(0.5 ** K * run(seq) for seq in itertools.product([0, 1], repeat=K))
    averaged = run([1] * K, info=0.5)
    d = belief[1:K + 1] - mean
    np.testing.assert_allclose(belief[1], mean[0], rtol=1e-9)
    assert np.linalg.eigvalsh(0.5 * (d + d.transpose(0, 2, 1))).min() >= -1e-12
    assert (np.trace(mean[:, :2, :2], axis1=1, axis2=2) > 10 * np.trace(averaged[:, :2, :2], axis1=1, axis2=2)).all()
    # The bound is tight where it matters: half the vehicles have no fix yet after the first step.
    np.testing.assert_allclose(np.trace(belief[1:K + 1, :2, :2], axis1=1, axis2=2),
                               np.trace(mean[:, :2, :2], axis1=1, axis2=2), rtol=0.15)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(d=st.lists(st.floats(0.0, 0.95), min_size=2, max_size=2, unique=True), ranges=st.booleans())
def test_more_dropout_never_predicts_a_smaller_covariance(d, ranges):
    """The two-branch step is monotone in the fix's probability (P_fix ⪯
    P_none, and the Riccati maps are monotone), so a fix that comes more
    rarely gives a larger covariance at every stage, in the psd order."""
    lms = np.array([[20.0 + 6 * np.cos(a), 20.0 + 6 * np.sin(a)] for a in np.linspace(0, 2 * np.pi, 5)[:-1]])
    path = np.array([[14.0, 19.0], [22.0, 19.0], [22.0, 24.0]])
    m, bmm = open_map(upper=(60, 40)), _core.BmmParams()
    P0 = np.diag([1.0, 1.0, 1e-2, 1e-2])
    covs = []
    for dropout in sorted(d):
        se = sensors(lms, ranges=ranges, occlusion=False, max_range=7.5)
        if ranges:
            se.faults.dropout_probability = dropout
        else:
            se.position.dropout_probability = dropout
        covs.append(profile_cov(P.propagate_belief(path, sensors=se, map=m, bmm=bmm, start_cov=P0, speed=SPEED,
                                                   deviation_mixture=False)))
    diff = covs[1] - covs[0]
    scale = np.abs(covs[1]).max(axis=(1, 2))
    assert (np.linalg.eigvalsh(0.5 * (diff + diff.transpose(0, 2, 1))).min(axis=1) >= -1e-9 * scale).all()


def test_unambiguous_share_is_the_localizer_s_acceptance_rate():
    """Model.unambiguous_share, by its specification (test_belief.unambiguous_share),
    against the localizer itself: three landmarks nearly in line (world 37's,
    where the vehicles' window of three in view mostly yields no fix), the
    share of 2 000 noisy range sets (σ 0.05 m) that trilaterate() accepts.
    The normal model of the χ² gap, N(Δ, 4Δ), holds to about 0.03 here."""
    from safenav.vision.localization import trilaterate
    from test_belief import unambiguous_share

    se = sensors([[0.0, 0.0]], ranges=True)
    se.range_std = 0.05
    A = np.array([[152.198, 90.662], [147.784, 76.029], [149.839, 83.246]])
    rng = np.random.default_rng(1)
    shares = []
    triangle = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    for anchors, p in [(A, [159.2, 62.5]), (A, [158.0, 66.0]), (A, [165.0, 55.0]), (A, [155.5, 75.0]),
                       (A, [157.0, 80.0]), (A, [175.0, 85.0]), (triangle, [3.0, 3.0])]:
        p = np.array(p)
        d = np.hypot(*(anchors - p).T)
        u = unambiguous_share(se, anchors, p)
        ok = np.mean([trilaterate(anchors, d + 0.05 * rng.normal(size=3), 0.05).ok for _ in range(2000)])
        assert abs(u - ok) < 0.06, (p, u, ok)
        shares.append(u)
    assert min(shares) < 0.3 and shares[-1] == 1.0      # mostly refused; a spread triangle never


def test_belief_takes_a_range_fix_only_as_often_as_the_trilateration_accepts_it(monkeypatch):
    """FixModel.RANGES past three landmarks nearly in line: the belief's range
    fix arrives with the unambiguous share (intermittent branches, as for a
    dropout), so it equals the branch reference (test_belief's
    reference_covariances) and keeps a larger σ than full fixes would give."""
    from test_belief import reference_covariances, unambiguous_share

    A = np.array([[152.198, 90.662], [147.784, 76.029], [149.839, 83.246]]) - [100.0, 40.0]
    path = np.array([[50.0, 5.0], [60.0, 25.0]])
    se = sensors(A, ranges=True, max_range=40.0)
    se.range_std = 0.05
    bmm = _core.BmmParams()
    m = open_map(upper=(100, 100))
    P0 = np.diag([0.3, 0.3, 0.003, 0.001])
    prof = P.propagate_belief(path, sensors=se, map=m, bmm=bmm, start_cov=P0, speed=SPEED, deviation_mixture=False)
    pos = np.asarray(prof.positions)
    u = np.array([unambiguous_share(se, A, q) for q in pos])
    assert u.min() < 0.01 and u.max() < 0.5                    # every stage's fix is in doubt
    np.testing.assert_allclose(profile_cov(prof), reference_covariances(prof, bmm, se, P0, 0.0,
                                                                        _core.ObstacleChecker(m)),
                               rtol=1e-9, atol=1e-15)
    import test_belief
    monkeypatch.setattr(test_belief, "unambiguous_share", lambda *a: 1.0)
    full = reference_covariances(prof, bmm, se, P0, 0.0, _core.ObstacleChecker(m))
    tr = lambda c: c[:, 0, 0] + c[:, 1, 1]                       # noqa: E731
    assert tr(profile_cov(prof))[-1] > 1.5 * tr(full)[-1]

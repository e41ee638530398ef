"""Belief propagation along a path and its collision probability
(safenav.belief; docs/belief_planning.md).

References: the covariance recursion against FilterPy's KalmanFilter
(predict P = F P F^T + Q, Joseph-form update) driven by an independent numpy
Jacobian of the BMM at the nominal [SafeNav eqs. 7, 11-14]; visibility
against SensorSettings.landmarks_in_view; the collision probability of Patil
et al. against a Monte Carlo of the same linear-Gaussian error dynamics and
against the union bound."""
from __future__ import annotations

import copy
import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import stats

from safenav import _core
from safenav import planning as P
from safenav.vision.localization import trilaterate

kalman = pytest.importorskip("filterpy.kalman")

SPEED = 2.0


def open_map(upper=(60.0, 40.0), polygons=()):
    return P.make_map(upper=upper, polygons=list(polygons))


def sensors(landmarks, *, ranges=False, fov=2 * np.pi, max_range=30.0, occlusion=True, imu=True):
    se = _core.SensorSettings()
    se.landmarks = np.asarray(landmarks, dtype=float).reshape(-1, 2)
    se.field_of_view = fov
    se.max_range = max_range
    se.occlusion = occlusion
    se.imu = imu
    if ranges:
        se.fix_model = _core.FixModel.RANGES
        se.range_std = 0.2
    return se


def np_jacobians(v, theta, dt, tau=0.0):
    """F = df/dx and G = df/d(eps) of the BMM at cruise (v' = v: the speed
    limit binds, dv'/dv = 0) with no heading change [SafeNav eqs. 3, 7, 9]."""
    k = dt / (1.0 + tau)
    c, s = np.cos(theta), np.sin(theta)
    F = np.eye(4)
    F[2, 2] = 0.0
    F[0, 3], F[1, 3] = -k * v * s, k * v * c
    G = np.eye(4)
    G[0, 2], G[1, 2] = k * c, k * s
    G[0, 3], G[1, 3] = -k * v * s, k * v * c
    return F, G


def belief_camera(se, settings=None):
    """The camera the belief sees with, by its specification
    (BeliefSettings.sight_fov_margin, sight_range_fraction): (field of view,
    range) = the vehicle's field of view less the margin, at least 10°,
    unless all round; its range scaled."""
    s = settings if settings is not None else _core.BeliefSettings()
    fov = se.field_of_view
    if fov < 2 * np.pi:
        fov = max(np.deg2rad(10.0), fov - s.sight_fov_margin)
    return fov, se.max_range * s.sight_range_fraction


def reference_covariances(prof, bmm, se, P0, bearing_std=0.0, checker=None, stage=None):
    """FilterPy's KalmanFilter over the profile's stages (ML observations: z = H x).
    ``stage(k)`` -> (F, G, camera heading) of stage k; default: the leg's at cruise (np_jacobians)."""
    kf = kalman.KalmanFilter(dim_x=4, dim_z=1)
    kf.x = np.zeros((4, 1))
    kf.P = P0.copy()
    out = [kf.P.copy()]
    for k in range(1, len(prof.time)):
        _reference_stage(kf, prof, k, prof.positions[k], bmm, se, bearing_std, checker, stage=stage)
        out.append(kf.P.copy())
    return np.array(out)


class _TrackedKF(kalman.KalmanFilter):
    """FilterPy's filter that also keeps T, the product of its updates'
    I - K H since T was last reset: the map of its mean error over a stage."""

    def update(self, z, R=None, H=None):
        super().update(z, R=R, H=H)
        self.T = (np.eye(4) - self.K @ H) @ self.T


def reference_mixture(prof, bmm, se, P0, bearing_std=0.0, checker=None, stage=None, nodes=3, along=False):
    """BeliefSettings.deviation_mixture by its specification: the error
    stratified on (lateral, heading) u = J e (with ``along``: (along the leg,
    lateral, heading)) at the product of nodes-point
    Gauss-Hermite rules z of N(0, I) (numpy's hermegauss; with 3, nodes
    -sqrt(3), 0, sqrt(3) and weights 1/6, 2/3, 1/6): stratum i
    has mean m_i = M J^T L^-T z_i and second moment C + m_i m_i^T, C = M - M
    J^T (J M J^T)^-1 J M, L L^T = J M J^T, M the mixture's second moment.
    One FilterPy filter per stratum: its x is m_i (predict x = F x, update
    with z = 0: x = (I - K H) x), its P the filter's; the vehicles of stratum
    i see from the nominal pose moved by -m_i across the leg (and along it)
    and in heading.
    N_i = second moment - P_i moves as T F N_i F^T T^T (T = prod (I - K H) of
    FilterPy's gains).  The strata are stratified anew before a stage when
    at the previous one all saw the same landmarks and their P agreed within
    1 % (Frobenius).  The mixture per stage: sum_i w_i (P_i + N_i)."""
    x, weights = np.polynomial.hermite_e.hermegauss(nodes)
    weights = weights / np.sqrt(2 * np.pi)
    axes = 3 if along else 2
    z = np.array(list(itertools.product(x, repeat=axes)))
    w = np.array([np.prod(c) for c in itertools.product(weights, repeat=axes)])
    kfs, N = [], [np.zeros((4, 4)) for _ in range(len(w))]
    for _ in range(len(w)):
        kf = _TrackedKF(dim_x=4, dim_z=1)
        kf.x, kf.P = np.zeros((4, 1)), P0.copy()
        kfs.append(kf)
    pos = np.asarray(prof.positions)
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pos, axis=0), axis=1))]
    out, merged = [P0.copy()], True
    for k in range(1, len(prof.time)):
        h = prof.headings[k]
        J = np.array([[-np.sin(h), np.cos(h), 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])  # lateral, heading
        if along:
            J = np.vstack([[np.cos(h), np.sin(h), 0.0, 0.0], J])
        if merged:
            M = sum(wi * (kf.P + Ni) for wi, kf, Ni in zip(w, kfs, N))
            M = 0.5 * (M + M.T)
            G = M @ J.T
            L = np.linalg.cholesky(J @ G)
            C = M - G @ np.linalg.solve(J @ G, G.T)
            for i, kf in enumerate(kfs):
                kf.x = (G @ np.linalg.solve(L.T, z[i])).reshape(4, 1)
                N[i] = C - kf.P + kf.x @ kf.x.T
        seen = []
        for i, kf in enumerate(kfs):
            d = -(J @ kf.x).ravel()
            kf.T = np.eye(4)
            p, dth = prof.positions[k] + d[-2] * J[-2, :2], d[-1]
            if along:
                camera = (lambda j: stage(j)[2]) if stage is not None else (lambda j: prof.headings[j])
                p, dth = _ahead_view(prof, arc, k, kf.x.ravel(), camera)
            seen.append(_reference_stage(kf, prof, k, p, bmm, se, bearing_std, checker, dtheta=dth, stage=stage))
            N[i] = kf.T @ kf.F @ N[i] @ kf.F.T @ kf.T.T
        out.append(sum(wi * (kf.P + Ni) for wi, kf, Ni in zip(w, kfs, N)))
        merged = all(s == seen[0] for s in seen) and all(
            np.linalg.norm(kf.P - kfs[0].P) <= 1e-2 * np.linalg.norm(kfs[0].P) for kf in kfs)
    return np.array(out)


def _ahead_view(prof, arc, k, e, camera):
    """With the along-track axis: the estimate runs t.e ahead of the nominal
    (the vehicle's true progress keeps to the nominal's), so the vehicle sees
    from the nominal pose that far along the stages (the nearest stage j,
    then the rest along its leg), moved by -e, with stage j's camera
    (``camera(j)``) turned by -e_theta.  Returns the position and the
    camera's turn from stage k's."""
    h = prof.headings[k]
    target = arc[k] + np.cos(h) * e[0] + np.sin(h) * e[1]
    j = min(int(np.searchsorted(arc[1:], target, side="left")) + 1, len(arc) - 1)
    if j > 1 and target - arc[j - 1] < arc[j] - target:
        j -= 1
    seg = np.asarray(prof.positions[j]) - np.asarray(prof.positions[j - 1])
    length = np.linalg.norm(seg)
    rest = np.clip(target - arc[j], -length, arc[j + 1] - arc[j] if j + 1 < len(arc) else 0.0)
    p = np.asarray(prof.positions[j]) + rest * seg / length - e[:2]
    return p, camera(j) - camera(k) - e[3]


def _reference_stage(kf, prof, k, p, bmm, se, bearing_std, checker, dtheta=0.0, stage=None):
    """Stage k of the recursion: predict along the nominal, then the ML updates of what is in view
    from p, with the camera turned by dtheta from the nominal camera heading (the leg's, or
    ``stage(k)``'s with its F and G).  Returns which updates it took:
    (a fix, ranges, the landmarks ranged or beared)."""
    sig2 = np.array([bmm.position_noise, bmm.position_noise, bmm.speed_noise, bmm.heading_noise]) ** 2
    R_fix = se.position.reported_cov()
    lms = np.asarray(se.landmarks)
    dt = prof.time[k] - prof.time[k - 1]
    n = dt / bmm.dt
    if stage is None:
        theta = prof.headings[k]
        F, G = np_jacobians(SPEED, theta, dt)
    else:
        F, G, theta = stage(k)
    kf.F, kf.Q = F, G @ np.diag(sig2 * n) @ G.T
    kf.predict()
    seen = [i for i in range(len(lms)) if _visible(se, lms[i], p, theta + dtheta, checker)]
    ranges = se.fix_model == _core.FixModel.RANGES
    range_fix = ranges and len(seen) >= max(3, se.min_landmarks)
    fix = not ranges and len(seen) >= se.min_landmarks
    # A range fix that the trilateration may refuse as ambiguous: two branches, as for a
    # fix that may not arrive (test_belief_faults), the ranges counted a u / p times.
    p_fix, count, without = 1.0, n, None
    if range_fix:
        u = unambiguous_share(se, lms[seen], p)
        if u < 1.0:
            assert not isinstance(kf, _TrackedKF), "the mixture references carry no branches"
            p_fix = 1.0 - (1.0 - u) ** n
            count = n * u / p_fix if p_fix > 0 else 0.0
            without = copy.deepcopy(kf)
    if fix:
        kf.update(np.zeros((2, 1)), R=R_fix / n, H=np.c_[np.eye(2), np.zeros((2, 2))])
    for i in seen if range_fix and p_fix > 0 else ():
        d = lms[i] - p
        q = d @ d
        if q >= 1e-18:  # a landmark at the vehicle: no Jacobian, no update (measurement.hpp)
            kf.update(np.zeros((1, 1)), R=np.array([[se.range_std ** 2 / count]]),
                      H=np.array([[-d[0] / np.sqrt(q), -d[1] / np.sqrt(q), 0.0, 0.0]]))
    for branch in (kf, without) if without is not None else (kf,):
        for i in seen if bearing_std > 0 else ():
            d = lms[i] - p
            q = d @ d
            if q >= 1e-18:
                branch.update(np.zeros((1, 1)), R=np.array([[bearing_std ** 2 / n]]),
                              H=np.array([[d[1] / q, -d[0] / q, 0.0, -1.0]]))
        if se.imu:
            branch.update(np.zeros((2, 1)), R=np.diag([se.imu_speed_std ** 2, se.imu_heading_std ** 2]) / n,
                          H=np.array([[0.0, 0, 1, 0], [0, 0, 0, 1]]))
    if without is not None:
        kf.P = p_fix * kf.P + (1.0 - p_fix) * without.P
    return fix, range_fix, tuple(seen) if range_fix or bearing_std > 0 else ()


def unambiguous_share(se, anchors, p):
    """The share of range fixes from p to ``anchors`` that the trilateration
    does not refuse, by its specification: 0 where the noise-free ranges
    fail for their geometry; else, with Δ the noise-free χ² gap between the
    solution and its mirror minimum, P(|N(Δ, 4 Δ)| > ambiguity_margin)."""
    anchors = np.asarray(anchors, dtype=float)
    r = trilaterate(anchors, np.hypot(*(anchors - p).T), se.range_std)
    gap, M = r.ambiguity_gap, _core.LocalizationOptions().ambiguity_margin
    if not r.ok and not gap <= M:
        return 0.0
    if np.isinf(gap):
        return 1.0
    sd = 2.0 * np.sqrt(gap)
    return float(stats.norm.sf((M - gap) / sd) + stats.norm.sf((M + gap) / sd))


def _visible(se, landmark, p, theta, checker):
    one = _core.SensorSettings()
    one.field_of_view, one.max_range = belief_camera(se)
    one.occlusion = se.occlusion
    one.landmarks = np.asarray(landmark, dtype=float).reshape(1, 2)
    return one.landmarks_in_view(np.r_[p, SPEED, theta], checker) == 1


def profile_cov(prof):
    return np.asarray(prof.covariance).reshape(-1, 4, 4)


# ------------------------------------------------------------- the recursion
@pytest.mark.parametrize("ranges, bearing_std", [(False, 0.0), (True, 0.0), (True, 0.02), (False, 0.05)])
def test_covariance_equals_filterpy_ekf_recursion(ranges, bearing_std):
    # Legs that are whole numbers of 0.1 m steps: every step is the BMM's dt.
    path = np.array([[0.0, 0.0], [20.0, 0.0], [20.0, 15.0], [5.0, 15.0]])
    lms = [[10.0, 5.0], [12.0, -4.0], [8.0, 3.0], [25.0, 10.0], [60.0, 60.0]]
    se = sensors(lms, ranges=ranges, max_range=12.0)
    bmm = _core.BmmParams()
    m = open_map(upper=(100, 100))
    P0 = np.diag([0.01, 0.02, 0.003, 0.001])
    prof = P.propagate_belief(path, sensors=se, map=m, bmm=bmm, start_cov=P0, speed=SPEED, bearing_std=bearing_std,
                              deviation_mixture=False)
    assert np.allclose(np.diff(prof.time), bmm.dt)
    ref = reference_covariances(prof, bmm, se, P0, bearing_std, _core.ObstacleChecker(m))
    np.testing.assert_allclose(profile_cov(prof), ref, rtol=1e-9, atol=1e-15)
    # σ is √λ_max of the position block; cov_xy is that block.
    lam = np.linalg.eigvalsh(ref[:, :2, :2])[:, 1]
    np.testing.assert_allclose(prof.sigma, np.sqrt(lam), rtol=1e-9)
    np.testing.assert_array_equal(np.asarray(prof.cov_xy).reshape(-1, 2, 2), profile_cov(prof)[:, :2, :2])


@pytest.mark.parametrize("ranges, bearing_std, nodes, along", [
    (False, 0.0, 3, False), (True, 0.0, 3, False), (False, 0.05, 3, False), (False, 0.0, 5, False),
    (True, 0.05, 7, False), (False, 0.0, 3, True), (True, 0.05, 3, True), (False, 0.0, 5, True)])
def test_deviation_mixture_equals_nodes_squared_filterpy_filters(ranges, bearing_std, nodes, along):
    # A blind stretch (σ grows to about 0.5 m), then landmarks come into view one by one.
    path = np.array([[0.0, 0.0], [40.0, 0.0], [40.0, 12.0]])
    lms = [[44.0, 4.0], [46.0, -3.0], [48.0, 6.0], [52.0, 0.5]]
    se = sensors(lms, ranges=ranges, max_range=12.0, fov=np.deg2rad(90))
    bmm = _core.BmmParams()
    m = open_map(upper=(100, 100))
    P0 = np.diag([0.2, 0.1, 0.003, 0.001])
    kw = dict(sensors=se, map=m, bmm=bmm, start_cov=P0, speed=SPEED, bearing_std=bearing_std)
    prof = P.propagate_belief(path, **kw, deviation_nodes=nodes, deviation_along=along, deviation_split=False)
    nominal = P.propagate_belief(path, **kw, deviation_mixture=False)
    ref = reference_mixture(prof, bmm, se, P0, bearing_std, _core.ObstacleChecker(m), nodes=nodes, along=along)
    np.testing.assert_allclose(profile_cov(prof), ref, rtol=1e-9, atol=1e-15)
    # It differs from the nominal recursion where landmarks come into view: there the nominal
    # drops at once, the mixture over the stages where part of its components see.
    tr = lambda p: profile_cov(p)[:, 0, 0] + profile_cov(p)[:, 1, 1]  # noqa: E731
    ratio = tr(prof) / tr(nominal)
    assert ratio.max() > 1.05
    np.testing.assert_allclose(ratio[:50], 1.0, rtol=1e-12)  # blind: every component steps alike
    # Patil's error dynamics stay valid: Cov w_k = P_k+1 − A_k P_k A_kᵀ ⪰ 0.
    A = np.asarray(prof.transition).reshape(-1, 4, 4)
    Pk = profile_cov(prof)
    for k in range(len(Pk) - 1):
        W = Pk[k + 1] - A[k] @ Pk[k] @ A[k].T
        assert np.linalg.eigvalsh(0.5 * (W + W.T)).min() > -1e-12


@pytest.mark.parametrize("nodes, along", [(3, False), (5, False), (7, False), (3, True), (5, True)])
def test_deviation_mixture_is_the_recursion_when_every_component_sees_alike(nodes, along):
    # An all-round camera of long range: every component sees every landmark; with the fix
    # model's constant H every component steps alike, and the mixture is the single recursion.
    path = np.array([[0.0, 0.0], [20.0, 0.0], [20.0, 15.0]])
    se = sensors([[10.0, 5.0], [12.0, -4.0], [8.0, 3.0]], max_range=1e4, occlusion=False)
    kw = dict(sensors=se, map=open_map(upper=(100, 100)), start_cov=np.diag([0.3, 0.1, 0.003, 0.001]),
              speed=SPEED)
    np.testing.assert_allclose(profile_cov(P.propagate_belief(path, **kw, deviation_nodes=nodes,
                                                              deviation_along=along)),
                               profile_cov(P.propagate_belief(path, **kw, deviation_mixture=False)), rtol=1e-13,
                               atol=1e-18 if along else 1e-30)  # conditioning on the whole position rounds zeros


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lx=st.floats(-15, 15), ly=st.floats(-15, 15), turn=st.integers(-3, 3), steps=st.integers(5, 120),
       s0=st.floats(1e-3, 1.0), ranges=st.booleans())
def test_covariance_recursion_property(lx, ly, turn, steps, s0, ranges):
    """Any straight-then-turned path and landmark layout: the same recursion as FilterPy's."""
    th = turn * np.pi / 4
    a = np.array([50.0, 50.0])
    b = a + 0.1 * steps * np.array([1.0, 0.0])
    c = b + 0.1 * steps * np.array([np.cos(th), np.sin(th)])
    lms = np.array([[lx, ly], [ly, -lx], [lx + 3, 2.0], [-4.0, ly]]) + b
    se = sensors(lms, ranges=ranges, fov=np.deg2rad(85))
    bmm = _core.BmmParams()
    m = open_map(upper=(100, 100))
    P0 = np.diag([s0, 2 * s0, 0.01, 0.001])
    prof = P.propagate_belief(np.array([a, b, c]), sensors=se, map=m, bmm=bmm, start_cov=P0, speed=SPEED,
                              deviation_mixture=False)
    ref = reference_covariances(prof, bmm, se, P0, 0.0, _core.ObstacleChecker(m))
    np.testing.assert_allclose(profile_cov(prof), ref, rtol=1e-7, atol=1e-14)


# --------------------------------------------------------- what σ does
def test_sigma_grows_blind_and_shrinks_when_landmarks_come_into_view():
    # Landmarks (a cluster of 4) only near x = 40: blind from 0 to ~15, in view later.
    lms = [[45.0, 3.0], [45.0, -3.0], [48.0, 0.5], [47.0, -1.0]]
    se = sensors(lms, fov=np.deg2rad(85), max_range=30.0)
    bmm = _core.BmmParams()
    bmm.position_noise = 0.03
    prof = P.propagate_belief([[0.0, 0.0], [38.0, 0.0]], sensors=se, map=open_map(upper=(100, 100)),
                              bmm=bmm, start_cov=np.diag([1e-4, 1e-4, 1e-3, 1e-4]), speed=SPEED,
                              deviation_mixture=False)
    seen = np.asarray(prof.landmarks) >= se.min_landmarks
    first = int(np.argmax(seen))
    assert 0 < first < len(seen) - 1 and not seen[:first].any() and seen[first:].all()
    sig = np.asarray(prof.sigma)
    assert np.all(np.diff(sig[:first]) > 0), "dead reckoning: σ grows every step"
    assert sig[first] < 0.2 * sig[first - 1], "the first fix collapses σ"
    assert sig[first:].max() < 0.06
    # Dead reckoning grows like a random walk: σ² ≈ linear in time.
    t = np.asarray(prof.time)[1:first]
    slope = np.polyfit(t, sig[1:first] ** 2, 1)[0]
    assert slope > 0.9 * bmm.position_noise ** 2 / bmm.dt


def test_occlusion_hides_landmarks():
    wall = np.array([[10.0, 2.0], [30.0, 2.0], [30.0, 4.0], [10.0, 4.0]])
    lms = [[15.0, 8.0], [20.0, 9.0], [25.0, 8.0], [18.0, 10.0]]
    m = open_map(upper=(60, 40), polygons=[wall])
    path = [[12.0, 0.0], [28.0, 0.0]]
    prof = {}
    for occ in (True, False):
        se = sensors(lms, occlusion=occ)
        prof[occ] = P.propagate_belief(path, sensors=se, map=m, start_cov=np.diag([1e-4, 1e-4, 1e-3, 1e-4]))
        checker = _core.ObstacleChecker(m)
        for p, th, n in zip(prof[occ].positions, prof[occ].headings, prof[occ].landmarks):
            assert n == se.landmarks_in_view(np.r_[p, SPEED, th], checker)
    assert np.all(np.asarray(prof[True].landmarks) == 0)
    assert np.all(np.asarray(prof[False].landmarks) >= 3)
    assert prof[True].sigma[-1] > 5 * prof[False].sigma[-1]


# --------------------------------------------------- collision probability
def corridor_world():
    """Two blocks leave a 3 m corridor along y = 20 from x = 15 to 45; a wide
    lane along y = 36 above; landmarks along the top edge (y = 39.5)."""
    low = np.array([[15.0, 0.0], [45.0, 0.0], [45.0, 18.5], [15.0, 18.5]])
    high = np.array([[15.0, 21.5], [45.0, 21.5], [45.0, 32.0], [15.0, 32.0]])
    xs = np.arange(0.0, 61.0, 5.0)
    lms = np.c_[xs, np.full_like(xs, 39.5)]
    bmm = _core.BmmParams()
    bmm.position_noise = 0.03
    return open_map(polygons=[low, high]), bmm, sensors(lms, fov=np.deg2rad(85))


def monte_carlo(prof, radius, n=20000, seed=1):
    """e_{k+1} = A_k e_k + w_k, Cov w_k = P_{k+1} - A_k P_k A_k^T; collision when
    a_k . e_k > clearance_k - radius at some stage (the half-planes of Patil et al.)."""
    rng = np.random.default_rng(seed)
    Ps, A = profile_cov(prof), np.asarray(prof.transition).reshape(-1, 4, 4)
    a, b = np.asarray(prof.direction), np.asarray(prof.clearance) - radius
    e = rng.multivariate_normal(np.zeros(4), Ps[0], size=n)
    hit = e[:, :2] @ a[0] > b[0]
    for k in range(1, len(Ps)):
        N = Ps[k] - A[k - 1] @ Ps[k - 1] @ A[k - 1].T
        w = np.linalg.cholesky(0.5 * (N + N.T) + 1e-18 * np.eye(4))
        e = e @ A[k - 1].T + rng.standard_normal((n, 4)) @ w.T
        hit |= e[:, :2] @ a[k] > b[k]
    return hit.mean()


@pytest.mark.parametrize("radius", [0.0, 0.2, 0.5, 0.9])
def test_collision_probability_bounds_and_monte_carlo(radius):
    """Measured (n = 40000): radius 0 -> 0.068 vs MC 0.030; 0.2 -> 0.112 vs 0.064;
    0.5 -> 0.216 vs 0.178; 0.9 -> 0.468 vs 0.469.  Re-fitting a Gaussian after
    each truncation gives back part of the cut tail, so over many strongly
    correlated stages the estimate errs high: conservative, within a factor 2.5."""
    m, bmm, se = corridor_world()
    prof = P.propagate_belief([[5.0, 20.2], [55.0, 20.2]], sensors=se, map=m, bmm=bmm, vehicle_radius=radius,
                              margin=0.0, step=0.25)
    pc, ub = prof.collision_probability, prof.union_bound
    marg = np.asarray(prof.marginal_probability)
    assert 0.0 < pc <= ub
    assert pc >= marg.max() - 1e-12
    stage = np.asarray(prof.stage_probability)
    assert np.isclose(pc, 1 - np.prod(1 - stage))
    mc = monte_carlo(prof, radius, n=40000)
    assert 0.01 < mc < 0.99
    assert 0.9 * mc - 0.01 <= pc <= 2.5 * mc + 0.01, (pc, mc, ub)
    assert ub > 1.5 * pc or ub == 1.0, "the conditioned estimate is well inside the union bound"


@pytest.mark.parametrize("radius", [0.0, 0.5])
def test_core_monte_carlo_agrees_with_the_numpy_one(radius):
    m, bmm, se = corridor_world()
    prof = P.propagate_belief([[5.0, 20.2], [55.0, 20.2]], sensors=se, map=m, bmm=bmm, vehicle_radius=radius,
                              margin=0.0, step=0.25)
    assert prof.vehicle_radius == radius
    n = 40000
    core = P.collision_monte_carlo(prof, samples=n, seed=5)
    ref = monte_carlo(prof, radius, n=n, seed=7)
    se_ = np.sqrt(2 * ref * (1 - ref) / n)
    assert abs(core - ref) < 4 * se_ + 1e-3, (core, ref)
    assert core <= prof.collision_probability * 1.1
    assert P.collision_monte_carlo(prof, samples=1000, seed=5) == P.collision_monte_carlo(prof, samples=1000, seed=5)
    with pytest.raises(ValueError, match="samples"):
        P.collision_monte_carlo(prof, samples=0)


def test_single_stage_probability_is_the_gaussian_tail():
    # A path with one short step next to a wall: stage 0 is the exact Gaussian tail.
    m, bmm, se = corridor_world()
    prof = P.propagate_belief([[5.0, 20.0], [5.1, 20.0]], sensors=se, map=m, bmm=bmm, vehicle_radius=0.0,
                              margin=0.0, start_cov=np.diag([4.0, 4.0, 0.01, 0.01]))
    from math import erfc, sqrt
    d, s = prof.clearance[0], prof.sigma_toward[0]
    assert np.isclose(prof.marginal_probability[0], 0.5 * erfc(d / s / sqrt(2)))
    assert np.isclose(prof.stage_probability[0], prof.marginal_probability[0])
    assert np.allclose(np.linalg.norm(prof.direction, axis=1), 1.0)


def test_no_obstacles_no_collision():
    prof = P.propagate_belief([[1.0, 1.0], [9.0, 9.0]], sensors=sensors([[5.0, 5.0]]), map=open_map(),
                              start_cov=np.eye(4))
    assert prof.collision_probability == 0.0 and prof.union_bound == 0.0
    assert np.all(np.isinf(prof.clearance))


# --------------------------------------------------------------- bad input
@pytest.mark.parametrize("kwargs, match", [
    ({"path": [[0.0, 0.0]]}, "needs >= 2"),
    ({"path": [[0.0, 0.0], [np.nan, 1.0]]}, r"path\[\(1, 0\)\] = nan"),
    ({"speed": -1.0}, "speed"),
    ({"step": -0.1}, "step"),
    ({"vehicle_radius": -1.0}, "vehicle_radius"),
    ({"start_cov": -np.eye(4)}, "start_cov"),
    ({"start_cov": np.eye(3)}, "start_cov"),
    ({"deviation_nodes": 4}, "deviation_nodes = 4"),
    ({"deviation_nodes": 9}, "deviation_nodes"),
    ({"deviation_nodes": 1}, "deviation_nodes"),
])
def test_bad_input_names_the_value(kwargs, match):
    args = {"path": [[0.0, 0.0], [5.0, 0.0]], "sensors": sensors([[1.0, 1.0]]), "map": open_map(),
            "start_cov": np.eye(4) * 0.01}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        P.propagate_belief(**args)


def test_the_expected_belief_sees_with_the_vehicles_camera_and_the_robust_one_narrower():
    """BeliefSettings.sight_fov_margin / sight_range_fraction: a landmark at
    the edge of the vehicle's view (inside its 85° and 30 m) is counted by
    the default (expected) belief, and not by the robust camera of the
    planner and the certificate (robust_sight: 25° less, 90 % of the range)."""
    from safenav.belief import robust_sight

    # Heading +x; one landmark 35° off the heading at 20 m (inside 42.5°, outside 30°),
    # one straight ahead at 28 m (inside 30 m, outside 27 m).
    lms = np.array([[20 * np.cos(np.deg2rad(35)), 20 * np.sin(np.deg2rad(35))], [28.0, 0.0]]) + 10.0
    se = sensors(lms, fov=np.deg2rad(85), occlusion=False)
    m = open_map(upper=(100, 100))
    path = np.array([[10.0, 10.0], [10.2, 10.0]])
    own = P.propagate_belief(path, sensors=se, map=m, speed=SPEED)
    narrow = P.propagate_belief(path, sensors=se, map=m, speed=SPEED, **robust_sight())
    assert np.asarray(own.landmarks)[1] == 2
    assert np.asarray(narrow.landmarks)[1] == 0
    s = _core.BeliefSettings()
    assert s.sight_fov_margin == 0.0 and s.sight_range_fraction == 1.0
    b = _core.BeliefPlannerSettings().belief
    assert b.sight_fov_margin == pytest.approx(np.deg2rad(25.0)) and b.sight_range_fraction == 0.9
    assert s.deviation_mixture and not b.deviation_mixture
    assert robust_sight() == {"sight_fov_margin": b.sight_fov_margin, "sight_range_fraction": 0.9,
                              "deviation_mixture": False}
    with pytest.raises(ValueError, match="sight_range_fraction"):
        P.propagate_belief(path, sensors=se, map=m, sight_range_fraction=0.0)


def test_the_robust_belief_is_never_below_the_expected_one():
    """The robust camera sees a subset of the vehicle's landmarks at every
    stage; the covariance recursion is monotone, so P_robust ⪰ P_expected
    stage by stage (smallest eigenvalue of the difference ≥ 0), up to 10⁻⁶ of
    the stage's scale: the expected belief is the mixture of its strata's
    errors (deviation_mixture), and a stratum's update can raise its error a
    little where its filter trusts a fix more than its own, smaller error
    warrants (parts in 10⁸ here, during transitions)."""
    from safenav.belief import robust_sight

    rng = np.random.default_rng(11)
    se = sensors(rng.uniform(0.0, 60.0, (25, 2)), fov=np.deg2rad(85), occlusion=False)
    m = open_map(upper=(60, 60))
    path = np.array([[5.0, 5.0], [55.0, 10.0], [50.0, 55.0], [8.0, 40.0]])
    own = P.propagate_belief(path, sensors=se, map=m, speed=SPEED)
    narrow = P.propagate_belief(path, sensors=se, map=m, speed=SPEED, **robust_sight())
    assert (np.asarray(narrow.landmarks) <= np.asarray(own.landmarks)).all()
    assert (np.asarray(narrow.landmarks) < np.asarray(own.landmarks)).any()
    expected = np.asarray(own.covariance).reshape(-1, 4, 4)
    d = np.asarray(narrow.covariance).reshape(-1, 4, 4) - expected
    scale = np.linalg.eigvalsh(expected).max(axis=1)
    assert (np.linalg.eigvalsh(0.5 * (d + d.transpose(0, 2, 1))).min(axis=1) >= -1e-6 * scale).all()
    assert (np.asarray(narrow.sigma) >= np.asarray(own.sigma) - 1e-12).all()

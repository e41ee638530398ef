"""The regularised particle filter stays consistent: its NEES against the
chi-square band on a near-linear problem, after fix gaps (where the plain
SIR filter collapses) and through long dead reckoning on the IMU alone
(where resampling used to shrink the cloud), its estimate against the
Kalman filter's on a near-linear problem, its reported covariance never
below the kernel floor, the jitter's bandwidth as Musso et al. 2001 give
it, and fixed seeds.

Truth from ``Bmm(params).simulate`` with the filter's own parameters; position
fixes with noise drawn from the R the filter is given; the initial estimate
drawn from N(truth_0, P0).  The controls keep eq. 3 exactly linear (the desired
speed alternates far above and far below v), as in test_consistency.py.
"""

from __future__ import annotations

import numpy as np
import pytest

import safenav
from safenav import Bmm, BmmParams, MeasurementModel
from safenav.metrics import chi2_interval, nees

PARAMS = BmmParams(acceleration=2.0, deceleration=2.0, max_speed=10.0, max_heading_rate=1.0, dt=0.1,
                   speed_noise=0.05, heading_noise=0.01, position_noise=0.02)
P0 = np.diag([0.1**2, 0.1**2, 0.1**2, 0.03**2])
X0_TRUE = np.array([0.0, 0.0, 3.0, 0.4])
#: LanBLoc's fix noise (0.014 m in x, 0.039 m in y): far narrower than the
#: spread a cloud reaches after a few steps without a fix.
R_LANBLOC = np.diag([0.014**2, 0.039**2])


def controls(n):
    k = np.arange(n)
    vd = np.where((k // 5) % 2 == 0, 50.0, -50.0)  # always rate-limited: v' = v +- 0.2
    dth = 0.02 * np.sin(2 * np.pi * k / n)           # |dth| < m*dt: the clip never binds
    return np.column_stack([vd, dth])


def monte_carlo(n_runs, n_steps, seed, *, R, fix_every=1, **kw):
    """Per-run NEES sequences (n_runs, n_steps) of the PF's estimate after each step."""
    u = controls(n_steps)
    bmm = Bmm(PARAMS)
    out = np.empty((n_runs, n_steps))
    for i, ss in enumerate(np.random.SeedSequence(seed).spawn(n_runs)):
        rng = np.random.default_rng(ss)
        truth = bmm.simulate(X0_TRUE, u, seed=int(rng.integers(2**63)))
        z = truth[1:, :2] + rng.multivariate_normal(np.zeros(2), R, size=n_steps)
        z[np.arange(n_steps) % fix_every != fix_every - 1] = np.nan  # gaps: a fix every fix_every steps
        x0 = rng.multivariate_normal(X0_TRUE, P0)
        res = safenav.filter_trajectory(u, x0, P0, params=PARAMS, filter="pf", position=z, position_cov=R,
                                        seed=int(rng.integers(2**63)), **kw)
        out[i] = nees_or_inf(res.states[1:], truth[1:], res.covariances[1:])
    return out


def nees_or_inf(est, truth, covs):
    """metrics.nees, with inf where the covariance is singular (a collapsed cloud)."""
    out = np.full(len(est), np.inf)
    for k, P in enumerate(covs):
        try:
            out[k] = nees(est[k:k + 1], truth[k:k + 1], P[None])[0]
        except ValueError:  # not positive definite
            pass
    return out


def test_bandwidth_is_musso_optimal():
    """h = c (4 / (N (d + 2)))^(1/(d+4)) with d = 4 (and d = the augmented size), capped at 1."""
    for n, c in ((500, 1.0), (2000, 0.5), (1, 1.0), (10, 3.0)):
        pf = safenav.ParticleFilter(PARAMS, X0_TRUE, P0, n_particles=n, bandwidth_scale=c)
        assert pf.bandwidth == pytest.approx(min(1.0, c * (4 / (n * 6)) ** (1 / 8)), rel=1e-14)
    assert safenav.ParticleFilter(PARAMS, X0_TRUE, P0, n_particles=50, bandwidth_scale=0.0).bandwidth == 0.0
    from safenav import _core
    a = _core.AugmentedStates()
    a.range_scale = a.heading_rate_bias = True
    f = _core.AugmentedParticleFilter(PARAMS, a, 3, X0_TRUE, P0, n_particles=400)
    assert f.state_size == 6
    assert f.bandwidth == pytest.approx((4 / (400 * 8)) ** (1 / 10), rel=1e-14)
    with pytest.raises(ValueError, match="bandwidth_scale = -1"):
        safenav.ParticleFilter(PARAMS, X0_TRUE, P0, n_particles=50, bandwidth_scale=-1.0)


def test_anees_inside_chi2_interval_on_near_linear_problem():
    """Fixes every step (R comparable to the cloud): the two-sided 95 % band of the mean of M time-averaged NEES."""
    M, N = 80, 40
    e = monte_carlo(M, N, seed=11, R=np.diag([0.2**2, 0.25**2]), n_particles=500)
    lo, hi = chi2_interval(dof=4, n_runs=M)
    anees = e.mean(axis=1).mean()
    assert lo < anees < hi, (anees, lo, hi)


def test_anees_stays_in_band_after_fix_gaps_where_sir_collapses():
    """A LanBLoc fix every 8 steps: the fix is far narrower than the particle
    spacing, one or two particles take all the weight.  The plain SIR filter
    (bandwidth_scale = 0) then reports a covariance of almost nothing; the
    regularised one stays in the chi-square band (per-step 95 % band of the
    mean of M chi2(4) values, two-sided)."""
    M, N = 60, 48
    kw = dict(R=R_LANBLOC, fix_every=8, n_particles=500)
    sir = monte_carlo(M, N, seed=12, bandwidth_scale=0.0, **kw)
    rpf = monte_carlo(M, N, seed=12, **kw)
    assert np.mean(sir.mean(axis=1) > 100.0) > 0.1, np.sort(sir.mean(axis=1))
    lo, hi = chi2_interval(dof=4, n_runs=M)
    anees = rpf.mean(axis=1).mean()
    # the band of a consistent filter, widened by the per-run time averages' extra spread
    assert 0.75 * lo < anees < 1.25 * hi, (anees, lo, hi)
    assert np.percentile(rpf.mean(axis=1), 95) < 15.0, np.sort(rpf.mean(axis=1))[-5:]


THR = 0.5


def test_reported_covariance_never_collapses_with_one_landmark():
    """200 range updates to one landmark (one direction observed, the other
    only through the motion): the reported covariance stays above the
    kernel floor h^2 C_u and the weighted one (Loewner order) after every
    update, and the NEES stays bounded, below the SIR filter's."""
    landmark = np.array([[5.0, 5.0]])
    model = MeasurementModel.range(landmark, 0.05)
    bmm = Bmm(PARAMS)
    rng = np.random.default_rng(4)
    u = controls(200)
    truth = bmm.simulate(X0_TRUE, u, seed=4)
    out = {}
    for c in (0.0, 1.0):
        pf = safenav.ParticleFilter(PARAMS, X0_TRUE, P0, n_particles=400, seed=9, resample_threshold=THR,
                                    bandwidth_scale=c)
        e, ess = [], []
        for k in range(len(u)):
            pf.predict(u[k])
            r = np.hypot(*(truth[k + 1, :2] - landmark[0])) + 0.05 * rng.standard_normal()
            pf.update(model, [r])
            P, F = pf.P, pf.covariance_floor
            if c > 0:
                np.testing.assert_allclose(F, pf.bandwidth**2 * np.cov(pf.particles.T, bias=True), rtol=1e-6,
                                           atol=1e-12)
                assert np.linalg.eigvalsh(P - F).min() > -1e-9 * np.abs(F).max(), k
                assert np.linalg.eigvalsh(P - pf.sample_covariance).min() > -1e-12, k
            e.append(float(nees_or_inf(pf.x[None], truth[k + 1][None], P[None])[0]))
            ess.append(pf.ess)
        out[c] = np.array(e), np.array(ess)
    e_sir, _ = out[0.0]
    e_rpf, _ = out[1.0]
    assert np.isfinite(e_rpf).all() and np.median(e_rpf) < 8.0, np.median(e_rpf)
    assert np.median(e_rpf) < np.median(e_sir), (np.median(e_rpf), np.median(e_sir))


def test_same_seed_same_numbers():
    u = controls(60)
    truth = Bmm(PARAMS).simulate(X0_TRUE, u, seed=2)
    z = truth[1:, :2] + np.random.default_rng(2).multivariate_normal(np.zeros(2), R_LANBLOC, size=60)
    z[::3] = np.nan
    run = lambda seed: safenav.filter_trajectory(u, X0_TRUE, P0, params=PARAMS, filter="pf", position=z,
                                                 position_cov=R_LANBLOC, n_particles=300, seed=seed)
    a, b, c = run(5), run(5), run(6)
    assert a.n_updates == 40
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.covariances, b.covariances)
    assert not np.array_equal(a.states, c.states)
    # the step API: two filters with one seed stay equal through resamplings
    # (the SIR filter, resample_threshold 1: every update resamples) and
    # through the regularised filter's redraws, IMU ensemble updates and
    # moment-matched process noise
    pos, imu = MeasurementModel.position(R_LANBLOC), MeasurementModel.speed_heading(R_IMU)
    zi = truth[1:, 2:] + np.random.default_rng(3).multivariate_normal(np.zeros(2), R_IMU, size=60)
    for c in (0.0, 1.0):
        f, g = (safenav.ParticleFilter(PARAMS, X0_TRUE, P0, n_particles=300, seed=5, resample_threshold=1.0,
                                       bandwidth_scale=c) for _ in range(2))
        for k in range(len(u)):
            for h in (f, g):
                h.predict(u[k])
                h.update(imu, zi[k])
                if not np.isnan(z[k, 0]):
                    h.update(pos, z[k])
        if c == 0.0:
            assert f.resample_count > 5
        np.testing.assert_array_equal(f.particles, g.particles)
        np.testing.assert_array_equal(f.P, g.P)


#: The IMU (speed, heading) noise of the default scenario.
R_IMU = np.diag([0.05**2, 0.02**2])


def dead_reckoning(n_runs, n_steps, seed, p0):
    """Per-run NEES (n_runs, n_steps) and reported position variances of the
    PF (500 particles) and the EKF on the same runs: an IMU update every step,
    no position fix.  Position is observed by nothing; the IMU reweights the
    particles by (v, θ) only."""
    u = np.column_stack([np.full(n_steps, 50.0), 0.01 * np.sin(2 * np.pi * np.arange(n_steps) / n_steps)])
    out = {"pf": [], "ekf": []}
    for ss in np.random.SeedSequence(seed).spawn(n_runs):
        rng = np.random.default_rng(ss)
        truth = Bmm(PARAMS).simulate(X0_TRUE, u, seed=int(rng.integers(2**63)))
        z = truth[1:, 2:] + rng.multivariate_normal(np.zeros(2), R_IMU, size=n_steps)
        x0 = rng.multivariate_normal(X0_TRUE, p0)
        for f in out:
            kw = dict(n_particles=500, seed=int(rng.integers(2**63))) if f == "pf" else {}
            r = safenav.filter_trajectory(u, x0, p0, params=PARAMS, filter=f, speed_heading=z,
                                          speed_heading_cov=R_IMU, **kw)
            out[f].append((nees_or_inf(r.states[1:], truth[1:], r.covariances[1:]),
                           r.covariances[1:, 0, 0] + r.covariances[1:, 1, 1]))
    return {f: (np.array([a for a, _ in v]), np.array([b for _, b in v])) for f, v in out.items()}


def test_dead_reckoning_on_the_imu_keeps_the_cloud_and_the_nees():
    """200 steps of IMU updates only, from a 0.3 m position prior.  Every
    update reweights by (v, θ), which says almost nothing about position: a
    filter that resamples on those weights turns ~Σ/ESS of the position
    spread into Monte Carlo error of the mean per cycle, and the spread
    shrinks while the error grows (mean NEES 9 with the old update, 20 with
    the SIR filter).  The EKF's position variance barely changes here; the
    PF's must not collapse below it, and its mean NEES stays near the
    chi-square band."""
    M, N = 30, 200
    p0 = np.diag([0.3**2, 0.3**2, 0.05**2, 0.02**2])
    r = dead_reckoning(M, N, seed=21, p0=p0)
    e_pf, v_pf = r["pf"]
    e_ekf, v_ekf = r["ekf"]
    # The IMU update is the Gaussian one of the cloud's moments (no
    # reweighting) and the process noise is moment-matched, so the PF's
    # position variance follows the EKF's: the ratio after 200 steps is 1 up
    # to Monte Carlo error (a weighted variance of ESS ≥ 250 particles: a
    # relative σ of √(2/250) ≈ 0.09 per run, ≈ 0.016 over 30 runs; ±0.1 is
    # about 6σ).  With the ensemble update on sampled weights the ratio fell
    # to 0.75, with reweighting and resampling to 0.5.
    ratio = v_pf[:, -1].mean() / v_ekf[:, -1].mean()
    assert 0.9 < ratio < 1.1, ratio
    for step in (49, 99):
        assert 0.9 < v_pf[:, step].mean() / v_ekf[:, step].mean() < 1.1, step
    lo, hi = chi2_interval(dof=4, n_runs=M)
    anees = e_pf.mean(axis=1).mean()
    assert lo < anees < hi, (anees, lo, hi, e_ekf.mean())
    assert e_pf[:, -1].mean() < 1.5 * hi, e_pf[:, -1].mean()


def test_imu_update_is_the_gaussian_update_of_the_clouds_moments():
    """One IMU (v, θ) update of the regularised PF, against the equations
    computed here from the cloud before it: the weights stay, the weighted
    mean moves by K ȳ and the weighted covariance becomes Σ − K S Kᵀ
    exactly (K = C_xh S⁻¹, S = C_hh + R, C the weighted moments of x and
    h(x) = (v, θ); the perturbations are moment-matched), to rounding."""
    imu = MeasurementModel.speed_heading(R_IMU)
    pf = safenav.ParticleFilter(PARAMS, X0_TRUE, P0, n_particles=400, seed=8)
    u = controls(20)
    for k in range(10):
        pf.predict(u[k])
    z = np.array([X0_TRUE[2] + 0.05, X0_TRUE[3] - 0.02])
    X, w = pf.particles, pf.weights
    m = w @ X
    D = X - m
    y = z - X[:, 2:]
    ybar = w @ y
    Chh = (D[:, 2:] * w[:, None]).T @ D[:, 2:]
    Cxh = (D * w[:, None]).T @ D[:, 2:]
    S = Chh + R_IMU
    K = Cxh @ np.linalg.inv(S)
    pf.update(imu, z)
    X1 = pf.particles
    np.testing.assert_array_equal(pf.weights, w)
    m1 = pf.weights @ X1
    np.testing.assert_allclose(m1, m + K @ ybar, rtol=0, atol=1e-12)
    D1 = X1 - m1
    P1 = (D1 * w[:, None]).T @ D1
    np.testing.assert_allclose(P1, (D * w[:, None]).T @ D - K @ S @ K.T, rtol=1e-9, atol=1e-15)


def test_estimate_follows_the_kalman_filter_on_a_near_linear_problem():
    """Fixes (R comparable to the cloud) and IMU every step, eq. 3 kept linear
    by the controls: the EKF is then (nearly) the exact filter.  The PF's mean
    stays within a fraction of the EKF's σ of the EKF's estimate, and its
    reported covariance within Monte Carlo error of the EKF's P (traces)."""
    n = 60
    u = controls(n)
    rng = np.random.default_rng(31)
    truth = Bmm(PARAMS).simulate(X0_TRUE, u, seed=31)
    R = np.diag([0.2**2, 0.25**2])
    zp = truth[1:, :2] + rng.multivariate_normal(np.zeros(2), R, size=n)
    zi = truth[1:, 2:] + rng.multivariate_normal(np.zeros(2), R_IMU, size=n)
    kw = dict(params=PARAMS, position=zp, position_cov=R, speed_heading=zi, speed_heading_cov=R_IMU)
    ekf = safenav.filter_trajectory(u, X0_TRUE, P0, filter="ekf", **kw)
    pf = safenav.filter_trajectory(u, X0_TRUE, P0, filter="pf", n_particles=500, seed=3, **kw)
    d = nees(pf.states[1:], ekf.states[1:], ekf.covariances[1:])  # (x_pf − x_ekf)ᵀ P_ekf⁻¹ (…)
    assert np.median(d) < 0.5 and d.max() < 3.0, (np.median(d), d.max())
    t_pf = np.trace(pf.covariances[1:, :2, :2], axis1=1, axis2=2)
    t_ekf = np.trace(ekf.covariances[1:, :2, :2], axis1=1, axis2=2)
    assert 0.8 < np.median(t_pf / t_ekf) < 1.3, np.median(t_pf / t_ekf)


def _imu_pf(seed=8):
    pf = safenav.ParticleFilter(PARAMS, X0_TRUE, P0, n_particles=400, seed=seed)
    for uk in controls(10):
        pf.predict(uk)
    return pf


def test_imu_update_takes_the_heading_modulo_a_turn():
    """The IMU's heading is an angle: z_θ and z_θ ± 2π update alike (the
    residual wraps), to rounding."""
    imu = MeasurementModel.speed_heading(R_IMU)
    z = np.array([X0_TRUE[2] + 0.05, X0_TRUE[3] - 0.02])
    runs = []
    for turn in (0.0, 2 * np.pi, -4 * np.pi):
        pf = _imu_pf()
        pf.update(imu, z + [0.0, turn])
        runs.append((pf.particles, pf.x))
    for X, m in runs[1:]:
        np.testing.assert_allclose(X, runs[0][0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(m, runs[0][1], rtol=0, atol=1e-12)


def test_a_large_imu_turn_keeps_the_headings_cosines_exact():
    """An IMU heading far from the cloud's (2 rad, far past the small-turn
    series) moves every particle's θ by more than the series covers: those
    are redone exactly, so the filter's circular mean of θ (from its cached
    cos θ and sin θ) equals the one computed here from the headings."""
    imu = MeasurementModel.speed_heading(np.diag([0.05**2, 0.001**2]))
    pf = _imu_pf()
    pf.update(imu, np.array([X0_TRUE[2], X0_TRUE[3] + 2.0]))
    X, w = pf.particles, pf.weights
    assert abs(X[:, 3].mean() - (X0_TRUE[3] + 2.0)) < 0.05  # the turn happened
    theta = np.arctan2(w @ np.sin(X[:, 3]), w @ np.cos(X[:, 3]))
    assert abs(pf.x[3] - theta) < 1e-12

"""Filter consistency by Monte Carlo: NEES of the EKF and of the PF against the
chi-square acceptance interval, the PF converging to the EKF on a near-linear
problem, and the information filter equal to the EKF.

Set-up shared by the NEES tests: truth from ``Bmm(params).simulate`` with the
same parameters the filter uses; LanBLoc-style position fixes with noise drawn
from the same R the filter is given; the initial estimate drawn from
N(truth_0, P0).  The controls keep the BMM in a regime where its speed update is
exactly linear: the desired speed alternates between far above and far below the
current speed, so eq. 3 always returns v + a*dt or v - d*dt (dv'/dv = 1, the
v_desired, v_max and 0 limits never bind, v stays in about [2.8, 3.8] m/s);
heading changes are a fraction of m*dt so the clip of eq. 4 never binds, and
the heading stays far from +-pi.
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
R = np.diag([0.2**2, 0.25**2])
X0_TRUE = np.array([0.0, 0.0, 3.0, 0.4])


def controls(n):
    k = np.arange(n)
    # +-50 m/s desired: always rate-limited, so v' = v +- 0.2 (blocks of 5 steps)
    vd = np.where((k // 5) % 2 == 0, 50.0, -50.0)
    dth = 0.02 * np.sin(2 * np.pi * k / n)  # |dth| <= 0.02 < m*dt = 0.1
    return np.column_stack([vd, dth])


def monte_carlo(filter_name, n_runs, n_steps, seed, *, filter_R=R, filter_params=PARAMS, **kw):
    """Per-run NEES sequences (n_runs, n_steps) of the estimates after each step's update."""
    u = controls(n_steps)
    bmm = Bmm(PARAMS)
    out = np.empty((n_runs, n_steps))
    for i, ss in enumerate(np.random.SeedSequence(seed).spawn(n_runs)):
        rng = np.random.default_rng(ss)
        truth = bmm.simulate(X0_TRUE, u, seed=int(rng.integers(2**63)))
        assert truth[:, 2].min() > 1.0 and truth[:, 2].max() < PARAMS.max_speed - 1.0
        z = truth[1:, :2] + rng.multivariate_normal(np.zeros(2), R, size=n_steps)
        x0 = rng.multivariate_normal(X0_TRUE, P0)
        res = safenav.filter_trajectory(u, x0, P0, params=filter_params, filter=filter_name, position=z,
                                        position_cov=filter_R, seed=int(rng.integers(2**63)), **kw)
        out[i] = nees(res.states[1:], truth[1:], res.covariances[1:])
    return out


# The statistic tested: for each run the time-averaged NEES over its steps, then
# the mean of those over the M runs.  chi2_interval(4, M) is the 95% interval of
# the mean of M independent chi2(4) values (M*ANEES ~ chi2(4M)).  Each run's time
# average has the same mean 4 as a single NEES but a smaller variance (it averages
# correlated chi2(4) values), so the mean of M time averages has variance <= 8/M:
# the interval is conservative (coverage >= 95%) for a consistent filter.  The
# negative controls below show it still rejects a mistuned filter.

def test_nees_function_matches_numpy():
    rng = np.random.default_rng(5)
    est, tru = rng.normal(size=(6, 4)), rng.normal(size=(6, 4))
    tru[0, 3], est[0, 3] = 3.1, -3.1  # the angle error wraps: 0.083, not 6.2
    A = rng.normal(size=(6, 4, 4))
    covs = A @ np.transpose(A, (0, 2, 1)) + 0.5 * np.eye(4)
    e = est - tru
    e[:, 3] = (e[:, 3] + np.pi) % (2 * np.pi) - np.pi
    ref = np.einsum("ki,kij,kj->k", e, np.linalg.inv(covs), e)
    np.testing.assert_allclose(nees(est, tru, covs), ref, rtol=1e-10)


def test_ekf_anees_inside_chi2_interval():
    M, N = 200, 50
    e = monte_carlo("ekf", M, N, seed=1)
    lo, hi = chi2_interval(dof=4, n_runs=M)
    anees = e.mean(axis=1).mean()
    assert lo < anees < hi, (anees, lo, hi)
    # per time step, the ANEES over the M runs: mostly inside its 95% interval
    # (correlated in time, so the fraction inside varies; 95% expected)
    per_step = e.mean(axis=0)
    assert np.mean((per_step > lo) & (per_step < hi)) >= 0.7, per_step


@pytest.mark.parametrize("scale, side", [(0.25, "high"), (4.0, "low")],
                         ids=["overconfident-R", "underconfident-R"])
def test_ekf_anees_rejects_mistuned_filter(scale, side):
    """Negative control: the same statistic fails when the filter's R is wrong."""
    M, N = 100, 50
    e = monte_carlo("ekf", M, N, seed=2, filter_R=R * scale)
    lo, hi = chi2_interval(dof=4, n_runs=M)
    anees = e.mean(axis=1).mean()
    assert (anees > hi) if side == "high" else (anees < lo), (anees, lo, hi)


def test_pf_anees_inside_chi2_interval():
    # 1000 particles, 100 runs of 40 steps (~0.2 us per particle-step).  The PF's
    # Monte Carlo error inflates its NEES slightly (about 4.2 here, towards 4 as
    # particles grow); the interval is (3.46, 4.57).
    M, N = 100, 40
    e = monte_carlo("pf", M, N, seed=3, n_particles=1000)
    lo, hi = chi2_interval(dof=4, n_runs=M)
    anees = e.mean(axis=1).mean()
    assert lo < anees < hi, (anees, lo, hi)


# ---------------------------------------------------------------------------
# PF -> EKF on a near-linear problem
# ---------------------------------------------------------------------------

def _pf_vs_ekf(n_particles, n_runs=5, n_steps=30):
    """Mean over runs, steps and state components of |PF mean - EKF mean| / EKF std,
    the worst such ratio, and the PF/EKF variance ratios."""
    u = controls(n_steps)
    ratios, var_ratios = [], []
    for i in range(n_runs):
        rng = np.random.default_rng(100 + i)
        truth = Bmm(PARAMS).simulate(X0_TRUE, u, seed=200 + i)
        z = truth[1:, :2] + rng.multivariate_normal(np.zeros(2), R, size=n_steps)
        x0 = rng.multivariate_normal(X0_TRUE, P0)
        ekf = safenav.filter_trajectory(u, x0, P0, params=PARAMS, filter="ekf", position=z, position_cov=R)
        pf = safenav.filter_trajectory(u, x0, P0, params=PARAMS, filter="pf", position=z, position_cov=R,
                                       n_particles=n_particles, seed=300 + i)
        sd = np.sqrt(np.diagonal(ekf.covariances, axis1=1, axis2=2))
        d = pf.states - ekf.states
        d[:, 3] = np.asarray(safenav.wrap_angle(d[:, 3]))
        ratios.append(np.abs(d) / sd)
        var_ratios.append(np.diagonal(pf.covariances, axis1=1, axis2=2) / sd**2)
    ratios, var_ratios = np.array(ratios), np.array(var_ratios)
    return ratios.mean(), ratios.max(), var_ratios


def test_pf_converges_to_ekf_on_near_linear_problem():
    mean_5k, worst_5k, var_5k = _pf_vs_ekf(5000)
    # a small fraction of the EKF standard deviation, everywhere
    assert mean_5k < 0.08, mean_5k
    assert worst_5k < 1.0, worst_5k  # single-step excursions of ~0.6 occur at 5000 particles
    # the PF covariance agrees with the EKF's
    assert 0.85 < var_5k.mean() < 1.15, var_5k.mean(axis=(0, 1))
    assert np.all(var_5k.mean(axis=1) > 0.6) and np.all(var_5k.mean(axis=1) < 1.6)
    # and the gap shrinks as particles grow (Monte Carlo error ~ 1/sqrt(N))
    mean_500, _, _ = _pf_vs_ekf(500)
    mean_20k, _, _ = _pf_vs_ekf(20000)
    # (across other seeds: mean_5k / mean_500 ~ 0.25-0.55, mean_20k / mean_500 ~ 0.1-0.37)
    assert mean_5k < 0.75 * mean_500, (mean_500, mean_5k)
    assert mean_20k < 0.5 * mean_500, (mean_500, mean_20k)


# ---------------------------------------------------------------------------
# EIF == EKF
# ---------------------------------------------------------------------------

LANDMARKS = np.array([[-6.0, 7.0], [14.0, -5.0], [12.0, 10.0]])


def _eif_scenario(n=40):
    u = controls(n)
    truth = Bmm(PARAMS).simulate(X0_TRUE, u, seed=9)
    rng = np.random.default_rng(9)
    z = truth[1:, :2] + rng.multivariate_normal(np.zeros(2), R, size=n)
    d = LANDMARKS[None, :, :] - truth[1:, None, :2]
    ranges = np.hypot(d[..., 0], d[..., 1]) + 0.3 * rng.standard_normal((n, 3))
    bearings = np.arctan2(d[..., 1], d[..., 0]) - truth[1:, 3:4] + 0.03 * rng.standard_normal((n, 3))
    bearings = (bearings + np.pi) % (2 * np.pi) - np.pi
    ranges[::4, 1] = np.nan  # some landmarks unseen (subset models)
    bearings[::3, 0] = np.nan
    z[::5] = np.nan           # some position gaps
    x0 = X0_TRUE + rng.multivariate_normal(np.zeros(4), P0)
    return u, z, ranges, bearings, x0


def test_information_filter_equals_ekf_step_by_step():
    u, z, ranges, bearings, x0 = _eif_scenario()
    ekf = safenav.Ekf(PARAMS, x0, P0)
    eif = safenav.InformationFilter(PARAMS, x0, P0)
    np.testing.assert_allclose(eif.information_matrix, np.linalg.inv(P0), rtol=1e-12)
    pos = MeasurementModel.position(R)
    rng_m = MeasurementModel.range(LANDMARKS, 0.3)
    brg_m = MeasurementModel.bearing(LANDMARKS, 0.03)
    for k in range(len(u)):
        for f in (ekf, eif):
            f.predict(u[k])
        np.testing.assert_allclose(eif.x, ekf.x, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(eif.P, ekf.P, rtol=1e-8, atol=1e-12)
        # the same order as the batch filter; rows with an unseen landmark are skipped here
        for model, zk in ((pos, z[k]), (rng_m, ranges[k]), (brg_m, bearings[k])):
            if np.isnan(zk).any():
                continue
            re, ri = ekf.update(model, zk), eif.update(model, zk)
            assert re.nis == pytest.approx(ri.nis, rel=1e-8)
            np.testing.assert_allclose(eif.x, ekf.x, rtol=1e-8, atol=1e-10, err_msg=f"step {k} {model.kind}")
            np.testing.assert_allclose(eif.P, ekf.P, rtol=1e-8, atol=1e-12, err_msg=f"step {k} {model.kind}")
        np.testing.assert_allclose(eif.information_matrix @ eif.x, eif.information_vector, rtol=1e-8, atol=1e-8)


def test_information_filter_equals_ekf_batch():
    u, z, ranges, bearings, x0 = _eif_scenario()
    kw = dict(params=PARAMS, position=z, position_cov=R, ranges=ranges, range_std=0.3, bearings=bearings,
              bearing_std=0.03, landmarks=LANDMARKS)
    ekf = safenav.filter_trajectory(u, x0, P0, filter="ekf", **kw)
    eif = safenav.filter_trajectory(u, x0, P0, filter="eif", **kw)
    assert ekf.n_updates == eif.n_updates > len(u)
    np.testing.assert_allclose(eif.states, ekf.states, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(eif.covariances, ekf.covariances, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(eif.nis, ekf.nis, rtol=1e-8)
    # the updates mattered: the filtered covariance is well below the prediction-only one
    pred = safenav.filter_trajectory(u, x0, P0, filter="ekf", params=PARAMS)
    assert np.all(np.diagonal(ekf.covariances[-1]) < 0.5 * np.diagonal(pred.covariances[-1]))


def test_information_filter_zero_speed_noise_with_binding_speed_limit():
    p = BmmParams(speed_noise=0.0)
    x0 = np.array([0.0, 0.0, 2.0, 0.3])
    ekf = safenav.Ekf(p, x0, P0)
    eif = safenav.InformationFilter(p, x0, P0)
    u = np.array([2.05, 0.0])  # within a*dt of v: v' = v_desired, dv'/dv = 0
    ekf.predict(u)
    # The speed became exactly known: infinite information, which the
    # information form cannot hold.  It must say so, not turn into NaN.
    with pytest.raises(RuntimeError, match="singular"):
        eif.predict(u)

"""Filter consistency statistics (ours; SafeNav section V-B's metrics are in
``test_metrics.py``): NEES against plain NumPy, with heading wrapping, and the
chi-square interval against ``scipy.stats.chi2.ppf`` and by simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from safenav import metrics


def rng(seed):
    return np.random.default_rng(seed)


# --------------------------------------------------------------------------- 4. NEES and chi-square interval

def random_spd(g, n_mat, dim):
    a = g.normal(size=(n_mat, dim, dim))
    return a @ np.transpose(a, (0, 2, 1)) + 0.1 * np.eye(dim)


def wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def numpy_nees(est, truth, covs, angle_index):
    e = np.asarray(est, float) - np.asarray(truth, float)
    if angle_index is not None:
        e[:, angle_index] = wrap(e[:, angle_index])
    return np.array([ek @ np.linalg.solve(P, ek) for ek, P in zip(e, covs)])


def test_nees_matches_numpy_with_angle_wrapping():
    g = rng(30)
    n = 300
    truth = np.column_stack([g.uniform(-50, 50, n), g.uniform(-50, 50, n), g.uniform(0, 5, n),
                             g.uniform(-np.pi, np.pi, n)])
    est = truth + g.normal(scale=[0.5, 0.5, 0.2, 0.3], size=(n, 4))
    est[:, 3] += 2 * np.pi * g.integers(-3, 4, n)  # same heading, different branch
    # and headings on opposite sides of ±pi
    truth[:10, 3] = 3.1
    est[:10, 3] = -3.1
    covs = random_spd(g, n, 4)
    ours = metrics.nees(est, truth, covs)
    ref = numpy_nees(est, truth, covs, 3)
    np.testing.assert_allclose(ours, ref, rtol=1e-9)
    # the wrapping matters for this data: without it the values would be far off
    assert not np.allclose(ref, numpy_nees(est, truth, covs, None), rtol=1e-3)


def test_nees_angle_index_none_and_other_index():
    g = rng(31)
    n = 100
    truth = g.normal(size=(n, 3))
    est = truth + g.normal(size=(n, 3)) * 4.0
    covs = random_spd(g, n, 3)
    np.testing.assert_allclose(metrics.nees(est, truth, covs, angle_index=None),
                               numpy_nees(est, truth, covs, None), rtol=1e-9)
    np.testing.assert_allclose(metrics.nees(est, truth, covs, angle_index=1),
                               numpy_nees(est, truth, covs, 1), rtol=1e-9)


def test_nees_identity_covariance_is_squared_norm():
    e = np.array([[3.0, 4.0, 0.0, 0.0], [1.0, 2.0, 2.0, 0.5]])
    covs = np.tile(np.eye(4), (2, 1, 1))
    np.testing.assert_allclose(metrics.nees(e, np.zeros_like(e), covs), [25.0, 9.25], rtol=1e-14)


def test_nees_rejects_bad_input():
    g = rng(32)
    est = g.normal(size=(5, 4))
    covs = random_spd(g, 5, 4)
    with pytest.raises(ValueError):
        metrics.nees(est, est[:4], covs)
    with pytest.raises(ValueError):
        metrics.nees(est, est, covs[:, :3, :3])
    not_pd = covs.copy()
    not_pd[2] = -np.eye(4)
    with pytest.raises(ValueError, match="row 2"):
        metrics.nees(est, est + 0.1, not_pd)
    with pytest.raises(ValueError, match="angle_index"):
        metrics.nees(est[:, :3], est[:, :3], covs[:, :3, :3])  # default angle_index 3 out of range
    bad = est.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match=r"estimates\[\(3, 1\)\]"):
        metrics.nees(bad, est, covs)
    with pytest.raises(ValueError, match=r"truth\[\(3, 1\)\]"):
        metrics.nees(est, bad, covs)
    bad_cov = covs.copy()
    bad_cov[3, 0, 0] = np.nan
    with pytest.raises(ValueError, match=r"covariances\[\(3, 0, 0\)\]"):
        metrics.nees(est, est, bad_cov)


@pytest.mark.parametrize("dof,n_runs,probability", [(1, 1, 0.95), (2, 1, 0.99), (4, 1, 0.95), (4, 50, 0.95),
                                                    (2, 1000, 0.9), (3, 7, 0.5)])
def test_chi2_interval_vs_scipy(dof, n_runs, probability):
    lo, hi = metrics.chi2_interval(dof, n_runs, probability)
    alpha = 1 - probability
    assert lo == pytest.approx(stats.chi2.ppf(alpha / 2, dof * n_runs) / n_runs, rel=1e-12)
    assert hi == pytest.approx(stats.chi2.ppf(1 - alpha / 2, dof * n_runs) / n_runs, rel=1e-12)
    # as a probability statement: the interval holds `probability` of the mass of the averaged chi-square
    cdf = stats.chi2.cdf([lo * n_runs, hi * n_runs], dof * n_runs)
    assert cdf[1] - cdf[0] == pytest.approx(probability, abs=1e-9)
    assert lo < dof < hi


def test_chi2_interval_covers_simulated_average_nees():
    # consistent Gaussian errors: the M-run average NEES lands inside the 95 % interval ~95 % of the time
    g = rng(33)
    dim, M, trials = 4, 10, 4000
    covs = random_spd(g, trials * M, dim)
    chol = np.linalg.cholesky(covs)
    e = np.einsum("kij,kj->ki", chol, g.standard_normal((trials * M, dim)))
    truth = np.zeros((trials * M, dim))
    values = metrics.nees(e, truth, covs, angle_index=None)
    avg = values.reshape(trials, M).mean(axis=1)
    lo, hi = metrics.chi2_interval(dim, M, 0.95)
    inside = np.mean((avg >= lo) & (avg <= hi))
    assert inside == pytest.approx(0.95, abs=0.015)  # binomial sd ≈ 0.0034


# ---------------------------------------------------------------------------
# TrajectoryScore: the one accumulator of the simulator's trials and the replay


def _poses(n, dim, seed=3):
    rng = np.random.default_rng(seed)
    est = rng.normal(size=(n, dim))
    tru = est + 0.5 * rng.normal(size=(n, dim))
    A = rng.normal(size=(n, dim, dim))
    P = A @ A.transpose(0, 2, 1) + 0.1 * np.eye(dim)
    if dim == 4:
        est[:, 3] = rng.uniform(-np.pi, np.pi, n)
        tru[:, 3] = rng.uniform(-np.pi, np.pi, n)
    return est, P, tru


def test_trajectory_score_equals_the_textbook_formulas():
    """ADE, FDE, RMSE against the truth, the state NEES (θ wrapped, ext eq. 21–22
    and Bar-Shalom §5.4), the position NEES and the share outside 3σ."""
    n = 150
    est, P, tru = _poses(n, 4)
    acc = metrics.TrajectoryScore(10)               # grows past its capacity
    for i in range(n):
        acc.add(est[i], P[i], tru[i])
    e = tru - est
    e[:, 3] = (e[:, 3] + np.pi) % (2 * np.pi) - np.pi
    nees4 = np.einsum("ni,ni->n", e, np.linalg.solve(P, e[:, :, None])[:, :, 0])
    ep = e[:, :2]
    nees2 = np.einsum("ni,ni->n", ep, np.linalg.solve(P[:, :2, :2], ep[:, :, None])[:, :, 0])
    d = np.linalg.norm(est[:, :2] - tru[:, :2], axis=1)
    assert acc.size == n
    np.testing.assert_array_equal(acc.estimates, est[:, :2])
    assert acc.length == pytest.approx(np.linalg.norm(np.diff(est[:, :2], axis=0), axis=1).sum(), rel=1e-13)
    assert acc.truth_ade == pytest.approx(d.mean(), rel=1e-13)
    assert acc.truth_fde == pytest.approx(d[-1], rel=1e-14)
    assert acc.truth_rmse == pytest.approx(np.sqrt(np.mean(d ** 2)), rel=1e-13)
    assert acc.nees == pytest.approx(nees4.mean(), rel=1e-9) and acc.nees_poses == n
    assert acc.position_nees == pytest.approx(nees2.mean(), rel=1e-9) and acc.position_nees_poses == n
    assert acc.outside_3sigma == np.mean(nees2 > 9.0)


def test_trajectory_score_rows_equal_pose_by_pose():
    est, P, tru = _poses(40, 2)
    one, rows = metrics.TrajectoryScore(), metrics.TrajectoryScore(40)
    for i in range(40):
        one.add(est[i], P[i], tru[i])
    rows.add_rows(est, P.reshape(40, 4), tru)
    for name in ("truth_ade", "truth_fde", "truth_rmse", "position_nees", "outside_3sigma", "length"):
        assert getattr(one, name) == getattr(rows, name)
    assert math.isnan(one.nees) and one.nees_poses == 0   # positions only: no state NEES


def test_trajectory_score_without_a_positive_definite_covariance():
    """A singular P has no NEES and counts outside 3σ; an empty score is NaN."""
    acc = metrics.TrajectoryScore()
    assert acc.size == 0 and math.isnan(acc.truth_ade) and math.isnan(acc.outside_3sigma)
    acc.add(np.zeros(4), np.zeros((4, 4)), np.array([3.0, 4.0, 0.0, 0.0]))
    assert acc.truth_ade == 5.0 and acc.outside_3sigma == 1.0
    assert acc.nees_poses == 0 and acc.position_nees_poses == 0 and math.isnan(acc.nees)


def test_trajectory_score_bad_input_names_it():
    acc = metrics.TrajectoryScore()
    with pytest.raises(ValueError, match="not finite"):
        acc.add(np.array([np.nan, 0.0]), np.eye(2), np.zeros(2))
    with pytest.raises(ValueError, match="position"):
        acc.add(np.zeros(3), np.eye(3), np.zeros(3))
    with pytest.raises(ValueError, match="covariance is 2x2"):
        acc.add(np.zeros(4), np.eye(2), np.zeros(4))
    with pytest.raises(ValueError, match="add_rows"):
        acc.add_rows(np.zeros((3, 2)), np.zeros((2, 4)), np.zeros((3, 2)))
    assert acc.size == 0

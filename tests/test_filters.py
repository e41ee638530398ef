"""Filter behaviour not covered by the FilterPy and consistency tests:
NIS gate, PF log-weights, systematic resampling, PF estimates, determinism,
measurement streams with gaps, and NIS statistics."""

from __future__ import annotations

import numpy as np
import pytest

import safenav
from safenav import BmmParams, MeasurementModel
from safenav.metrics import chi2_interval

PARAMS = BmmParams()
X0 = np.array([0.0, 0.0, 2.0, 0.2])
P0 = np.diag([0.2, 0.2, 0.1, 0.05]) ** 2
R = np.diag([0.05, 0.05]) ** 2
POS = MeasurementModel.position(R)


def test_nis_gate_rejects_outliers_and_keeps_the_estimate():
    ekf = safenav.Ekf(PARAMS, X0, P0, gate=0.99)
    ekf.predict([2.0, 0.0])
    x, P = ekf.x.copy(), ekf.P.copy()
    res = ekf.update(POS, x[:2] + [5.0, 0.0])  # 5 m off: far outside the 99 % gate
    assert not res.accepted and res.nis > safenav._core.chi2_quantile(0.99, 2)
    np.testing.assert_array_equal(ekf.x, x)
    np.testing.assert_array_equal(ekf.P, P)
    good = ekf.update(POS, x[:2] + [0.01, -0.01])
    assert good.accepted and good.nis < safenav._core.chi2_quantile(0.99, 2)
    # NIS is yᵀ S⁻¹ y with S = H P Hᵀ + R
    S = P[:2, :2] + R
    y = np.array([0.01, -0.01])
    assert good.nis == pytest.approx(y @ np.linalg.solve(S, y), rel=1e-12)


@pytest.mark.parametrize("model", ["position", "range", "bearing", "range_bearing"])
def test_log_det_s_is_that_of_the_updates_innovation_covariance(model):
    """UpdateResult.log_det_s = log det(H P Hᵀ + R) [SafeNav eq. 12] of the
    update's own S (with its NIS, the innovation likelihood), accepted or
    gated out; the information filter reports the same."""
    lm = np.array([[6.0, 4.0]])
    m = {"position": POS, "range": MeasurementModel.range(lm, 0.3), "bearing": MeasurementModel.bearing(lm, 0.05),
         "range_bearing": MeasurementModel.range_bearing(lm, 0.3, 0.05)}[model]
    for gate, offset in ((0.0, 0.05), (0.99, 50.0)):
        ekf = safenav.Ekf(PARAMS, X0, P0, gate=gate)
        ekf.predict([2.0, 0.1])
        x, P = ekf.x.copy(), ekf.P.copy()
        H = m.jacobian(x)
        want = np.linalg.slogdet(H @ P @ H.T + m.R)[1]
        z = m.predict(x) + offset
        res = ekf.update(m, z)
        assert res.accepted == (gate == 0.0)
        assert res.log_det_s == pytest.approx(want, abs=1e-10)
        eif = safenav.InformationFilter(PARAMS, x, P)
        assert eif.update(m, z).log_det_s == pytest.approx(want, abs=1e-10)


def test_batch_gate_counts_rejections():
    rng = np.random.default_rng(0)
    n = 200
    u = np.tile([2.0, 0.0], (n, 1))
    truth = safenav.Bmm(PARAMS).simulate(X0, u, seed=1)
    z = truth[1:, :2] + rng.standard_normal((n, 2)) * 0.05
    z[50] += 10.0  # two gross outliers
    z[120] -= 10.0
    gated = safenav.filter_trajectory(u, X0, P0, params=PARAMS, position=z, position_cov=R, gate=0.999)
    plain = safenav.filter_trajectory(u, X0, P0, params=PARAMS, position=z, position_cov=R)
    assert gated.n_rejected == 2 and gated.n_updates == n - 2
    err = lambda r: np.abs(r.states[51, :2] - truth[51, :2]).max()
    assert err(gated) < 0.1 < err(plain)


def test_pf_log_weights_survive_a_wildly_unlikely_measurement():
    pf = safenav.ParticleFilter(PARAMS, X0, P0, n_particles=500, seed=3)
    pf.predict([2.0, 0.0])
    pf.update(POS, [1e4, -1e4])  # every particle's likelihood underflows in linear space
    w = pf.weights
    assert np.isfinite(w).all() and w.sum() == pytest.approx(1.0) and (w >= 0).all()
    assert np.isfinite(pf.x).all() and np.isfinite(pf.P).all()


def test_pf_resamples_systematically_when_ess_drops():
    # The SIR filter (bandwidth_scale 0): the regularised one redraws every
    # particle from its kernel, so its particles are no longer exact copies.
    pf = safenav.ParticleFilter(PARAMS, X0, P0, n_particles=1000, seed=5, resample_threshold=0.5,
                                bandwidth_scale=0.0)
    assert pf.ess == pytest.approx(1000)
    pf.predict([2.0, 0.0])
    before = pf.particles.copy()
    pf.update(POS, before[:, :2].mean(axis=0) + [0.1, 0.0])
    assert pf.resample_count == 1 and pf.ess == pytest.approx(1000)  # weights reset to 1/N
    # every resampled particle is one of the particles before resampling
    after = pf.particles
    assert all((np.abs(before - p).sum(axis=1) == 0).any() for p in after[::50])
    # no resampling while ESS stays above threshold
    pf2 = safenav.ParticleFilter(PARAMS, X0, P0, n_particles=1000, seed=5, resample_threshold=0.0,
                                 bandwidth_scale=0.0)
    pf2.predict([2.0, 0.0])
    pf2.update(POS, pf2.x[:2])
    assert pf2.resample_count == 0 and pf2.ess < 1000


def test_systematic_resampling_preserves_weights_in_expectation():
    # Over many seeds, the share of copies of each particle matches its weight.
    # Systematic resampling gives particle i floor(N w_i) copies plus one more
    # with probability f_i = frac(N w_i): the count minus N w_i has mean 0 and
    # variance f_i (1 - f_i).  Summed over seeds, the gap must stay within a
    # few of its standard deviations (4 sd: a false alarm about once in 10^4).
    # The SIR filter (bandwidth_scale 0), whose particles are exact copies.
    n, counts, wsum, var = 50, np.zeros(50), np.zeros(50), np.zeros(50)
    for seed in range(300):
        pf = safenav.ParticleFilter(PARAMS, X0, P0 * 100, n_particles=n, seed=seed, resample_threshold=1.0,
                                    bandwidth_scale=0.0)
        parts = pf.particles
        pf.update(POS, X0[:2])
        w = np.exp(-0.5 * np.sum((parts[:, :2] - X0[:2]) ** 2 / np.diag(R), axis=1))
        w /= w.sum()
        order = np.argsort(w)[::-1]
        after = pf.particles
        copies = np.array([(np.abs(after - parts[i]).sum(axis=1) == 0).sum() for i in order])
        # systematic resampling: copies of particle i is floor or ceil of N·w_i
        assert np.all(np.abs(copies - n * w[order]) < 1.0 + 1e-9)
        counts += copies
        wsum += n * w[order]
        frac = n * w[order] - np.floor(n * w[order])
        var += frac * (1.0 - frac)
    assert np.all(np.abs(counts - wsum) <= 4.0 * np.sqrt(var) + 1e-6), (counts - wsum, np.sqrt(var))


def test_pf_mean_and_covariance_match_numpy_from_particles():
    pf = safenav.ParticleFilter(PARAMS, np.array([1.0, 2.0, 1.5, 3.1]), np.diag([0.3, 0.3, 0.2, 0.2]) ** 2,
                                n_particles=2000, seed=9, resample_threshold=0.0)
    pf.predict([1.5, 0.05])
    pf.update(POS, [1.1, 2.0])
    X, w = pf.particles, pf.weights
    mean = X[:, :3].T @ w
    theta = np.arctan2(w @ np.sin(X[:, 3]), w @ np.cos(X[:, 3]))  # circular mean near ±π
    np.testing.assert_allclose(pf.x, [*mean, theta], atol=1e-12)
    d = X - pf.x
    d[:, 3] = (d[:, 3] + np.pi) % (2 * np.pi) - np.pi
    np.testing.assert_allclose(pf.sample_covariance, (d * w[:, None]).T @ d, atol=1e-12)
    # the reported covariance is that one floored by the kernel covariance h² C_u of the unweighted cloud
    # (binding here: no resampling, so the weights are far from uniform)
    F = pf.bandwidth**2 * np.cov(X.T, bias=True)
    np.testing.assert_allclose(pf.covariance_floor[:3, :3], F[:3, :3], rtol=1e-9)
    for B in (pf.sample_covariance, pf.covariance_floor):
        assert np.linalg.eigvalsh(pf.P - B).min() > -1e-12


def test_pf_is_deterministic_for_a_seed():
    u = np.tile([2.0, 0.02], (60, 1))
    z = safenav.Bmm(PARAMS).simulate(X0, u, seed=2)[1:, :2]
    run = lambda seed: safenav.filter_trajectory(u, X0, P0, params=PARAMS, filter="pf", position=z,
                                                 position_cov=R, n_particles=300, seed=seed)
    a, b, c = run(4), run(4), run(5)
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.covariances, b.covariances)
    assert not np.array_equal(a.states, c.states)


_SAME_NUMBERS_SCRIPT = """
import hashlib, sys
import numpy as np
import safenav
u = np.tile([2.0, 0.03], (40, 1))
truth = safenav.Bmm(safenav.BmmParams()).simulate([0.0, 0.0, 2.0, 0.2], u, seed=2)
lm = np.array([[5.0, 5.0], [-3.0, 8.0]])
d = lm[None] - truth[1:, None, :2]
h = hashlib.sha256()
for n in (1, 3, 6, 1000, 1001):
    r = safenav.filter_trajectory(u, [0.0, 0.0, 2.0, 0.2], np.diag([0.04, 0.04, 0.01, 0.0025]), filter="pf",
                                  position=truth[1:, :2], position_cov=np.eye(2) * 0.01,
                                  ranges=np.hypot(d[..., 0], d[..., 1]), range_std=0.3, landmarks=lm,
                                  speed_heading=truth[1:, 2:], speed_heading_cov=np.diag([0.01, 0.0004]),
                                  n_particles=n, seed=n)
    for a in (r.states, r.covariances, r.nis):
        h.update(np.ascontiguousarray(a).tobytes())
print(h.hexdigest())
"""


def test_pf_gives_the_same_numbers_with_and_without_avx2():
    # The PF's hot loops have an AVX2 copy chosen at run time; SAFENAV_NO_AVX2
    # forces the baseline copy.  Both must give the same bits for a seed (on a
    # CPU without AVX2 both runs take the baseline copy).
    import os
    import subprocess
    import sys

    def digest(no_avx2):
        env = {k: v for k, v in os.environ.items() if k != "SAFENAV_NO_AVX2"}
        if no_avx2:
            env["SAFENAV_NO_AVX2"] = "1"
        out = subprocess.run([sys.executable, "-c", _SAME_NUMBERS_SCRIPT], env=env, capture_output=True, text=True,
                             timeout=600, check=True)
        return out.stdout.strip().splitlines()[-1]

    assert digest(False) == digest(True)


def test_stream_gaps_and_partial_landmark_visibility():
    n = 80
    u = np.tile([2.0, 0.03], (n, 1))
    truth = safenav.Bmm(PARAMS).simulate(X0, u, seed=6)
    lm = np.array([[5.0, 5.0], [-3.0, 4.0], [8.0, -2.0]])
    rng = np.random.default_rng(1)
    d = lm[None] - truth[1:, None, :2]
    ranges = np.hypot(d[..., 0], d[..., 1]) + rng.standard_normal((n, 3)) * 0.05
    ranges[::3, 1] = np.nan          # landmark 1 unseen every third step
    ranges[40:50] = np.nan           # nothing seen for 10 steps
    for f in ("ekf", "eif", "pf"):
        res = safenav.filter_trajectory(u, X0, P0, params=PARAMS, filter=f, ranges=ranges, range_std=0.05,
                                        landmarks=lm, n_particles=2000, seed=0)
        assert res.n_gaps == 10
        assert np.isnan(res.nis[40:50]).all() and (res.nis_dof[40:50] == 0).all()
        assert (res.nis_dof[0:3] == [2, 3, 3]).all()
        # uncertainty grows through the blackout, then the fixes pull it back
        assert res.covariances[50, 0, 0] > res.covariances[40, 0, 0]
        assert np.abs(res.states[-1, :2] - truth[-1, :2]).max() < 0.15


def test_ekf_nis_is_chi_square_distributed():
    rng = np.random.default_rng(2)
    n = 400
    params = BmmParams(speed_noise=0.02, heading_noise=0.005, position_noise=0.005)
    # Desired speed alternates ±50 m/s: eq. 3 always moves v by ±a·Δt, so no
    # limit binds and the speed update stays linear.
    u = np.column_stack([np.where(np.arange(n) % 2 == 0, 50.0, -50.0), np.full(n, 0.01)])
    x0 = np.array([0.0, 0.0, 3.0, 0.0])
    nis = []
    for run in range(20):
        truth = safenav.Bmm(params).simulate(x0, u, seed=100 + run)
        z = truth[1:, :2] + rng.standard_normal((n, 2)) * 0.05
        start = x0 + rng.standard_normal(4) * np.sqrt(np.diag(P0))
        res = safenav.filter_trajectory(u, start, P0, params=params, position=z, position_cov=R)
        nis.append(res.nis)
    nis = np.concatenate(nis)
    lo, hi = chi2_interval(2, len(nis))
    assert lo < nis.mean() < hi

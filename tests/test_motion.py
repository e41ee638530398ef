"""The Battlefield Motion Model (SafeNav eqs. 3-9): limits, the cases of eq. 3,
the heading clip of eq. 4, the terrain factor, angle wrapping, and the
seeded simulator's noise."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from safenav import Bmm, BmmParams, wrap_angle

TWO_PI = 2.0 * np.pi


def _random_params(rng):
    return BmmParams(acceleration=rng.uniform(0.5, 5.0), deceleration=rng.uniform(0.5, 5.0),
                     max_speed=rng.uniform(1.0, 15.0), max_heading_rate=rng.uniform(0.2, 3.0),
                     dt=rng.uniform(0.01, 0.5), terrain_effect=rng.uniform(0.0, 2.0),
                     speed_noise=rng.uniform(0.0, 2.0), heading_noise=rng.uniform(0.0, 0.5),
                     position_noise=rng.uniform(0.0, 0.5))


def _random_state(rng, p):
    return np.array([rng.uniform(-100, 100), rng.uniform(-100, 100), rng.uniform(0.0, p.max_speed),
                     rng.uniform(-np.pi, np.pi)])


def _random_control(rng, p):
    return np.array([rng.uniform(-3.0, p.max_speed + 5.0), rng.uniform(-2.0, 2.0)])


# ---------------------------------------------------------------------------
# Limits
# ---------------------------------------------------------------------------

def test_predict_respects_speed_and_heading_rate_limits():
    rng = np.random.default_rng(101)
    hit = {"vmax": 0, "zero": 0, "clip": 0}
    for _ in range(40):
        p = _random_params(rng)
        bmm = Bmm(p)
        lim = p.max_heading_rate * p.dt
        for _ in range(50):
            x, u = _random_state(rng, p), _random_control(rng, p)
            x1 = bmm.predict(x, u)
            assert 0.0 <= x1[2] <= p.max_speed, (p, x, u, x1)
            dth = float(wrap_angle(x1[3] - x[3]))
            assert abs(dth) <= lim * (1 + 1e-12) + 1e-15, (p, x, u, x1)
            assert -np.pi < x1[3] <= np.pi
            hit["vmax"] += x1[2] == p.max_speed
            hit["zero"] += x1[2] == 0.0
            hit["clip"] += abs(abs(dth) - lim) < 1e-12
    # the limits were actually exercised
    assert min(hit.values()) > 10, hit


def test_transition_with_noise_keeps_speed_in_range():
    rng = np.random.default_rng(102)
    clamped = 0
    for _ in range(20):
        p = _random_params(rng)
        bmm = Bmm(p)
        for _ in range(50):
            x, u = _random_state(rng, p), _random_control(rng, p)
            eps = rng.normal(0.0, [0.1, 0.1, 3.0, 0.5])  # large speed noise: pushes past both limits
            x1 = bmm.transition(x, u, eps)
            assert 0.0 <= x1[2] <= p.max_speed
            assert -np.pi < x1[3] <= np.pi
            clamped += x1[2] in (0.0, p.max_speed)
    assert clamped > 100


def test_simulate_keeps_speed_in_range():
    rng = np.random.default_rng(103)
    clamped = 0
    for seed in range(20):
        p = _random_params(rng)
        p.speed_noise = 1.5  # big enough to push past 0 and v_max often
        bmm = Bmm(p)
        x0 = _random_state(rng, p)
        controls = np.column_stack([rng.uniform(-3.0, p.max_speed + 5.0, 200), rng.uniform(-1, 1, 200)])
        traj = bmm.simulate(x0, controls, seed=seed)
        assert traj.shape == (201, 4)
        np.testing.assert_array_equal(traj[0], x0)
        assert np.all(traj[:, 2] >= 0.0) and np.all(traj[:, 2] <= p.max_speed)
        assert np.all(traj[1:, 3] > -np.pi) and np.all(traj[1:, 3] <= np.pi)
        clamped += np.sum(traj[1:, 2] == 0.0) + np.sum(traj[1:, 2] == p.max_speed)
    assert clamped > 100


# ---------------------------------------------------------------------------
# Eq. 3 and eq. 4 case by case
# ---------------------------------------------------------------------------

# a*dt = 0.2, d*dt = 0.4, v_max = 5
EQ3 = BmmParams(acceleration=2.0, deceleration=4.0, max_speed=5.0, max_heading_rate=1.5, dt=0.1)


@pytest.mark.parametrize("v, desired, expected, rate_limited", [
    (1.0, 3.0, 1.2, True),     # speeding up, limited by a*dt
    (1.0, 1.1, 1.1, False),    # speeding up, limited by v_desired
    (4.9, 8.0, 5.0, False),    # speeding up, limited by v_max
    (3.0, 1.0, 2.6, True),     # slowing down, limited by d*dt
    (3.0, 2.8, 2.8, False),    # slowing down, limited by v_desired
    (0.3, -1.0, 0.0, False),   # slowing down, limited by 0
    (2.0, 2.0, 2.0, False),    # v_desired == v: the second case of eq. 3 returns v
], ids=["accel-a", "accel-desired", "accel-vmax", "decel-d", "decel-desired", "decel-zero", "hold"])
def test_eq3_cases(v, desired, expected, rate_limited):
    bmm = Bmm(EQ3)
    x = np.array([1.0, 2.0, v, 0.4])
    u = np.array([desired, 0.0])
    assert bmm.next_speed(v, desired) == pytest.approx(expected, abs=1e-12)
    x1 = bmm.predict(x, u)
    assert x1[2] == pytest.approx(expected, abs=1e-12)
    # dv'/dv is 1 where v -/+ rate*dt is the active term of eq. 3, else 0
    assert bmm.jacobian(x, u)[2, 2] == (1.0 if rate_limited else 0.0)
    # position moves with the *updated* speed (eq. 7)
    assert np.hypot(*(x1[:2] - x[:2])) == pytest.approx(expected * EQ3.dt, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("dtheta, expected", [(1.0, 0.15), (-1.0, -0.15), (0.05, 0.05), (-0.149, -0.149)])
def test_eq4_heading_clip(dtheta, expected):
    bmm = Bmm(EQ3)  # m*dt = 0.15
    x = np.array([0.0, 0.0, 1.0, 0.3])
    x1 = bmm.predict(x, np.array([1.0, dtheta]))
    assert x1[3] == pytest.approx(0.3 + expected, abs=1e-14)
    assert bmm.clipped_heading_change(dtheta) == pytest.approx(expected, abs=1e-15)


def test_heading_wraps_across_pi():
    bmm = Bmm(EQ3)
    x1 = bmm.predict(np.array([0.0, 0.0, 1.0, np.pi - 0.05]), np.array([1.0, 0.1]))
    assert x1[3] == pytest.approx(-np.pi + 0.05, abs=1e-12)


# ---------------------------------------------------------------------------
# Terrain effect (eqs. 8-9 as read in motion.py): displacement scaled by 1/(1+tau)
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("tau", [0.0, 0.3, 1.0, 4.0])
def test_terrain_effect_scales_displacement(tau):
    base = dict(acceleration=2.0, deceleration=2.0, max_speed=10.0, max_heading_rate=1.0, dt=0.2)
    flat = Bmm(BmmParams(**base))
    rough = Bmm(BmmParams(**base, terrain_effect=tau))
    x = np.array([3.0, -1.0, 2.0, 0.7])
    u = np.array([2.5, 0.1])  # v' = 2.4 (a*dt limited), theta' = 0.8
    d_flat = flat.predict(x, u)[:2] - x[:2]
    d_rough = rough.predict(x, u)[:2] - x[:2]
    np.testing.assert_allclose(d_rough, d_flat / (1.0 + tau), rtol=1e-12)
    np.testing.assert_allclose(d_rough, 2.4 * 0.2 / (1.0 + tau) * np.array([np.cos(0.8), np.sin(0.8)]), rtol=1e-12)
    # speed and heading are unaffected by tau
    np.testing.assert_allclose(rough.predict(x, u)[2:], flat.predict(x, u)[2:], rtol=0, atol=0)
    # the same scaling in the noise-free simulator
    quiet = dict(speed_noise=0.0, heading_noise=0.0, position_noise=0.0)
    sim = Bmm(BmmParams(**base, terrain_effect=tau, **quiet)).simulate(x, u[None, :], seed=3)
    np.testing.assert_allclose(sim[1], rough.predict(x, u), rtol=1e-12)
    # and in the Jacobian: d x'/d theta = -k v' sin theta' with k = dt/(1+tau)
    assert rough.jacobian(x, u)[0, 3] == pytest.approx(-0.2 / (1 + tau) * 2.4 * np.sin(0.8), rel=1e-12)


# ---------------------------------------------------------------------------
# wrap_angle
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("a, expected", [
    (np.pi, np.pi), (-np.pi, np.pi), (0.0, 0.0), (TWO_PI, 0.0), (3 * np.pi, np.pi), (-3 * np.pi, np.pi),
    (np.pi / 2 + TWO_PI, np.pi / 2), (-np.pi / 2 - 4 * np.pi, -np.pi / 2), (1.0, 1.0), (-1.0, -1.0),
])
def test_wrap_angle_values(a, expected):
    assert float(wrap_angle(a)) == pytest.approx(expected, abs=1e-12)


def test_wrap_angle_pi_exact():
    assert float(wrap_angle(np.pi)) == np.pi
    assert float(wrap_angle(-np.pi)) == np.pi
    assert float(wrap_angle(np.nextafter(-np.pi, 0.0))) == np.nextafter(-np.pi, 0.0)


def test_wrap_angle_random_range_and_congruence():
    rng = np.random.default_rng(104)
    a = np.concatenate([rng.uniform(-60, 60, 5000), rng.uniform(-1e6, 1e6, 500),
                        np.arange(-20, 21) * np.pi])
    w = np.asarray(wrap_angle(a))
    assert w.shape == a.shape
    assert np.all(w > -np.pi) and np.all(w <= np.pi)
    turns = (a - w) / TWO_PI
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9 * np.maximum(1, np.abs(a)).max())
    inside = (a > -np.pi) & (a <= np.pi)
    np.testing.assert_array_equal(w[inside], a[inside])


# ---------------------------------------------------------------------------
# simulate: seeding and noise
# ---------------------------------------------------------------------------

def _controls(n=60):
    k = np.arange(n)
    return np.column_stack([2.0 + 0.5 * np.sin(k / 7), 0.03 * np.cos(k / 5)])


def test_simulate_deterministic_for_seed_and_differs_across_seeds():
    bmm = Bmm(BmmParams())
    x0 = np.array([0.0, 0.0, 2.0, 0.1])
    c = _controls()
    a = bmm.simulate(x0, c, seed=5)
    b = bmm.simulate(x0, c, seed=5)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(Bmm(BmmParams()).simulate(x0, c, seed=5), a)
    others = [bmm.simulate(x0, c, seed=s) for s in (6, 7, 2**63 + 5)]
    for o in others:
        assert np.all(np.abs(o[1:] - a[1:]).max(axis=0) > 0)
        assert not np.allclose(o[1:], a[1:])


def test_simulate_without_noise_equals_predict():
    p = BmmParams(speed_noise=0.0, heading_noise=0.0, position_noise=0.0, terrain_effect=0.5)
    bmm = Bmm(p)
    x = np.array([1.0, 2.0, 1.5, -0.4])
    traj = bmm.simulate(x, _controls(), seed=1)
    for k, u in enumerate(_controls()):
        x = bmm.predict(x, u)
        np.testing.assert_allclose(traj[k + 1], x, rtol=1e-13, atol=1e-14)


def test_simulate_one_step_noise_matches_process_cov():
    p = BmmParams(acceleration=3.0, deceleration=3.0, max_speed=10.0, max_heading_rate=1.5, dt=0.1,
                  terrain_effect=0.2, speed_noise=0.4, heading_noise=0.03, position_noise=0.01)
    bmm = Bmm(p)
    x0 = np.array([5.0, -2.0, 3.0, 0.9])
    u = np.array([3.1, 0.05])
    n = 20000
    ones = u[None, :]
    samples = np.array([bmm.simulate(x0, ones, seed=s)[1] for s in range(n)])
    mean = bmm.predict(x0, u)
    Q = bmm.process_cov(x0, u)
    # Q has strong x-v, y-v and x-theta correlations: the test is not only about the diagonal
    corr = Q / np.sqrt(np.outer(np.diag(Q), np.diag(Q)))
    assert np.abs(corr - np.eye(4)).max() > 0.5
    L = np.linalg.cholesky(Q)
    d = samples - mean
    d[:, 3] = np.asarray(wrap_angle(d[:, 3]))
    w = np.linalg.solve(L, d.T).T  # whitened: ~ N(0, I) if Q is right
    # mean: n * |mean(w)|^2 ~ chi2(4)
    assert n * np.sum(w.mean(axis=0) ** 2) < stats.chi2.ppf(1 - 1e-4, 4)
    # covariance: each entry of the sample covariance of w within 5 sigma of I
    C = np.cov(w.T)
    sd = np.sqrt((np.ones((4, 4)) + np.eye(4)) / n)
    assert np.all(np.abs(C - np.eye(4)) < 5 * sd), C
    # and the raw covariance, entry by entry, relative to scale
    scale = np.sqrt(np.outer(np.diag(Q), np.diag(Q)))
    assert np.all(np.abs(np.cov(d.T) - Q) < 0.05 * scale), (np.cov(d.T), Q)

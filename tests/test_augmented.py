"""AugmentedEkf (augmented.hpp): the EKF of [SafeNav eqs. 10–14] over the BMM
of [SafeNav eqs. 3–9] with optional augmented states — range scale k,
heading-rate bias β, per-landmark range biases b_j (ours, not the paper's).

A compact numpy reference below writes the equations out; single predict and
update steps of the C++ filter must match it to rounding, its Jacobians must
match finite differences, and the augmented states must converge on
synthetic data with a known scale and gyro bias."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st

from safenav import _core
from safenav import guidance as gd

LANDMARKS = np.array([(-20.0, -20.0), (20.0, -20.0), (20.0, 20.0), (-20.0, 20.0)])


def bmm(dt=0.2, **kw):
    p = dict(acceleration=3.0, deceleration=3.0, max_speed=10.0, max_heading_rate=1.5, dt=dt, terrain_effect=0.0,
             speed_noise=0.05, heading_noise=0.01, position_noise=0.02)
    p.update(kw)
    return _core.BmmParams(**p)


def augment(scale=True, gyro=True, bias=False, **kw):
    a = _core.AugmentedStates()
    a.range_scale, a.heading_rate_bias, a.range_bias = scale, gyro, bias
    for k, v in kw.items():
        setattr(a, k, v)
    return a


# --------------------------------------------------------------------------- numpy reference

def wrap(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class Ref:
    """The equations of augmented.hpp, written out with dense matrices."""

    def __init__(self, p, a, n_landmarks):
        self.p, self.a = p, a
        n = 4
        self.ik = self.ig = self.ib = None
        if a.range_scale:
            self.ik, n = n, n + 1
        if a.heading_rate_bias:
            self.ig, n = n, n + 1
        if a.range_bias:
            self.ib, n = n, n + n_landmarks
        self.n, self.K = n, n_landmarks

    def f(self, x, u, dt):
        """Mean of the prediction and F = ∂f/∂x, G = ∂f/∂ε (eqs. 3, 4, 7 with θ' = θ + clip(Δθ) − β·dt)."""
        p = self.p
        v, desired = x[2], u[0]
        if desired > v:
            v1 = max(0.0, min(v + p.acceleration * dt, desired, p.max_speed))
            up = v + p.acceleration * dt
            dv = 1.0 if (up <= desired and up <= p.max_speed and up >= 0.0) else 0.0
        else:
            v1 = min(p.max_speed, max(v - p.deceleration * dt, desired, 0.0))
            down = v - p.deceleration * dt
            dv = 1.0 if (down >= desired and down >= 0.0 and down <= p.max_speed) else 0.0
        lim = p.max_heading_rate * dt
        beta = x[self.ig] if self.ig is not None else 0.0
        th1 = wrap((x[3] - beta * dt) + min(max(u[1], -lim), lim))
        k = dt / (1.0 + p.terrain_effect)
        c, s = math.cos(th1), math.sin(th1)
        x1 = x.copy()
        x1[:4] = (x[0] + k * v1 * c, x[1] + k * v1 * s, v1, th1)
        F = np.eye(self.n)
        F[0, 2], F[0, 3], F[1, 2], F[1, 3], F[2, 2] = k * c * dv, -k * v1 * s, k * s * dv, k * v1 * c, dv
        if self.ig is not None:
            F[:4, self.ig] = -dt * F[:4, 3]
        G = np.eye(4)
        G[0, 2], G[0, 3], G[1, 2], G[1, 3] = k * c, -k * v1 * s, k * s, k * v1 * c
        return x1, F, G

    def predict(self, x, P, u, dt):
        p, a = self.p, self.a
        x1, F, G = self.f(x, u, dt)
        sc = 1.0 if abs(dt - p.dt) <= 1e-6 * p.dt else math.sqrt(dt / p.dt)
        sig = np.array([p.position_noise, p.position_noise, p.speed_noise, p.heading_noise]) * sc
        Q = np.zeros((self.n, self.n))
        Q[:4, :4] = G @ np.diag(sig ** 2) @ G.T
        if self.ik is not None:
            Q[self.ik, self.ik] = a.scale_walk ** 2 * dt
        if self.ig is not None:
            Q[self.ig, self.ig] = a.heading_rate_bias_walk ** 2 * dt
        if self.ib is not None:
            Q[self.ib:, self.ib:] = np.eye(self.K) * a.range_bias_walk ** 2 * dt
        P1 = F @ P @ F.T + Q
        return x1, 0.5 * (P1 + P1.T)

    def h_range(self, x, row, lm):
        k = x[self.ik] if self.ik is not None else 0.0
        b = x[self.ib + row] if self.ib is not None else 0.0
        return (1.0 + k) * math.hypot(x[0] - lm[0], x[1] - lm[1]) + b

    def H_range(self, x, row, lm):
        dx, dy = x[0] - lm[0], x[1] - lm[1]
        rho = math.hypot(dx, dy)
        k = x[self.ik] if self.ik is not None else 0.0
        H = np.zeros(self.n)
        H[0], H[1] = (1.0 + k) * dx / rho, (1.0 + k) * dy / rho
        if self.ik is not None:
            H[self.ik] = rho
        if self.ib is not None:
            H[self.ib + row] = 1.0
        return H

    def h_bearing(self, x, lm):
        return math.atan2(lm[1] - x[1], lm[0] - x[0]) - x[3]

    def H_bearing(self, x, lm):
        dx, dy = lm[0] - x[0], lm[1] - x[1]
        r2 = dx * dx + dy * dy
        H = np.zeros(self.n)
        H[0], H[1], H[3] = dy / r2, -dx / r2, -1.0
        return H

    @staticmethod
    def update(x, P, y, H, R):
        """Eqs. 12–14, Joseph form."""
        H, R, y = np.atleast_2d(H), np.atleast_2d(R), np.atleast_1d(y)
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        x1 = x + K @ y
        x1[3] = wrap(x1[3])
        A = np.eye(len(x)) - K @ H
        P1 = A @ P @ A.T + K @ R @ K.T
        return x1, 0.5 * (P1 + P1.T), float(y @ np.linalg.solve(S, y))


def random_prior(n, rng):
    A = rng.normal(size=(n, n)) * 0.1
    return A @ A.T + np.eye(n) * 0.01


def make(p=None, a=None, x=None, P=None, seed=0, K=len(LANDMARKS)):
    p = p or bmm()
    a = a or augment(bias=True)
    f = _core.AugmentedEkf(p, a, K, np.zeros(4), np.eye(4))
    ref = Ref(p, a, K)
    rng = np.random.default_rng(seed)
    if x is None:
        x = np.concatenate([[1.0, -2.0, 1.2, 0.4], rng.normal(size=ref.n - 4) * 0.02])
    if P is None:
        P = random_prior(ref.n, rng)
    f.set_state(x, P)
    return f, ref, x, P


# --------------------------------------------------------------------------- layout and prior

def test_state_layout_and_prior_come_from_the_settings():
    a = augment(bias=True, scale_prior=0.05, scale_std=0.03, heading_rate_bias_std=0.02, range_bias_std=0.4)
    f = _core.AugmentedEkf(bmm(), a, 3, np.array([1.0, 2.0, 0.5, 0.1]), np.eye(4) * 0.1)
    assert f.size == 4 + 1 + 1 + 3
    assert (f.scale_index, f.heading_rate_bias_index, f.range_bias_index(0), f.range_bias_index(2)) == (4, 5, 6, 8)
    np.testing.assert_array_equal(f.augmented, [1.0, 2.0, 0.5, 0.1, 0.05, 0.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(np.diag(f.augmented_cov), [0.1] * 4 + [0.03 ** 2, 0.02 ** 2] + [0.4 ** 2] * 3)
    np.testing.assert_array_equal(f.x, f.augmented[:4])
    np.testing.assert_array_equal(f.P, f.augmented_cov[:4, :4])
    g = _core.AugmentedEkf(bmm(), augment(scale=False, gyro=True), 3, np.zeros(4), np.eye(4))
    assert (g.size, g.scale_index, g.heading_rate_bias_index, g.range_bias_index(1)) == (5, -1, 4, -1)


def test_defaults_are_off_and_declared():
    a = _core.AugmentedStates()
    assert not a.any() and not (a.range_scale or a.heading_rate_bias or a.range_bias)
    names = [s.name for s in _core.AugmentedStates.params()]
    assert names == ["scale_prior", "scale_std", "scale_walk", "heading_rate_bias_prior", "heading_rate_bias_std",
                     "heading_rate_bias_walk", "range_bias_std", "range_bias_walk"]
    a.check_params()
    assert (a.scale_prior, a.scale_std, a.scale_walk) == (0.07, 0.02, 1e-5)  # ref.DEFAULTS (Plaza1 tuning)
    with pytest.raises(ValueError, match="scale_std = -1"):
        a.set_param("scale_std", -1.0)
    assert not _core.LocalizerSettings().augment.any()


# --------------------------------------------------------------------------- single steps against the reference

@pytest.mark.parametrize("dt", [0.2, 0.05, 0.37])
@pytest.mark.parametrize("u", [(1.0, 0.05), (3.0, -0.6), (0.0, 0.0)])
def test_predict_matches_the_reference(dt, u):
    f, ref, x, P = make()
    f.predict(np.array(u), dt)
    x1, P1 = ref.predict(x, P, np.array(u), dt)
    np.testing.assert_allclose(f.augmented, x1, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(f.augmented_cov, P1, rtol=1e-12, atol=1e-15)


def test_updates_match_the_reference():
    f, ref, x, P = make()
    lm = LANDMARKS[2]
    # range: r = (1+k)|p - a| + b_2
    r = ref.h_range(x, 2, lm) + 0.3
    res = f.update_range(2, lm, r, 0.25)
    x1, P1, nis = ref.update(x, P, r - ref.h_range(x, 2, lm), ref.H_range(x, 2, lm), 0.25)
    assert res.accepted and res.dim == 1 and res.nis == pytest.approx(nis, rel=1e-12)
    np.testing.assert_allclose(f.augmented, x1, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(f.augmented_cov, P1, rtol=1e-11, atol=1e-15)
    # bearing: not affected by k or b
    x, P = x1, P1
    b = ref.h_bearing(x, lm) - 0.02
    f.update_bearing(2, lm, b, 0.01 ** 2)
    x1, P1, _ = ref.update(x, P, wrap(b - ref.h_bearing(x, lm)), ref.H_bearing(x, lm), 0.01 ** 2)
    assert ref.H_bearing(x, lm)[4:].tolist() == [0.0] * (ref.n - 4)
    np.testing.assert_allclose(f.augmented, x1, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(f.augmented_cov, P1, rtol=1e-10, atol=1e-15)
    # range and bearing together
    x, P = x1, P1
    z = np.array([ref.h_range(x, 1, LANDMARKS[1]) - 0.2, ref.h_bearing(x, LANDMARKS[1]) + 0.01])
    R = np.diag([0.3, 0.02]) ** 2
    f.update_range_bearing(1, LANDMARKS[1], z, R)
    H = np.vstack([ref.H_range(x, 1, LANDMARKS[1]), ref.H_bearing(x, LANDMARKS[1])])
    y = np.array([z[0] - ref.h_range(x, 1, LANDMARKS[1]), wrap(z[1] - ref.h_bearing(x, LANDMARKS[1]))])
    x1, P1, _ = ref.update(x, P, y, H, R)
    np.testing.assert_allclose(f.augmented, x1, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(f.augmented_cov, P1, rtol=1e-10, atol=1e-15)
    # position fix and IMU speed/heading
    x, P = x1, P1
    f.update_position(np.array([1.3, -2.1]), np.eye(2) * 0.04)
    H = np.zeros((2, ref.n))
    H[0, 0] = H[1, 1] = 1.0
    x1, P1, _ = ref.update(x, P, np.array([1.3, -2.1]) - x[:2], H, np.eye(2) * 0.04)
    np.testing.assert_allclose(f.augmented, x1, rtol=1e-12, atol=1e-15)
    x, P = x1, P1
    f.update_speed_heading(np.array([1.1, 0.45]), np.diag([0.1, 0.05]) ** 2)
    H = np.zeros((2, ref.n))
    H[0, 2] = H[1, 3] = 1.0
    x1, P1, _ = ref.update(x, P, np.array([1.1 - x[2], wrap(0.45 - x[3])]), H, np.diag([0.1, 0.05]) ** 2)
    np.testing.assert_allclose(f.augmented, x1, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(f.augmented_cov, P1, rtol=1e-10, atol=1e-15)


# --------------------------------------------------------------------------- Jacobians vs finite differences

def wrapped_diff(a, b):
    d = a - b
    d[3] = wrap(d[3])
    return d


@settings(max_examples=60, deadline=None)
@given(st.floats(-30, 30), st.floats(-30, 30), st.floats(0.0, 5.0), st.floats(-3.1, 3.1), st.floats(-0.1, 0.1),
       st.floats(-0.02, 0.02), st.floats(0.0, 6.0), st.floats(-0.3, 0.3), st.floats(0.02, 0.5))
def test_predict_jacobian_matches_finite_differences(x, y, v, th, k, beta, speed, dth, dt):
    p = bmm()
    a = augment(bias=True)
    f = _core.AugmentedEkf(p, a, 2, np.zeros(4), np.eye(4))
    ref = Ref(p, a, 2)
    # keep away from the kinks of eq. 3 (speed limits) and eq. 4 (heading clip)
    lim_v = p.acceleration * dt
    assume(abs(abs(speed - v) - lim_v) > 1e-3 and v > 1e-3 and abs(abs(dth) - p.max_heading_rate * dt) > 1e-3)
    x0 = np.array([x, y, v, th, k, beta, 0.1, -0.1])
    u = np.array([speed, dth])
    _, F, _ = ref.f(x0, u, dt)
    h = 1e-6
    Fd = np.zeros_like(F)
    for j in range(len(x0)):
        cols = []
        for sgn in (1, -1):
            xp = x0.copy()
            xp[j] += sgn * h
            f.set_state(xp, np.eye(len(x0)))
            f.predict(u, dt)
            cols.append(f.augmented.copy())
        Fd[:, j] = wrapped_diff(cols[0], cols[1]) / (2 * h)
    np.testing.assert_allclose(Fd, F, atol=1e-6)


@settings(max_examples=60, deadline=None)
@given(st.floats(-30, 30), st.floats(-30, 30), st.floats(-3.1, 3.1), st.floats(-0.1, 0.1), st.floats(-1, 1),
       st.integers(0, 3))
def test_measurement_jacobians_match_finite_differences(x, y, th, k, b, row):
    ref = Ref(bmm(), augment(bias=True), 4)
    lm = LANDMARKS[row]
    assume(math.hypot(x - lm[0], y - lm[1]) > 0.5)
    x0 = np.concatenate([[x, y, 1.0, th, k, 0.0], np.full(4, b)])
    h = 1e-6
    for fun, jac in ((lambda z: ref.h_range(z, row, lm), ref.H_range(x0, row, lm)),
                     (lambda z: ref.h_bearing(z, lm), ref.H_bearing(x0, lm))):
        num = np.array([wrap(fun(x0 + h * e) - fun(x0 - h * e)) / (2 * h) for e in np.eye(len(x0))])
        np.testing.assert_allclose(num, jac if jac.ndim == 1 else jac[0], atol=1e-6)


# --------------------------------------------------------------------------- convergence on synthetic data

def circle_run(f, *, seconds, scale=1.0, gyro_bias=0.0, range_std=0.3, seed=0):
    """A vehicle on a circle (radius 10 m, 1 m/s) among LANDMARKS; odometry every 0.2 s whose heading change
    reads gyro_bias·dt high; after each step one range (cycling the landmarks) that reads scale·|p − a|."""
    rng = np.random.default_rng(seed)
    dt, speed, rate = 0.2, 1.0, 0.1
    th = f.x[3]
    p = f.x[:2].copy()
    for i in range(int(seconds / dt)):
        th = th + rate * dt
        p = p + speed * dt * np.array([math.cos(th), math.sin(th)])
        f.predict(np.array([speed, rate * dt + gyro_bias * dt]), dt)
        row = i % len(LANDMARKS)
        r = scale * math.hypot(*(p - LANDMARKS[row])) + range_std * rng.normal()
        f.update_range(row, LANDMARKS[row], r, range_std ** 2)
    return p


def test_range_scale_converges_to_a_known_7_percent():
    a = augment(scale=True, gyro=False, scale_prior=0.0, scale_std=0.05)
    x0 = np.array([10.0, 0.0, 1.0, math.pi / 2])
    f = _core.AugmentedEkf(bmm(speed_noise=0.01, heading_noise=0.002), a, 4, x0, np.diag([0.2, 0.2, 0.1, 0.02]) ** 2)
    f.gate = 0.999
    p = circle_run(f, seconds=300.0, scale=1.07)
    k = f.augmented[f.scale_index]
    assert abs(k - 0.07) < 0.005, k
    assert math.sqrt(f.augmented_cov[4, 4]) < 0.005
    assert np.hypot(*(f.x[:2] - p)) < 0.5


def test_heading_rate_bias_converges_under_a_gyro_bias():
    a = augment(scale=False, gyro=True, heading_rate_bias_std=0.02)
    x0 = np.array([10.0, 0.0, 1.0, math.pi / 2])
    f = _core.AugmentedEkf(bmm(speed_noise=0.01, heading_noise=0.001), a, 4, x0, np.diag([0.2, 0.2, 0.1, 0.02]) ** 2)
    p = circle_run(f, seconds=600.0, gyro_bias=0.01, range_std=0.2)
    beta = f.augmented[f.heading_rate_bias_index]
    assert abs(beta - 0.01) < 0.002, beta
    assert np.hypot(*(f.x[:2] - p)) < 0.5


# --------------------------------------------------------------------------- gate and bad input

def test_gate_rejects_a_gross_outlier_and_keeps_the_state():
    f, ref, x, P = make()
    f.gate = 0.999
    r = ref.h_range(x, 0, LANDMARKS[0]) + 50.0
    res = f.update_range(0, LANDMARKS[0], r, 0.3 ** 2)
    assert not res.accepted and res.nis > _core.chi2_quantile(0.999, 1)
    np.testing.assert_array_equal(f.augmented, x)
    np.testing.assert_array_equal(f.augmented_cov, P)
    assert f.update_range(0, LANDMARKS[0], r - 50.0, 0.3 ** 2).accepted
    with pytest.raises(ValueError, match="gate probability"):
        f.gate = 1.0


@pytest.mark.parametrize("call, match", [
    (lambda f: f.update_range(0, LANDMARKS[0], 10.0, -1.0), "variance = -1"),
    (lambda f: f.update_range(0, LANDMARKS[0], 10.0, float("nan")), "variance = nan"),
    (lambda f: f.update_range(4, LANDMARKS[0], 10.0, 1.0), "landmark row 4 is not in \\[0, 4\\)"),
    (lambda f: f.update_range(-1, LANDMARKS[0], 10.0, 1.0), "landmark row -1"),
    (lambda f: f.update_range(0, LANDMARKS[0], float("nan"), 1.0), "r = nan"),
    (lambda f: f.update_range(0, np.array([np.nan, 0.0]), 1.0, 1.0), "landmark position is not finite"),
    (lambda f: f.update_bearing(0, LANDMARKS[0], float("inf"), 1.0), "bearing = inf"),
    (lambda f: f.update_position(np.array([np.nan, 0.0]), np.eye(2)), "not finite"),
    (lambda f: f.update_position(np.zeros(2), -np.eye(2)), "positive definite"),
    (lambda f: f.update_speed_heading(np.zeros(2), np.full((2, 2), np.nan)), "positive definite"),
    (lambda f: f.predict(np.array([np.nan, 0.0]), 0.2), "not finite"),
    (lambda f: f.predict(np.array([1.0, 0.0]), 0.0), "dt = 0"),
    (lambda f: f.predict(np.array([1.0, 0.0]), float("nan")), "dt = nan"),
    (lambda f: f.set_state(np.zeros(3), np.eye(3)), "must have 10 entries"),
    (lambda f: f.set_state(np.full(10, np.nan), np.eye(10)), "x\\[0\\] = nan"),
    (lambda f: f.range_bias_index(7), "landmark row 7"),
])
def test_bad_input_names_the_value(call, match):
    f, _, x, P = make()
    with pytest.raises(ValueError, match=match):
        call(f)
    np.testing.assert_array_equal(f.augmented, x)  # nothing changed


def test_bad_settings_name_the_field():
    with pytest.raises(ValueError, match="augment.scale_std = 0"):
        _core.AugmentedEkf(bmm(), augment(scale_std=0.0), 2, np.zeros(4), np.eye(4))
    with pytest.raises(ValueError, match="n_landmarks = -1"):
        _core.AugmentedEkf(bmm(), augment(), -1, np.zeros(4), np.eye(4))


# --------------------------------------------------------------------------- in the Localizer

def augmented_localizer(**kw):
    s = gd.localizer_settings(bmm=bmm(), gate=0.999)
    s.augment = augment(bias=True, **kw)
    return gd.Localizer(s, LANDMARKS, [10, 11, 12, 13])


def test_localizer_runs_the_augmented_filter_input_by_input():
    loc = augmented_localizer()
    x0, P0 = np.array([1.0, 2.0, 1.0, 0.3]), np.diag([0.3, 0.3, 0.2, 0.05]) ** 2
    loc.initialize(0.0, x0, P0)
    f = _core.AugmentedEkf(bmm(), augment(bias=True), 4, x0, P0)
    f.gate = 0.999
    np.testing.assert_array_equal(loc.augmented, f.augmented)
    loc.motion(0.2, 1.0, 0.05)
    f.predict(np.array([1.0, 0.05]), 0.2)
    res = loc.observe(0.2, 12, range=30.0, range_std=0.5)
    f.update_range(2, LANDMARKS[2], 30.0, 0.25)
    loc.observe(0.2, 11, bearing=0.4, bearing_std=0.05)
    f.update_bearing(1, LANDMARKS[1], 0.4, 0.05 ** 2)
    loc.fix(0.2, 1.1, 2.2, np.eye(2) * 0.1)
    f.update_position(np.array([1.1, 2.2]), np.eye(2) * 0.1)
    loc.speed_heading(0.2, 1.0, 0.3, 0.1, 0.05)
    f.update_speed_heading(np.array([1.0, 0.3]), np.diag([0.1, 0.05]) ** 2)
    assert res.status == gd.InputStatus.APPLIED
    np.testing.assert_array_equal(loc.augmented, f.augmented)
    np.testing.assert_array_equal(loc.x, f.x)
    np.testing.assert_array_equal(loc.P, f.P)


def test_plain_localizer_has_no_augmented_state():
    loc = gd.Localizer(gd.localizer_settings(), LANDMARKS, [10, 11, 12, 13])
    loc.initialize(0.0, np.zeros(4), np.eye(4))
    assert loc.augmented is None


# --------------------------------------------------------------------------- the particle-filter counterpart

def test_particle_filter_estimates_the_range_scale():
    a = augment(scale=True, gyro=False, scale_prior=0.0, scale_std=0.05)
    x0 = np.array([10.0, 0.0, 1.0, math.pi / 2])
    f = _core.AugmentedParticleFilter(bmm(speed_noise=0.02, heading_noise=0.005, position_noise=0.02), a, 4, x0,
                                      np.diag([0.2, 0.2, 0.1, 0.02]) ** 2, n_particles=2000, seed=3)
    assert (f.size, f.state_size, f.scale_index, f.heading_rate_bias_index) == (2000, 5, 4, -1)
    f.gate = 0.999
    p = circle_run(f, seconds=120.0, scale=1.07)
    assert abs(f.augmented[4] - 0.07) < 0.01, f.augmented[4]
    assert np.hypot(*(f.x[:2] - p)) < 0.5
    assert f.weights.sum() == pytest.approx(1.0) and f.particles.shape == (5, 2000)
    r = f.update_range(0, LANDMARKS[0], 1.07 * math.hypot(*(p - LANDMARKS[0])) + 50.0, 0.09)
    assert not r.accepted


@pytest.mark.parametrize("call, match", [
    (lambda f: f.update_range(0, LANDMARKS[0], 10.0, -1.0), "variance = -1"),
    (lambda f: f.update_range(9, LANDMARKS[0], 10.0, 1.0), "landmark row 9"),
    (lambda f: f.update_range(0, LANDMARKS[0], float("nan"), 1.0), "r = nan"),
    (lambda f: f.predict(np.array([1.0, 0.0]), -0.1), "dt = -0.1"),
    (lambda f: f.predict(np.array([np.inf, 0.0]), 0.1), "not finite"),
])
def test_particle_filter_bad_input_names_the_value(call, match):
    f = _core.AugmentedParticleFilter(bmm(), augment(bias=True), 4, np.zeros(4), np.eye(4), n_particles=10)
    with pytest.raises(ValueError, match=match):
        call(f)
    with pytest.raises(ValueError, match="n_particles = 0"):
        _core.AugmentedParticleFilter(bmm(), augment(), 4, np.zeros(4), np.eye(4), n_particles=0)


def test_localizer_with_the_particle_filter_runs_the_augmented_counterpart():
    s = gd.localizer_settings(filter="pf", bmm=bmm(), gate=0.999, n_particles=200, seed=5)
    s.augment = augment()
    loc = gd.Localizer(s, LANDMARKS, [10, 11, 12, 13])
    loc.initialize(0.0, np.array([1.0, 2.0, 1.0, 0.3]), np.diag([0.3, 0.3, 0.2, 0.05]) ** 2)
    loc.motion(0.2, 1.0, 0.05)
    assert loc.observe(0.2, 12, range=1.07 * np.hypot(*(LANDMARKS[2] - loc.x[:2])), range_std=0.5).applied
    aug = loc.augmented
    assert aug.shape == (6,) and abs(aug[4] - 0.07) < 0.02

"""The EKF (per-step ``safenav.Ekf`` and batch ``filter_trajectory(filter="ekf")``)
against FilterPy's ``ExtendedKalmanFilter`` driven by an independent pure-numpy
Battlefield Motion Model (SafeNav eqs. 3, 4, 7 with the terrain factor
1/(1+tau)) and independent numpy measurement models.

FilterPy's update uses the Joseph form, as ours does (eq. 14); its predict is
``x = predict_x(u)`` (overridden below with the numpy BMM) and
``P = F P F^T + Q`` with the F and Q we set before each call.
"""

from __future__ import annotations

import numpy as np
import pytest

filterpy_ekf = pytest.importorskip("filterpy.kalman")

import safenav
from safenav import Bmm, BmmParams, MeasurementModel

RTOL = 1e-9
ATOL = 1e-12


# ---------------------------------------------------------------------------
# Independent numpy reference of the BMM
# ---------------------------------------------------------------------------

def np_wrap(a):
    """Wrap to (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(a, dtype=float), 2.0 * np.pi)


def _speed(v, vd, p):
    """Eq. 3 with the derivative dv'/dv (1 where v +/- a*dt is the active term)."""
    if vd > v:
        up = v + p.acceleration * p.dt
        v1 = min(up, vd, p.max_speed)
        dv = 1.0 if up < min(vd, p.max_speed) else 0.0
    else:
        down = v - p.deceleration * p.dt
        v1 = max(down, vd, 0.0)
        dv = 1.0 if down > max(vd, 0.0) else 0.0
    return v1, dv


def np_bmm(x, u, p, eps=(0.0, 0.0, 0.0, 0.0)):
    """f(x, u, eps): eqs. 3, 4, 7, noise (eps_x, eps_y, eps_v, eps_theta) added to
    v' and theta' before the position update and to x', y' after it."""
    X, Y, v, th = (float(c) for c in x)
    vd, dth = float(u[0]), float(u[1])
    v1, _ = _speed(v, vd, p)
    lim = p.max_heading_rate * p.dt
    th1 = float(np_wrap(th + np.clip(dth, -lim, lim)))
    v1e, th1e = v1 + eps[2], th1 + eps[3]
    k = p.dt / (1.0 + p.terrain_effect)
    return np.array([X + k * v1e * np.cos(th1e) + eps[0], Y + k * v1e * np.sin(th1e) + eps[1], v1e, th1e])


def np_bmm_F(x, u, p):
    """Analytic d f / d x."""
    v, th = float(x[2]), float(x[3])
    v1, dv = _speed(v, float(u[0]), p)
    lim = p.max_heading_rate * p.dt
    th1 = th + np.clip(float(u[1]), -lim, lim)
    k = p.dt / (1.0 + p.terrain_effect)
    c, s = np.cos(th1), np.sin(th1)
    return np.array([[1.0, 0.0, k * c * dv, -k * v1 * s],
                     [0.0, 1.0, k * s * dv, k * v1 * c],
                     [0.0, 0.0, dv, 0.0],
                     [0.0, 0.0, 0.0, 1.0]])


def np_bmm_G(x, u, p):
    """Analytic d f / d eps at eps = 0."""
    v1, _ = _speed(float(x[2]), float(u[0]), p)
    lim = p.max_heading_rate * p.dt
    th1 = float(x[3]) + np.clip(float(u[1]), -lim, lim)
    k = p.dt / (1.0 + p.terrain_effect)
    c, s = np.cos(th1), np.sin(th1)
    return np.array([[1.0, 0.0, k * c, -k * v1 * s],
                     [0.0, 1.0, k * s, k * v1 * c],
                     [0.0, 0.0, 1.0, 0.0],
                     [0.0, 0.0, 0.0, 1.0]])


def np_bmm_Q(x, u, p):
    G = np_bmm_G(x, u, p)
    S = np.diag([p.position_noise**2, p.position_noise**2, p.speed_noise**2, p.heading_noise**2])
    return G @ S @ G.T


# ---------------------------------------------------------------------------
# Independent numpy measurement models
# ---------------------------------------------------------------------------

def h_position(x):
    return np.array([x[0], x[1]])


def H_position(x):
    return np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


def h_range(x, lm):
    return np.hypot(lm[:, 0] - x[0], lm[:, 1] - x[1])


def H_range(x, lm):
    dx, dy = lm[:, 0] - x[0], lm[:, 1] - x[1]
    r = np.hypot(dx, dy)
    H = np.zeros((len(lm), 4))
    H[:, 0], H[:, 1] = -dx / r, -dy / r
    return H


def h_bearing(x, lm):
    return np_wrap(np.arctan2(lm[:, 1] - x[1], lm[:, 0] - x[0]) - x[3])


def H_bearing(x, lm):
    dx, dy = lm[:, 0] - x[0], lm[:, 1] - x[1]
    q = dx * dx + dy * dy
    H = np.zeros((len(lm), 4))
    H[:, 0], H[:, 1], H[:, 3] = dy / q, -dx / q, -1.0
    return H


def angle_residual(a, b):
    return np_wrap(np.asarray(a) - np.asarray(b))


# ---------------------------------------------------------------------------
# Scenario
# ---------------------------------------------------------------------------

PARAMS = BmmParams(acceleration=2.0, deceleration=2.5, max_speed=4.0, max_heading_rate=1.5, dt=0.05,
                   terrain_effect=0.25, speed_noise=0.08, heading_noise=0.015, position_noise=0.02)
LANDMARKS = np.array([[-5.0, 8.0], [12.0, -6.0], [15.0, 9.0], [4.0, 6.0]])
N_STEPS = 80
X0_TRUE = np.array([0.0, 0.0, 2.0, 0.2])
P0 = np.diag([0.3**2, 0.3**2, 0.2**2, 0.05**2])
POS_R = np.array([[0.05**2, 0.3 * 0.05 * 0.08], [0.3 * 0.05 * 0.08, 0.08**2]])
RANGE_STD = 0.2
BEARING_STD = 0.02


def make_controls(n=N_STEPS):
    """Desired speed alternating between far above (a*dt binds), close (v_desired
    binds), far below (d*dt binds), and the v_max ceiling; heading changes that
    sometimes exceed m*dt (clipped), keeping theta far from +-pi."""
    k = np.arange(n)
    vd = np.where(k % 20 < 5, 3.5, np.where(k % 20 < 10, 2.6, np.where(k % 20 < 15, 1.0, 9.0)))
    dth = 0.02 * np.sin(2 * np.pi * k / n)
    spikes = k % 13 == 6
    dth[spikes] = 0.2 * (-1.0) ** np.arange(spikes.sum())  # clipped to +-m*dt = 0.075
    return np.column_stack([vd, dth])


@pytest.fixture(scope="module")
def scenario():
    controls = make_controls()
    truth = Bmm(PARAMS).simulate(X0_TRUE, controls, seed=7)
    rng = np.random.default_rng(2024)
    x0 = X0_TRUE + rng.multivariate_normal(np.zeros(4), P0)
    after = truth[1:]
    position = after[:, :2] + rng.multivariate_normal(np.zeros(2), POS_R, size=N_STEPS)
    ranges = np.array([h_range(s, LANDMARKS) for s in after]) + RANGE_STD * rng.standard_normal((N_STEPS, 4))
    bearings = np_wrap(np.array([h_bearing(s, LANDMARKS) for s in after])
                       + BEARING_STD * rng.standard_normal((N_STEPS, 4)))
    # the scenario stays where no angle wrapping differs between implementations
    assert np.all(np.abs(truth[:, 3]) < 1.5)
    assert np.all(truth[:, 2] > 0.5)
    return dict(controls=controls, truth=truth, x0=x0, position=position, ranges=ranges, bearings=bearings)


class BmmEKF(filterpy_ekf.ExtendedKalmanFilter):
    """FilterPy EKF whose state prediction is the numpy BMM."""

    def __init__(self, params, x0, P0):
        super().__init__(dim_x=4, dim_z=1, dim_u=2)
        self.params = params
        self.x = np.array(x0, dtype=float)
        self.P = np.array(P0, dtype=float)

    def predict_x(self, u=0):
        self.x = np_bmm(self.x, u, self.params)

    def bmm_predict(self, u):
        self.F = np_bmm_F(self.x, u, self.params)
        self.Q = np_bmm_Q(self.x, u, self.params)
        self.predict(u=u)


def _model_setup(kind, data):
    """(safenav model, z stream, Hx, HJacobian, R, residual, filter_trajectory kwargs)."""
    if kind == "position":
        return (MeasurementModel.position(POS_R), data["position"], h_position, H_position, POS_R,
                np.subtract, dict(position=data["position"], position_cov=POS_R))
    if kind == "range":
        R = np.eye(4) * RANGE_STD**2
        return (MeasurementModel.range(LANDMARKS, RANGE_STD), data["ranges"],
                lambda x: h_range(x, LANDMARKS), lambda x: H_range(x, LANDMARKS), R, np.subtract,
                dict(ranges=data["ranges"], range_std=RANGE_STD, landmarks=LANDMARKS))
    if kind == "bearing":
        R = np.eye(4) * BEARING_STD**2
        return (MeasurementModel.bearing(LANDMARKS, BEARING_STD), data["bearings"],
                lambda x: h_bearing(x, LANDMARKS), lambda x: H_bearing(x, LANDMARKS), R, angle_residual,
                dict(bearings=data["bearings"], bearing_std=BEARING_STD, landmarks=LANDMARKS))
    raise AssertionError(kind)


# ---------------------------------------------------------------------------
# The numpy reference itself
# ---------------------------------------------------------------------------

def _random_cases(rng, n):
    """Random (x, u) pairs across all branches of eq. 3 and both sides of the eq. 4 clip,
    away from kinks (ties between the terms of the min/max)."""
    p = PARAMS
    out = []
    while len(out) < n:
        x = np.array([rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(0.0, p.max_speed),
                      rng.uniform(-2.5, 2.5)])
        u = np.array([rng.uniform(-1.0, p.max_speed + 2.0), rng.uniform(-0.2, 0.2)])
        v, vd = x[2], u[0]
        terms = [v + p.acceleration * p.dt, vd, p.max_speed, v - p.deceleration * p.dt, 0.0, v]
        if min(abs(a - b) for i, a in enumerate(terms) for b in terms[i + 1:]) < 1e-3:
            continue
        if abs(abs(u[1]) - p.max_heading_rate * p.dt) < 1e-4:
            continue
        out.append((x, u))
    return out


def test_numpy_bmm_matches_safenav_bmm():
    bmm = Bmm(PARAMS)
    rng = np.random.default_rng(11)
    branches = set()
    for x, u in _random_cases(rng, 400):
        np.testing.assert_allclose(bmm.predict(x, u), np_bmm(x, u, PARAMS), rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(bmm.jacobian(x, u), np_bmm_F(x, u, PARAMS), rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(bmm.noise_jacobian(x, u), np_bmm_G(x, u, PARAMS), rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(bmm.process_cov(x, u), np_bmm_Q(x, u, PARAMS), rtol=1e-12, atol=1e-16)
        branches.add((u[0] > x[2], np_bmm_F(x, u, PARAMS)[2, 2]))
    # both eq. 3 branches, each with the rate limit active (dv/dv = 1) and inactive (0)
    assert branches == {(True, 1.0), (True, 0.0), (False, 1.0), (False, 0.0)}


def test_numpy_bmm_noisy_transition_matches_safenav():
    bmm = Bmm(PARAMS)
    rng = np.random.default_rng(12)
    checked = 0
    for x, u in _random_cases(rng, 100):
        eps = rng.normal(0.0, [0.02, 0.02, 0.05, 0.01])
        ref = np_bmm(x, u, PARAMS, eps)
        if not (0.0 <= ref[2] <= PARAMS.max_speed) or abs(ref[3]) > np.pi:
            continue  # safenav clamps v and wraps theta there; the formula above does not
        np.testing.assert_allclose(bmm.transition(x, u, eps), ref, rtol=1e-13, atol=1e-13)
        checked += 1
    assert checked > 80


def test_numpy_jacobians_match_central_differences():
    rng = np.random.default_rng(13)
    h = 1e-6
    for x, u in _random_cases(rng, 200):
        F_fd = np.empty((4, 4))
        G_fd = np.empty((4, 4))
        for j in range(4):
            e = np.zeros(4)
            e[j] = h
            F_fd[:, j] = (np_bmm(x + e, u, PARAMS) - np_bmm(x - e, u, PARAMS)) / (2 * h)
            G_fd[:, j] = (np_bmm(x, u, PARAMS, e) - np_bmm(x, u, PARAMS, -e)) / (2 * h)
        np.testing.assert_allclose(np_bmm_F(x, u, PARAMS), F_fd, atol=1e-7)
        np.testing.assert_allclose(np_bmm_G(x, u, PARAMS), G_fd, atol=1e-7)


@pytest.mark.parametrize("kind", ["position", "range", "bearing"])
def test_numpy_measurement_models_match_safenav(kind, scenario):
    model, _, hx, Hj, R, _, _ = _model_setup(kind, scenario)
    np.testing.assert_allclose(model.R, R, rtol=1e-15)
    h = 1e-6
    for x in scenario["truth"][::7]:
        np.testing.assert_allclose(model.predict(x), hx(x), rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(model.jacobian(x), Hj(x), rtol=1e-12, atol=1e-13)
        H_fd = np.column_stack([(hx(x + h * e) - hx(x - h * e)) / (2 * h) for e in np.eye(4)])
        np.testing.assert_allclose(Hj(x), H_fd, atol=1e-7)


# ---------------------------------------------------------------------------
# EKF against FilterPy, step by step and in batch
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["position", "range", "bearing"])
def test_ekf_matches_filterpy(kind, scenario):
    model, zs, hx, Hj, R, residual, stream = _model_setup(kind, scenario)
    controls = scenario["controls"]
    ref = BmmEKF(PARAMS, scenario["x0"], P0)
    ours = safenav.Ekf(PARAMS, scenario["x0"], P0)
    batch = safenav.filter_trajectory(controls, scenario["x0"], P0, params=PARAMS, filter="ekf", **stream)
    assert batch.states.shape == (N_STEPS + 1, 4)
    assert batch.n_updates == N_STEPS
    np.testing.assert_allclose(batch.states[0], scenario["x0"], rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(batch.covariances[0], P0, rtol=RTOL, atol=ATOL)
    moved = 0.0
    for k in range(N_STEPS):
        u = controls[k]
        ref.bmm_predict(u)
        ours.predict(u)
        np.testing.assert_allclose(ours.x, ref.x, rtol=RTOL, atol=ATOL, err_msg=f"prior x, step {k}")
        np.testing.assert_allclose(ours.P, ref.P, rtol=RTOL, atol=ATOL, err_msg=f"prior P, step {k}")
        before = ref.x.copy()
        ref.update(zs[k], Hj, hx, R=R, residual=residual)
        res = ours.update(model, zs[k])
        assert res.accepted and res.dim == model.dim
        moved = max(moved, np.abs(ref.x - before).max())
        np.testing.assert_allclose(ours.x, ref.x, rtol=RTOL, atol=ATOL, err_msg=f"posterior x, step {k}")
        np.testing.assert_allclose(ours.P, ref.P, rtol=RTOL, atol=ATOL, err_msg=f"posterior P, step {k}")
        np.testing.assert_allclose(batch.states[k + 1], ref.x, rtol=RTOL, atol=ATOL, err_msg=f"batch x, {k}")
        np.testing.assert_allclose(batch.covariances[k + 1], ref.P, rtol=RTOL, atol=ATOL,
                                   err_msg=f"batch P, step {k}")
        # NIS reported by our update against FilterPy's innovation
        np.testing.assert_allclose(res.nis, float(ref.y @ np.linalg.solve(ref.S, ref.y)), rtol=1e-8)
    # the updates did something (the comparison is not trivially between two predictions)
    assert moved > 1e-3
    # and the filter tracks the truth
    err = np.abs(ref.x[:2] - scenario["truth"][-1, :2])
    assert np.all(err < 5 * np.sqrt(np.diag(ref.P)[:2]))

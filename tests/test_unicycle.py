"""The motion model for logged speeds: ``BmmParams.unicycle``.

With ``unicycle`` the speed comes from the input — v' = clamp(v_desired,
−v_max, v_max), signed, with no acceleration limit — in place of [SafeNav
eq. 3]; eq. 4's heading clip and eqs. 6–9 stay.  Tested against the
textbook unicycle written out here, finite differences for the Jacobian,
the particle filters against the EKF, and — on real-like logs in which the
robot backs up — FilterPy's EKF over a 3-state unicycle as the peer: the
paper's BMM (speed ≥ 0) cannot follow a reversing vehicle; the unicycle
preset does, as well as the peer that is handed the true noise and a head
start."""

from __future__ import annotations

import math

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter
from hypothesis import given, settings, strategies as st

import safenav
from safenav import _core
from safenav import replay as rp
from safenav.reallike import RealLikeConfig, reallike_log

UNI = _core.BmmParams(unicycle=True, terrain_effect=0.25)


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def textbook(x, u, p):
    """The unicycle with the BMM's order (heading first, then position, eq. 7) and eq. 4's clip."""
    v1 = float(np.clip(u[0], -p.max_speed, p.max_speed))
    th1 = wrap(x[3] + np.clip(u[1], -p.max_heading_rate * p.dt, p.max_heading_rate * p.dt))
    k = p.dt / (1.0 + p.terrain_effect)
    return np.array([x[0] + k * v1 * math.cos(th1), x[1] + k * v1 * math.sin(th1), v1, th1])


finite = st.floats(-50, 50, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(x=st.tuples(finite, finite, st.floats(-10, 10), st.floats(-3.1, 3.1)),
       u=st.tuples(st.floats(-15, 15), st.floats(-0.2, 0.2)))
def test_predict_is_the_textbook_unicycle_and_F_its_derivative(x, u):
    x, u = np.array(x), np.array(u)
    m = _core.Bmm(UNI)
    np.testing.assert_allclose(m.predict(x, u), textbook(x, u, UNI), rtol=1e-14, atol=1e-12)
    F = m.jacobian(x, u)
    h = 1e-6
    num = np.column_stack([(textbook(x + h * e, u, UNI) - textbook(x - h * e, u, UNI)) / (2 * h)
                           for e in np.eye(4)])
    num[3, 3] = 1.0  # wrap(θ ± h) across ±π
    np.testing.assert_allclose(F, num, atol=1e-6)
    assert F[2, 2] == 0.0 and F[0, 2] == 0.0 and F[1, 2] == 0.0   # v' does not depend on v


def test_reverse_speed_and_limits():
    m, paper = _core.Bmm(UNI), _core.Bmm(_core.BmmParams())
    assert m.next_speed(5.0, -3.0) == -3.0                  # at once, signed
    assert m.next_speed(0.0, -99.0) == -UNI.max_speed
    assert paper.next_speed(0.0, -3.0) == 0.0               # eq. 3: never below 0
    assert paper.next_speed(0.0, 2.0) == pytest.approx(3.0 * 0.05)  # eq. 3: a·Δt
    assert UNI.min_speed() == -UNI.max_speed and _core.BmmParams().min_speed() == 0.0
    # the noisy transition (eq. 6) clamps to [−v_max, v_max]
    x = np.array([0.0, 0.0, -9.9, 0.0])
    assert m.transition(x, np.array([-9.9, 0.0]), np.array([0, 0, -5.0, 0]))[2] == -UNI.max_speed
    assert _core.BmmParams(unicycle=True).get_param("unicycle") is True
    import pickle
    assert pickle.loads(pickle.dumps(UNI)).unicycle


@pytest.mark.parametrize("bandwidth", [0.0, 1.0])
def test_particle_filters_follow_a_reversing_vehicle_as_the_ekf_does(bandwidth):
    """Small process noise: the cloud's mean follows the EKF's mean (the same f), reversing included."""
    p = _core.BmmParams(unicycle=True, speed_noise=0.01, heading_noise=0.002, position_noise=0.002)
    x0, P0 = np.array([1.0, 2.0, 0.0, 0.3]), np.diag([1e-4, 1e-4, 1e-4, 1e-5])
    ekf = safenav.Ekf(p, x0, P0)
    pf = safenav.ParticleFilter(p, x0, P0, n_particles=2000, seed=3, bandwidth_scale=bandwidth)
    a = _core.AugmentedStates()
    a.heading_rate_bias = True
    a.heading_rate_bias_std = 1e-6
    apf = _core.AugmentedParticleFilter(p, a, 0, x0, P0, n_particles=2000)
    controls = [(1.0, 0.01)] * 40 + [(-1.5, -0.02)] * 80
    for u in controls:
        for f in (ekf, pf):
            f.predict(u)
        apf.predict(np.array(u), p.dt)
    assert ekf.x[2] == pytest.approx(-1.5)
    assert np.hypot(*(ekf.x[:2] - x0[:2])) > 3.0           # it backed up well past the start
    for f in (pf, apf):
        assert np.hypot(*(f.x[:2] - ekf.x[:2])) < 0.05
        assert f.x[2] == pytest.approx(-1.5, abs=0.02)


class UnicycleEkf(ExtendedKalmanFilter):
    """FilterPy's EKF with the unicycle's f over u = (v, ω, Δt): heading first, then position."""

    def predict_x(self, u=0):
        v, w, dt = u
        th = self.x[2] + w * dt
        self.x = np.array([self.x[0] + v * dt * math.cos(th), self.x[1] + v * dt * math.sin(th), wrap(th)])


def _filterpy_unicycle(log, cfg: RealLikeConfig, t0: float, x0: np.ndarray) -> np.ndarray:
    """FilterPy's EKF over (x, y, θ), handed the generator's true noise (as bench/bench_reallike.py)."""
    f = UnicycleEkf(dim_x=3, dim_z=2)
    f.x, f.P = x0.astype(float).copy(), np.diag([0.05, 0.05, 0.02]) ** 2
    lm, t_prev, out = log.landmarks, t0, []
    ev = log.events[log.events["t"] > t0]
    for row in ev.itertuples(index=False):
        if row.kind == "motion":
            dt, t_prev = row.t - t_prev, row.t
            v, w = row.speed, (row.heading_change / dt if dt > 0 else 0.0)
            moving = v != 0.0 or w != 0.0
            var_v = (cfg.speed_scale_std * v) ** 2 + (cfg.speed_noise ** 2 if moving else 0.0)
            var_w = (cfg.turn_scale_std * w) ** 2 + ((cfg.turn_bias_std ** 2 + cfg.turn_noise ** 2) if moving else 0)
            th = f.x[2] + w * dt
            c, s = math.cos(th), math.sin(th)
            f.F = np.array([[1, 0, -v * dt * s], [0, 1, v * dt * c], [0, 0, 1]])
            G = np.array([[dt * c, -v * dt * dt * s], [dt * s, v * dt * dt * c], [0, dt]])
            f.Q = G @ np.diag([var_v, var_w]) @ G.T
            f.predict(u=(v, w, dt))
            out.append((row.t, f.x[0], f.x[1]))
        elif row.kind == "range_bearing":
            a = np.array(lm[int(row.landmark)])

            def hx(x, a=a):
                d = a - x[:2]
                return np.array([math.hypot(*d), wrap(math.atan2(d[1], d[0]) - x[2])])

            def jac(x, a=a):
                d = a - x[:2]
                q = d @ d
                r = math.sqrt(q)
                return np.array([[-d[0] / r, -d[1] / r, 0], [d[1] / q, -d[0] / q, -1]])

            f.update(np.array([row.range, row.bearing]), jac, hx, R=np.diag([row.range_std ** 2, row.bearing_std ** 2]),
                     residual=lambda z, h: np.array([z[0] - h[0], wrap(z[1] - h[1])]))
            f.x[2] = wrap(f.x[2])
    return np.array(out)


def _rmse(est, truth, t_from):
    tt = truth[truth["t"] >= t_from]
    j = np.searchsorted(est[:, 0], tt["t"].to_numpy() + 1e-9, side="right") - 1
    ok = j >= 0
    e = est[j[ok], 1:3] - tt[["x", "y"]].to_numpy()[ok]
    return float(np.sqrt((e ** 2).sum(axis=1).mean()))


@pytest.mark.parametrize("seed", [0, 1])
def test_a_reversing_robot_is_tracked_as_well_as_by_a_textbook_ekf(seed):
    cfg = RealLikeConfig(reverse_share=0.5, duration=90.0)
    log = reallike_log(seed, cfg)
    assert (log.events["speed"] < 0).sum() > 1000            # it does back up
    uni = rp.replay(log)                                      # the default preset: unicycle
    assert uni.estimated
    paper = rp.preset_settings("default")
    paper.bmm.unicycle = False
    eq3 = rp.replay(log, settings=paper)
    tr = log.truth
    th = np.unwrap(tr["heading"].to_numpy())
    t0 = uni.t_start
    x0 = np.array([np.interp(t0, tr["t"], tr["x"]), np.interp(t0, tr["t"], tr["y"]),
                   wrap(np.interp(t0, tr["t"], th))])
    peer = _rmse(_filterpy_unicycle(log, cfg, t0, x0), tr, t0)
    got = uni.metrics["truth_rmse"]
    assert got <= 1.1 * peer, (got, peer)
    assert 0.5 < uni.metrics["nees"] < 4.0                    # consistent (2 for a perfect filter)
    assert eq3.metrics["truth_rmse"] > 10 * got               # eq. 3's speed >= 0 cannot back up


def test_forward_logs_are_unchanged_in_substance():
    """Without reversing, eq. 3's limits hardly bind at these speeds: both models give the same RMSE to 1 mm."""
    log = reallike_log(0)
    paper = rp.preset_settings("default")
    paper.bmm.unicycle = False
    a, b = rp.replay(log), rp.replay(log, settings=paper)
    assert a.metrics["truth_rmse"] == pytest.approx(b.metrics["truth_rmse"], abs=1e-3)

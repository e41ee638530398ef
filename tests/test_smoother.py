"""The fixed-lag Rauch–Tung–Striebel smoother beside the causal EKF
(safenav/smoother.hpp, ``Localizer.set_lag``, ``replay(..., lag=)``).

Checked against a full RTS smoother written here in numpy (Rauch, Tung and
Striebel 1965) on the same F, Q (the EKF's own ``last_transition``), H and R,
against the causal filter (lag 0), and on Plaza1 against the truth."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from safenav import _core
from safenav import replay as rp
from safenav.guidance import Localizer, localizer_settings


def _bmm():
    # Nominal step dt = 0.05 s; limits that a slow, straight run never reaches.
    return _core.BmmParams(acceleration=100.0, deceleration=100.0, max_speed=100.0, max_heading_rate=100.0,
                           dt=0.05, terrain_effect=0.0, speed_noise=0.05, heading_noise=0.01,
                           position_noise=0.02, unicycle=True)


def _linear_case(n=60, seed=3):
    """Straight-line motion with a tiny turn, a position fix at every step."""
    rng = np.random.default_rng(seed)
    x0 = np.array([1.0, -2.0, 1.0, 0.3])
    P0 = np.diag([0.5, 0.5, 0.1, 0.05])
    u = np.column_stack([np.full(n, 1.0), np.full(n, 1e-4)])
    z = np.column_stack([1.0 + np.arange(1, n + 1) * 0.05 * math.cos(0.3), -2.0 + np.arange(1, n + 1) * 0.05
                         * math.sin(0.3)]) + rng.normal(0.0, 0.3, (n, 2))
    R = np.diag([0.09, 0.16])
    return x0, P0, u, z, R


def _numpy_rts(x0, P0, u, z, R):
    """Filtered and full-RTS-smoothed means and covariances at the prior and each step, computed here:
    the EKF's prediction (its f, F and Q: Ekf.last_transition) and the Kalman update with H = [I 0]."""
    ekf = _core.Ekf(_bmm(), x0, P0)
    H = np.hstack([np.eye(2), np.zeros((2, 2))])
    xs, Ps, xps, Pps, Fs = [x0.copy()], [P0.copy()], [], [], []
    x, P = x0.copy(), P0.copy()
    for k in range(len(u)):
        ekf.predict(u[k])
        F, Q = ekf.last_transition()
        xp = np.array(ekf.x)
        Pp = F @ P @ F.T + Q                      # eq. 11
        S = H @ Pp @ H.T + R                      # eq. 12
        K = Pp @ H.T @ np.linalg.inv(S)           # eq. 13
        x = xp + K @ (z[k] - H @ xp)              # eq. 14
        A = np.eye(4) - K @ H
        P = A @ Pp @ A.T + K @ R @ K.T            # eq. 14, Joseph form
        ekf.set_state(x, P)
        xs.append(x), Ps.append(P), xps.append(xp), Pps.append(Pp), Fs.append(F)
    sx, sP = [xs[-1]], [Ps[-1]]
    for k in range(len(u) - 1, -1, -1):         # RTS backward pass
        C = Ps[k] @ Fs[k].T @ np.linalg.inv(Pps[k])
        sx.insert(0, xs[k] + C @ (sx[0] - xps[k]))
        sP.insert(0, Ps[k] + C @ (sP[0] - Pps[k]) @ C.T)
    return np.array(xs), np.array(Ps), np.array(sx), np.array(sP)


def _localizer_run(x0, P0, u, z, R, lag, smoother="rts", iterations=1):
    s = localizer_settings(filter="ekf", bmm=_bmm(), gate=0.0)
    loc = Localizer(s, np.zeros((0, 2)), [])
    loc.set_lag(lag, smoother, iterations)
    loc.initialize(0.0, x0, P0)
    causal = [(0.0, np.array(loc.x), np.array(loc.P))]
    for k in range(len(u)):
        t = (k + 1) * 0.05
        loc.motion(t, u[k, 0], u[k, 1])
        loc.fix(t, z[k, 0], z[k, 1], R)
        causal.append((t, np.array(loc.x), np.array(loc.P)))
    early = loc.take_smoothed()
    loc.finish_smoothing()
    t, x, P = loc.take_smoothed()
    t, x, P = (np.concatenate([a, b]) for a, b in zip(early, (t, x, P)))
    return causal, t, x, P.reshape(-1, 4, 4)


def test_long_lag_equals_full_rts_smoother():
    x0, P0, u, z, R = _linear_case()
    xf, Pf, sx, sP = _numpy_rts(x0, P0, u, z, R)
    causal, t, x, P = _localizer_run(x0, P0, u, z, R, lag=100.0)
    assert np.allclose(t, np.arange(len(u) + 1) * 0.05, atol=1e-12)
    # The causal filter is the numpy EKF (the reference's filtered pass is right) ...
    assert np.abs(np.array([c[1] for c in causal]) - xf).max() < 1e-9
    # ... and the smoother with a lag beyond the log is the full RTS smoother.
    assert np.abs(x - sx).max() < 1e-9
    assert np.abs(P - sP).max() < 1e-9
    # Smoothing helps: the smoothed position variance is below the filtered one except at the end.
    assert (P[:-1, 0, 0] < Pf[:-1, 0, 0]).all()


def test_fixed_lag_is_rts_over_the_window():
    # With lag L, the estimate at t_i is the full RTS of the data up to t_i + L.
    x0, P0, u, z, R = _linear_case(n=40)
    lag = 0.5  # 10 steps
    _, t, x, P = _localizer_run(x0, P0, u, z, R, lag=lag)
    for i in (0, 5, 17, 29, 35):
        m = min(len(u), i + 10)
        _, _, sx, sP = _numpy_rts(x0, P0, u[:m], z[:m], R)
        assert abs(t[i] - i * 0.05) < 1e-12
        assert np.abs(x[i] - sx[i]).max() < 1e-9
        assert np.abs(P[i] - sP[i]).max() < 1e-9


@pytest.mark.parametrize("smoother", ["rts", "iterated"])
def test_lag_zero_is_the_causal_filter(smoother):
    x0, P0, u, z, R = _linear_case(n=30)
    causal, t, x, P = _localizer_run(x0, P0, u, z, R, lag=0.0, smoother=smoother, iterations=3)
    assert np.allclose(t, [c[0] for c in causal], atol=1e-12)
    assert np.abs(x - np.array([c[1] for c in causal])).max() < 1e-12
    assert np.abs(P - np.array([c[2] for c in causal])).max() < 1e-12


@pytest.mark.parametrize("lag", [-1.0, math.nan, math.inf])
def test_bad_lag_raises_naming_lag(lag):
    loc = Localizer(localizer_settings(filter="ekf"), np.zeros((0, 2)), [])
    with pytest.raises(ValueError, match="lag"):
        loc.set_lag(lag)


def test_particle_filter_refused():
    loc = Localizer(localizer_settings(filter="pf"), np.zeros((0, 2)), [])
    with pytest.raises(ValueError, match="lag.*particle"):
        loc.set_lag(2.0)


def test_causal_path_unchanged_by_the_smoother():
    x0, P0, u, z, R = _linear_case(n=30)
    with_lag, *_ = _localizer_run(x0, P0, u, z, R, lag=1.0)
    s = localizer_settings(filter="ekf", bmm=_bmm(), gate=0.0)
    loc = Localizer(s, np.zeros((0, 2)), [])
    loc.initialize(0.0, x0, P0)
    assert math.isnan(loc.lag)
    for k in range(len(u)):
        loc.motion((k + 1) * 0.05, u[k, 0], u[k, 1])
        loc.fix((k + 1) * 0.05, z[k, 0], z[k, 1], R)
    assert np.array_equal(np.array(loc.x), with_lag[-1][1])


def test_augmented_transition_matches_its_predict():
    # P' = F P Fᵀ + Q with the full augmented F and Q of last_transition.
    a = _core.AugmentedStates()
    a.range_scale = a.heading_rate_bias = a.range_bias = True
    f = _core.AugmentedEkf(_bmm(), a, 2, np.array([0.0, 0.0, 1.0, 0.2]), np.diag([0.3, 0.3, 0.1, 0.05]))
    f.predict(np.array([1.0, 0.01]), 0.07)
    P = np.array(f.augmented_cov)
    f.predict(np.array([1.2, -0.02]), 0.11)
    F, Q = f.last_transition()
    assert F.shape == (f.size, f.size)
    assert np.abs(F @ P @ F.T + Q - np.array(f.augmented_cov)).max() < 1e-12


def _plaza1():
    gtsam = pytest.importorskip("gtsam")
    path = Path(gtsam.__file__).parent / "Data" / "Plaza1_.mat"
    if not path.exists():
        pytest.skip(f"{path} is not in this gtsam wheel")
    return rp.load(path, range_std=rp.PLAZA_RANGE_STD)


def test_plaza1_smoothed_beats_causal():
    r = rp.replay(_plaza1(), rp.preset_settings("plaza"), lag=2.0)
    m, s = r.metrics, r.smoothed_metrics
    assert m["label"] == "causal" and s["label"] == "fixed-lag 2 s"
    assert s["n_scored"] == m["n_scored"]
    assert np.allclose(r.smoothed["t"], r.trajectory["t"])
    assert s["truth_rmse"] < m["truth_rmse"] - 0.02
    assert m["truth_rmse"] == pytest.approx(0.2813, abs=5e-4)  # the causal result stays as it was


def test_plaza1_late_ranges_replayed_into_the_window():
    # Ranges 0-300 ms late (max_delay 0.5 s): the localizer re-runs its history, the smoother records those
    # steps again; one output per causal row, in time order, and the smoothed RMSE as in time order.
    log = _plaza1()
    ev = log.events
    d = np.where(ev["kind"].to_numpy() == "range", np.random.default_rng(0).uniform(0.0, 0.3, len(ev)), 0.0)
    r = rp.replay(log, rp.preset_settings("plaza"), lag=2.0, delays=d)
    in_order = rp.replay(log, rp.preset_settings("plaza"), lag=2.0)
    assert np.array_equal(r.smoothed["t"], r.trajectory["t"])
    assert (np.diff(r.smoothed["t"]) > 0).all()
    assert r.smoothed_metrics["truth_rmse"] == pytest.approx(in_order.smoothed_metrics["truth_rmse"], abs=0.005)


# -- the iterated window solve ---------------------------------------------------------------------------------


def test_bad_smoother_raises_naming_it():
    loc = Localizer(localizer_settings(filter="ekf"), np.zeros((0, 2)), [])
    with pytest.raises(ValueError, match="smoother = 'gn'"):
        loc.set_lag(1.0, "gn")
    with pytest.raises(ValueError, match="iterations = 0"):
        loc.set_lag(1.0, "iterated", 0)
    loc.set_lag(1.0, "iterated", 2)
    assert loc.smoother == "iterated" and loc.lag == 1.0


@pytest.mark.parametrize("lag", [0.5, 100.0])
def test_iterated_equals_rts_on_a_linear_model(lag):
    # A vehicle that turns in place (speed input 0) seen by position fixes: f, F and Q do not depend on the
    # state where the fixes move it (with v' = 0 the position does not depend on θ, the unicycle's v' not on
    # v, and θ, uncorrelated with the rest, is never updated), so the model is linear-Gaussian and
    # re-linearising changes nothing: the iterated solve is the RTS smoother.
    x0, P0, _, z, R = _linear_case(n=40)
    u = np.column_stack([np.zeros(40), np.full(40, 0.02)])
    causal, t_r, x_r, P_r = _localizer_run(x0, P0, u, z, R, lag=lag)
    _, t_i, x_i, P_i = _localizer_run(x0, P0, u, z, R, lag=lag, smoother="iterated", iterations=3)
    assert np.array_equal(t_r, t_i)
    assert np.abs(x_i - x_r).max() < 1e-9
    assert np.abs(P_i - P_r).max() < 1e-9
    # ... and it smooths: the position variance falls below the filtered one.
    assert all(P_i[k, 0, 0] < causal[k][2][0, 0] for k in (0, 5, 20))


def _range_case(n=24, seed=5):
    """A turning run with a range to each of three landmarks at every step, the start (x0, P0) off the truth."""
    rng = np.random.default_rng(seed)
    lm = np.array([[3.0, 4.0], [-2.0, 5.0], [1.0, -4.0]])
    truth = np.array([0.0, 0.0, 1.0, 0.4])
    u = np.column_stack([np.full(n, 1.0), np.full(n, 0.03)])
    states, x = [], truth.copy()
    for k in range(n):
        th = x[3] + u[k, 1]
        x = np.array([x[0] + 0.05 * u[k, 0] * math.cos(th), x[1] + 0.05 * u[k, 0] * math.sin(th), u[k, 0], th])
        states.append(x)
    z = np.array([[np.hypot(*(a - s[:2])) for a in lm] for s in states]) + rng.normal(0.0, 0.2, (n, 3))
    x0 = truth + np.array([0.6, -0.5, 0.0, 0.15])
    P0 = np.diag([0.5, 0.5, 0.1, 0.05])
    return lm, u, z, x0, P0


def _ranges_run(lm, u, z, x0, P0, lag, smoother, iterations):
    loc = Localizer(localizer_settings(filter="ekf", bmm=_bmm(), gate=0.0), lm, [])
    loc.set_lag(lag, smoother, iterations)
    loc.initialize(0.0, x0, P0)
    for k in range(len(u)):
        t = (k + 1) * 0.05
        loc.motion(t, u[k, 0], u[k, 1])
        for i in range(len(lm)):
            loc.observe(t, i, z[k, i], math.nan, 0.2, 1.0)
    loc.finish_smoothing()
    return loc.take_smoothed()


def _batch_gauss_newton(lm, u, z, x0, P0, m, sigma=0.2):
    """The MAP of states 0..m (prior (x0, P0) at 0; the motion of the EKF's own f, F, Q, Ekf.last_transition,
    at the current iterate; the ranges ‖a − p‖ written out here) by Gauss–Newton on the dense normal
    equations, to convergence.  Returns the mean and the covariance (inverse Hessian) of state 0."""
    ekf = _core.Ekf(_bmm(), x0, P0)
    X = [x0.copy()]
    for k in range(m):                       # start from the open-loop prediction
        ekf.set_state(X[-1], np.eye(4))
        ekf.predict(u[k])
        X.append(np.array(ekf.x))
    X = np.array(X)
    wrap = lambda a: (a + math.pi) % (2 * math.pi) - math.pi  # noqa: E731
    for _ in range(100):
        N = 4 * (m + 1)
        A, b = np.zeros((N, N)), np.zeros(N)

        def add(J, r, W, blocks):            # J: list of (block, 4-column Jacobian); r residual; W weight
            Js = np.zeros((len(r), N))
            for blk, Jb in zip(blocks, J):
                Js[:, 4 * blk:4 * blk + 4] = Jb
            A[:] += Js.T @ W @ Js
            b[:] += Js.T @ W @ r

        r0 = X[0] - x0
        r0[3] = wrap(r0[3])
        add([np.eye(4)], r0, np.linalg.inv(P0), [0])
        for k in range(m):
            ekf.set_state(X[k], np.eye(4))
            ekf.predict(u[k])
            F, Q = ekf.last_transition()
            r = X[k + 1] - np.array(ekf.x)
            r[3] = wrap(r[3])
            add([-F, np.eye(4)], r, np.linalg.inv(Q), [k, k + 1])
            for i, a in enumerate(lm):
                d = X[k + 1, :2] - a
                rho = np.hypot(*d)
                H = np.array([[d[0] / rho, d[1] / rho, 0.0, 0.0]])
                add([H], np.array([rho - z[k, i]]), np.eye(1) / sigma ** 2, [k + 1])
        delta = -np.linalg.solve(A, b)
        X = X + delta.reshape(-1, 4)
        X[:, 3] = wrap(X[:, 3])
        if np.abs(delta).max() < 1e-13:
            break
    return X[0], np.linalg.inv(A)[:4, :4]


def test_iterated_window_solve_is_batch_gauss_newton():
    # The first output's window (the start t = 0 up to t = lag) has an exact prior, the start's: with enough
    # passes the iterated smoother's estimate at t = 0 is the MAP of that window, computed here by Gauss–Newton
    # on the full normal equations.  The RTS pass, at the filter's linearisation, is not.
    lm, u, z, x0, P0 = _range_case()
    lag, m = 0.6, 12                          # the window: steps 0..12
    t, x, P = _ranges_run(lm, u, z, x0, P0, lag, "iterated", 40)
    xm, Pm = _batch_gauss_newton(lm, u, z, x0, P0, m)
    assert t[0] == 0.0
    assert np.abs(x[0] - xm).max() < 1e-9
    assert np.abs(P[0].reshape(4, 4) - Pm).max() < 1e-9
    _, x_rts, _ = _ranges_run(lm, u, z, x0, P0, lag, "rts", 1)
    assert np.abs(x_rts[0] - xm)[:2].max() > 1e-3


def test_iterated_keeps_the_gate_decisions():
    # A range the causal gate rejects stays out of the window: the smoothed estimate is the one without it.
    lm, u, z, x0, P0 = _range_case()
    bad = z.copy()
    bad[6, 1] += 40.0                          # an outlier the gate rejects
    runs = []
    for zz in (z, bad):
        loc = Localizer(localizer_settings(filter="ekf", bmm=_bmm(), gate=0.999), lm, [])
        loc.set_lag(0.6, "iterated", 2)
        loc.initialize(0.0, x0, P0)
        status = []
        for k in range(len(u)):
            t = (k + 1) * 0.05
            loc.motion(t, u[k, 0], u[k, 1])
            for i in range(len(lm)):
                if zz is bad or (k, i) != (6, 1):
                    status.append(loc.observe(t, i, zz[k, i], math.nan, 0.2, 1.0).status.name.lower())
        loc.finish_smoothing()
        runs.append((loc.take_smoothed(), status))
    assert runs[1][1].count("rejected") == runs[0][1].count("rejected") + 1
    assert np.array_equal(runs[0][0][1], runs[1][0][1])


def test_plaza1_iterated_is_the_rts_result():
    # On Plaza1 re-linearising the window changes the 2 s estimate by well under a millimetre of RMSE
    # (docs/replay.md, "Fixed-lag smoothing": the filter's linearisation is not what limits it).
    log = _plaza1()
    r = rp.replay(log, rp.preset_settings("plaza"), lag=2.0, smoother="iterated")
    rts = rp.replay(log, rp.preset_settings("plaza"), lag=2.0)
    assert r.smoothed_metrics["label"] == "fixed-lag 2 s" and r.smoothed_metrics["smoother"] == "iterated"
    assert np.array_equal(r.smoothed["t"], r.trajectory["t"])
    assert np.array_equal(r.trajectory.to_numpy(), rts.trajectory.to_numpy())  # the causal path is untouched
    assert r.smoothed_metrics["truth_rmse"] == pytest.approx(rts.smoothed_metrics["truth_rmse"], abs=1e-3)
    assert r.smoothed_metrics["truth_rmse"] < r.metrics["truth_rmse"] - 0.02


def test_augmented_transition_at_a_state_is_its_predict():
    # AugmentedEkf.transition(x, u, dt) is predict's model at any x: at the estimate, predict's mean and
    # last_transition's F, Q exactly; elsewhere the mean moves by F (x − x̂) to first order.
    a = _core.AugmentedStates()
    a.range_scale = a.heading_rate_bias = a.range_bias = True
    f = _core.AugmentedEkf(_bmm(), a, 2, np.array([0.0, 0.0, 1.0, 0.2]), np.diag([0.3, 0.3, 0.1, 0.05]))
    f.predict(np.array([1.0, 0.01]), 0.07)
    x = np.array(f.augmented)
    x[f.heading_rate_bias_index] = 0.02
    f.set_state(x, np.array(f.augmented_cov))
    u, dt = np.array([1.2, -0.02]), 0.11
    x1, F, Q = f.transition(x, u, dt)
    f.predict(u, dt)
    F_, Q_ = f.last_transition()
    assert np.array_equal(x1, np.array(f.augmented)) and np.array_equal(F, F_) and np.array_equal(Q, Q_)
    e = np.array([1e-4, -2e-4, 0.0, 3e-4, 1e-4, -1e-4, 2e-4, 0.0])
    x2, _, _ = f.transition(x + e, u, dt)
    assert np.abs(x2 - x1 - F @ e).max() < 1e-7
    with pytest.raises(ValueError, match="transition"):
        f.transition(x[:4], u, dt)


def test_iterated_late_range_is_replayed_into_the_window():
    # A range delivered two steps late (max_delay): the localizer re-runs from its checkpoint and the
    # smoother's record of updates is rewound with it, so nothing is lost or counted twice.  With passes to
    # convergence each window's MAP depends on the warm start only through the linearisation point of its
    # marginalised prior (second order): every output not yet final when the range arrived matches the
    # in-order run's to that order, while the one final before it lacks the range.
    lm, u, z, x0, P0 = _range_case()
    late = (10, 2)                             # step 10's range to landmark 2 arrives after step 12's motion
    runs = []
    for delayed in (False, True):
        loc = Localizer(localizer_settings(filter="ekf", bmm=_bmm(), gate=0.0), lm, [])
        loc.set_lag(0.6, "iterated", 40)
        loc.initialize(0.0, x0, P0)
        statuses = []
        for k in range(len(u)):
            t = (k + 1) * 0.05
            loc.motion(t, u[k, 0], u[k, 1])
            for i in range(len(lm)):
                if not (delayed and (k, i) == late):
                    statuses.append(loc.observe(t, i, z[k, i], math.nan, 0.2, 1.0).status.name.lower())
            if delayed and k == late[0] + 2:
                statuses.append(loc.observe((late[0] + 1) * 0.05, late[1], z[late], math.nan, 0.2, 1.0)
                                .status.name.lower())
        loc.finish_smoothing()
        runs.append((loc.take_smoothed(), statuses))
    (t0, x0s, P0s), s0 = runs[0]
    (t1, x1s, P1s), s1 = runs[1]
    assert s1.count("applied") == s0.count("applied") == len(s0)
    assert np.array_equal(t0, t1)
    after = t0 > 0.0   # final only after the range arrived (t = 0.65): all but the start's (final at 0.6)
    assert after.sum() > 10
    assert np.abs(x1s[after] - x0s[after]).max() < 1e-5
    assert np.abs(P1s[after] - P0s[after]).max() < 1e-5
    assert np.abs(x1s[~after] - x0s[~after]).max() > 1e-3   # the start's lacks it, as emitted

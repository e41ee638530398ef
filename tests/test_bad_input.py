"""Bad input raises ValueError whose message names the bad value or field."""

from __future__ import annotations

import time

import numpy as np
import pytest

from safenav import (Bmm, BmmParams, Ekf, InformationFilter, MeasurementModel, ParticleFilter, RiskZones,
                     filter_trajectory)
from safenav import metrics

PARAMS = BmmParams()
X0 = np.array([0.0, 0.0, 1.0, 0.2])
P0 = np.diag([0.01, 0.01, 0.01, 0.001])
N = 10
U = np.column_stack([np.full(N, 1.2), np.full(N, 0.01)])
POS = np.column_stack([np.linspace(0.05, 0.5, N), np.linspace(0.01, 0.1, N)])


def make_ekf(x0=X0, P=P0):
    return Ekf(PARAMS, x0, P)


def make_pf(x0=X0, P=P0):
    return ParticleFilter(PARAMS, x0, P, n_particles=50, seed=1)


def make_eif(x0=X0, P=P0):
    return InformationFilter(PARAMS, x0, P)


def make_batch(filt):
    return lambda x0=X0, P=P0: filter_trajectory(U, x0, P, params=PARAMS, filter=filt, position=POS, n_particles=50)


CONSTRUCTORS = {"Ekf": make_ekf, "ParticleFilter": make_pf, "InformationFilter": make_eif,
                "batch-ekf": make_batch("ekf"), "batch-pf": make_batch("pf"), "batch-eif": make_batch("eif")}
ALL = pytest.mark.parametrize("make", list(CONSTRUCTORS.values()), ids=list(CONSTRUCTORS))


# ---------------------------------------------------------------------------
# x0 and P0
# ---------------------------------------------------------------------------

@ALL
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nonfinite_x0(make, bad):
    x0 = X0.copy()
    x0[2] = bad
    with pytest.raises(ValueError, match=rf"x0\[2\] = -?{'nan' if np.isnan(bad) else 'inf'} is not finite"):
        make(x0=x0)


@ALL
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_nonfinite_P0(make, bad):
    P = P0.copy()
    P[1, 3] = P[3, 1] = bad
    with pytest.raises(ValueError, match=r"P0\[\(1, 3\)\] = (nan|inf) is not finite"):
        make(P=P)


@ALL
@pytest.mark.parametrize("x0, shape", [(np.zeros(3), r"\(3,\)"), (np.zeros(5), r"\(5,\)"),
                                       (np.zeros((1, 4)), r"\(1, 4\)")])
def test_x0_wrong_shape(make, x0, shape):
    with pytest.raises(ValueError, match=rf"x0 must have shape \(4,\), got {shape}"):
        make(x0=x0)


@ALL
def test_P0_wrong_shape(make):
    with pytest.raises(ValueError, match=r"P0 must have shape \(4, 4\), got \(3, 3\)"):
        make(P=np.eye(3))


@ALL
def test_P0_not_symmetric(make):
    P = P0.copy()
    P[0, 1] = 0.005  # P[1, 0] stays 0
    with pytest.raises(ValueError, match=r"P0 is not symmetric"):
        make(P=P)


@ALL
@pytest.mark.parametrize("P", [np.diag([0.01, 0.01, -0.01, 0.001]), np.diag([0.01, 0.01, 0.0, 0.001]),
                               np.ones((4, 4))], ids=["negative", "singular", "rank-1"])
def test_P0_not_positive_definite(make, P):
    with pytest.raises(ValueError, match=r"P0 is not positive definite"):
        make(P=P)


def test_ekf_set_state_validates():
    f = make_ekf()
    with pytest.raises(ValueError, match=r"x\[3\] = nan is not finite"):
        f.set_state(np.array([0.0, 0.0, 1.0, np.nan]), P0)
    with pytest.raises(ValueError, match=r"not symmetric"):
        f.set_state(X0, P0 + np.triu(np.full((4, 4), 1e-3), 1))
    # the failed calls did not change the filter
    np.testing.assert_array_equal(f.x, X0)


def test_ekf_set_state_wrong_shape():
    with pytest.raises(ValueError, match=r"\bx\b.*shape"):
        make_ekf().set_state(np.zeros(3), P0)


# ---------------------------------------------------------------------------
# controls and measurements
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("filt", ["ekf", "pf", "eif"])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_nonfinite_controls_batch(filt, bad):
    u = U.copy()
    u[4, 1] = bad
    with pytest.raises(ValueError, match=r"controls\[\(4, 1\)\] = (nan|inf) is not finite"):
        filter_trajectory(u, X0, P0, params=PARAMS, filter=filt, position=POS, n_particles=50)


@pytest.mark.parametrize("make", [make_ekf, make_pf, make_eif], ids=["Ekf", "ParticleFilter", "InformationFilter"])
@pytest.mark.parametrize("bad", [np.nan, -np.inf])
def test_nonfinite_control_step(make, bad):
    with pytest.raises(ValueError, match=r"u\[0\] = (nan|-inf) is not finite"):
        make().predict(np.array([bad, 0.0]))


def test_nonfinite_controls_simulate_and_predict():
    bmm = Bmm(PARAMS)
    u = U.copy()
    u[7, 0] = np.nan
    with pytest.raises(ValueError, match=r"controls\[\(7, 0\)\] = nan is not finite"):
        bmm.simulate(X0, u, seed=0)
    with pytest.raises(ValueError, match=r"u\[1\] = inf is not finite"):
        bmm.predict(X0, np.array([1.0, np.inf]))
    with pytest.raises(ValueError, match=r"x\[3\] = nan is not finite"):
        bmm.jacobian(np.array([0.0, 0.0, 1.0, np.nan]), np.array([1.0, 0.0]))
    with pytest.raises(ValueError, match=r"x0\[0\] = nan is not finite"):
        bmm.simulate(np.array([np.nan, 0.0, 1.0, 0.0]), U, seed=0)
    with pytest.raises(ValueError, match=r"eps\[2\] = nan is not finite"):
        bmm.transition(X0, np.array([1.0, 0.0]), np.array([0.0, 0.0, np.nan, 0.0]))


def test_next_speed_rejects_nan():
    with pytest.raises(ValueError, match=r"nan"):
        Bmm(PARAMS).next_speed(np.nan, 1.0)


@pytest.mark.parametrize("filt", ["ekf", "pf", "eif"])
def test_controls_wrong_shape(filt):
    with pytest.raises(ValueError, match=r"controls must have shape \(N, 2\), got \(10, 3\)"):
        filter_trajectory(np.zeros((N, 3)), X0, P0, params=PARAMS, filter=filt, n_particles=50)
    with pytest.raises(ValueError, match=r"controls must have shape \(N, 2\), got \(2,\)"):
        filter_trajectory(np.zeros(2), X0, P0, params=PARAMS, filter=filt, n_particles=50)


def test_simulate_controls_wrong_shape():
    with pytest.raises(ValueError, match=r"controls must have shape \(N, 2\), got \(10, 3\)"):
        Bmm(PARAMS).simulate(X0, np.zeros((N, 3)), seed=0)


@pytest.mark.parametrize("filt", ["ekf", "pf", "eif"])
def test_position_stream_wrong_length(filt):
    with pytest.raises(ValueError, match=r"position must have shape \(10, 2\), got \(9, 2\)"):
        filter_trajectory(U, X0, P0, params=PARAMS, filter=filt, position=POS[:-1], n_particles=50)


@pytest.mark.parametrize("stream", ["position", "speed_heading"])
@pytest.mark.parametrize("col", [0, 1])
def test_half_nan_row(stream, col):
    z = POS.copy() if stream == "position" else np.column_stack([np.full(N, 1.2), np.full(N, 0.2)])
    z[3, col] = np.nan
    kw = {stream: z}
    if stream == "speed_heading":
        kw["speed_heading_cov"] = np.diag([0.01, 0.001])
    shown = r"\(nan, [-0-9.e]+\)" if col == 0 else r"\([-0-9.e]+, nan\)"
    with pytest.raises(ValueError, match=rf"measurement stream '{stream}' row 3 = {shown} is invalid"):
        filter_trajectory(U, X0, P0, params=PARAMS, position_cov=np.eye(2) * 0.01, **kw)


def test_full_nan_row_is_a_gap():
    z = POS.copy()
    z[[2, 5]] = np.nan
    res = filter_trajectory(U, X0, P0, params=PARAMS, position=z)
    assert res.n_gaps == 2 and res.n_updates == N - 2
    assert np.isnan(res.nis[[2, 5]]).all() and np.isfinite(np.delete(res.nis, [2, 5])).all()


@pytest.mark.parametrize("stream", ["position", "ranges", "bearings"])
def test_inf_in_measurement_stream(stream):
    lm = np.array([[5.0, 5.0], [-5.0, 5.0]])
    z = POS.copy() if stream == "position" else np.ones((N, 2))
    z[6, 1] = np.inf
    kw = {stream: z}
    if stream != "position":
        kw["landmarks"] = lm
    with pytest.raises(ValueError, match=rf"{stream}\[\(6, 1\)\] = inf is not finite"):
        filter_trajectory(U, X0, P0, params=PARAMS, **kw)


@pytest.mark.parametrize("make", [make_ekf, make_pf, make_eif], ids=["Ekf", "ParticleFilter", "InformationFilter"])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_nonfinite_z_step(make, bad):
    f = make()
    f.predict(U[0])
    with pytest.raises(ValueError, match=r"z\[1\] = (nan|inf) is not finite"):
        f.update(MeasurementModel.position(), np.array([0.05, bad]))
    with pytest.raises(ValueError, match=r"z must have shape \(2,\), got \(3,\)"):
        f.update(MeasurementModel.position(), np.zeros(3))


# ---------------------------------------------------------------------------
# particles, parameters, filter name
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("n", [0, -5])
def test_zero_or_negative_particles(n):
    with pytest.raises(ValueError, match=rf"n_particles must be a positive integer, got {n}"):
        ParticleFilter(PARAMS, X0, P0, n_particles=n)
    with pytest.raises(ValueError, match=rf"n_particles must be a positive integer, got {n}"):
        filter_trajectory(U, X0, P0, params=PARAMS, filter="pf", position=POS, n_particles=n)


@pytest.mark.parametrize("dt", [0.0, -0.1, -np.inf, np.nan])
def test_bmm_params_dt(dt):
    with pytest.raises(ValueError, match=r"BmmParams\.dt = (0|0\.0|-0\.1|-inf|nan) is invalid"):
        BmmParams(dt=dt)


def test_bmm_params_mutated_after_construction_is_rejected_on_use():
    p = BmmParams()
    p.dt = -0.5
    for use in (lambda: Bmm(p), lambda: Ekf(p, X0, P0), lambda: ParticleFilter(p, X0, P0, n_particles=10),
                lambda: InformationFilter(p, X0, P0), lambda: filter_trajectory(U, X0, P0, params=p)):
        with pytest.raises(ValueError, match=r"BmmParams\.dt = -0\.5 is invalid"):
            use()


FIELDS = ["acceleration", "deceleration", "max_speed", "max_heading_rate", "dt", "terrain_effect", "speed_noise",
          "heading_noise", "position_noise"]


@pytest.mark.parametrize("field", FIELDS)
def test_bmm_params_nan(field):
    with pytest.raises(ValueError, match=rf"BmmParams\.{field} = nan is invalid"):
        BmmParams(**{field: np.nan})


@pytest.mark.parametrize("field", FIELDS)
def test_bmm_params_negative(field):
    with pytest.raises(ValueError, match=rf"BmmParams\.{field} = -1(\.0)? is invalid"):
        BmmParams(**{field: -1.0})


@pytest.mark.parametrize("field", ["acceleration", "deceleration", "max_speed", "max_heading_rate", "dt"])
def test_bmm_params_zero_where_positive_required(field):
    with pytest.raises(ValueError, match=rf"BmmParams\.{field} = 0(\.0)? is invalid"):
        BmmParams(**{field: 0.0})


@pytest.mark.parametrize("name", ["ukf", "EKF", ""])
def test_bad_filter_name(name):
    with pytest.raises(ValueError, match=rf"filter must be one of \['eif', 'ekf', 'pf'\], got '{name}'"):
        filter_trajectory(U, X0, P0, params=PARAMS, filter=name)


def test_other_bad_options():
    with pytest.raises(ValueError, match=r"seed must be an integer in \[0, 2\*\*64\), got -1"):
        filter_trajectory(U, X0, P0, params=PARAMS, filter="pf", seed=-1)
    with pytest.raises(ValueError, match=r"resample_threshold = 2(\.0)? must be in \[0, 1\]"):
        filter_trajectory(U, X0, P0, params=PARAMS, filter="pf", resample_threshold=2.0)
    with pytest.raises(ValueError, match=r"gate probability = 1\.5 must be in \[0, 1\)"):
        filter_trajectory(U, X0, P0, params=PARAMS, gate=1.5)
    with pytest.raises(ValueError, match=r"landmarks \(K, 2\) are required"):
        filter_trajectory(U, X0, P0, params=PARAMS, ranges=np.ones((N, 2)))
    with pytest.raises(ValueError, match=r"range_std = 0(\.0)? must be finite and > 0"):
        filter_trajectory(U, X0, P0, params=PARAMS, ranges=np.ones((N, 1)), landmarks=[[5.0, 5.0]], range_std=0.0)
    with pytest.raises(ValueError, match=r"position R is not symmetric"):
        filter_trajectory(U, X0, P0, params=PARAMS, position=POS, position_cov=[[1.0, 0.5], [0.0, 1.0]])
    with pytest.raises(ValueError, match=r"sigma = 0(\.0)? must be > 0"):
        MeasurementModel.range([[1.0, 2.0]], 0.0)


def test_a_measurement_covariance_is_symmetric_to_the_rounding_of_its_largest_entry():
    """The one symmetry rule of every covariance check: entries may differ
    from their transposes by 1e-9 of the largest entry, whatever its scale
    (a small R gets no absolute allowance)."""
    MeasurementModel.position([[1e3, 1e-7], [1.5e-7, 2e3]])                # 5e-8 < 1e-9 · 2e3: rounding
    MeasurementModel.position([[1e-6, 1e-16], [1.5e-16, 2e-6]])            # 5e-17 < 1e-9 · 2e-6
    with pytest.raises(ValueError, match=r"R is not symmetric: \[1, 0\] = 0 but \[0, 1\] = 1e-13"):
        MeasurementModel.position([[1e-6, 1e-13], [0.0, 1e-6]])         # 1e-13 = 1e-7 of the largest entry


# ---------------------------------------------------------------------------
# landmark at the vehicle position: range and bearing undefined
# ---------------------------------------------------------------------------

LM = np.array([[10.0, -3.0], [3.0, 4.0]])
AT_LM1 = np.array([3.0, 4.0, 0.0, 0.3])
MSG = r"landmark 1 coincides with the vehicle position \(3, 4\)"


@pytest.mark.parametrize("kind", ["range", "bearing", "range_bearing"])
def test_landmark_at_vehicle_predict_and_jacobian(kind):
    model = (MeasurementModel.range_bearing(LM, 0.1, 0.05) if kind == "range_bearing"
             else getattr(MeasurementModel, kind)(LM, 0.1))
    with pytest.raises(ValueError, match=MSG):
        model.predict(AT_LM1)
    with pytest.raises(ValueError, match=MSG):
        model.jacobian(AT_LM1)
    # a millimetre away both are defined and finite
    near = AT_LM1 + np.array([1e-3, 0.0, 0.0, 0.0])
    assert np.isfinite(model.predict(near)).all() and np.isfinite(model.jacobian(near)).all()


@pytest.mark.parametrize("kind", ["range", "bearing"])
@pytest.mark.parametrize("make", [make_ekf, make_eif], ids=["Ekf", "InformationFilter"])
def test_landmark_at_vehicle_update(kind, make):
    model = getattr(MeasurementModel, kind)(LM, 0.1)
    f = make(x0=AT_LM1)
    with pytest.raises(ValueError, match=MSG):
        f.update(model, np.array([1.0, 1.0]))


@pytest.mark.parametrize("kind", ["range", "bearing"])
def test_landmark_at_vehicle_update_pf(kind):
    # every particle sits on landmark 1 (tiny P0, zero speed, no process noise)
    p = BmmParams(speed_noise=0.0, heading_noise=0.0, position_noise=0.0)
    pf = ParticleFilter(p, AT_LM1, np.eye(4) * 1e-30, n_particles=5, seed=0)
    pf.predict(np.array([0.0, 0.0]))
    with pytest.raises(ValueError, match=MSG):
        pf.update(getattr(MeasurementModel, kind)(LM, 0.1), np.array([1.0, 1.0]))


@pytest.mark.parametrize("kind", ["ranges", "bearings"])
def test_landmark_at_vehicle_batch_ekf(kind):
    # zero speed, v_desired 0: the estimate stays on landmark 1
    u = np.zeros((3, 2))
    with pytest.raises(ValueError, match=MSG):
        filter_trajectory(u, AT_LM1, P0, params=PARAMS, filter="ekf", landmarks=LM, **{kind: np.ones((3, 2))})


# ---------------------------------------------------------------------------
# metrics
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("kw, msg", [
    (dict(half_width=-1.0), r"RiskZones\.half_width = -1(\.0)? must be finite and > 0"),
    (dict(half_width=0.0), r"RiskZones\.half_width = 0(\.0)? must be finite and > 0"),
    (dict(half_width=np.nan), r"RiskZones\.half_width = nan must be finite and > 0"),
    (dict(weights=[2.0, -4.0, 6.0]), r"RiskZones\.weights\[1\] = -4(\.0)? must be finite and > 0"),
    (dict(weights=[]), r"RiskZones\.weights must not be empty"),
])
def test_risk_zones(kw, msg):
    with pytest.raises(ValueError, match=msg):
        RiskZones(**kw)


def test_risk_zones_mutated_then_used():
    z = RiskZones()
    z.half_width = -2.0
    pts = np.array([[0.0, 0.1], [1.0, 0.2]])
    with pytest.raises(ValueError, match=r"RiskZones\.half_width = -2"):
        metrics.awrs(pts, pts, z)


def test_ade_requires_equal_lengths_fde_and_path_length_error_do_not():
    rng = np.random.default_rng(0)
    est = np.cumsum(rng.normal(size=(5, 2)), axis=0)
    tru = np.cumsum(rng.normal(size=(7, 2)), axis=0)
    with pytest.raises(ValueError, match=r"ADE .*estimate has 5 points but truth has 7"):
        metrics.ade(est, tru)
    with pytest.raises(ValueError, match=r"estimate has 7 points but truth has 5"):
        metrics.ade(tru, est)
    assert metrics.fde(est, tru) == pytest.approx(np.hypot(*(est[-1] - tru[-1])), rel=1e-14)
    L_est = np.sum(np.hypot(*np.diff(est, axis=0).T))
    L_tru = np.sum(np.hypot(*np.diff(tru, axis=0).T))
    assert metrics.path_length_error_percent(est, tru) == pytest.approx(abs(L_est - L_tru) / L_tru * 100, rel=1e-12)
    # equal lengths: ADE is the mean point-wise distance
    assert metrics.ade(est, tru[:5]) == pytest.approx(np.mean(np.hypot(*(est - tru[:5]).T)), rel=1e-14)


def test_metric_points_named():
    with pytest.raises(ValueError, match=r"truth\[\(1, 0\)\] = nan is not finite"):
        metrics.ade(np.zeros((3, 2)), np.array([[0.0, 0.0], [np.nan, 0.0], [0.0, 0.0]]))
    with pytest.raises(ValueError, match=r"estimate must have shape \(N, 2\), got \(3, 3\)"):
        metrics.fde(np.zeros((3, 3)), np.zeros((3, 2)))



# ---------------------------------------------------------------------------
# Issue #12, item 4: hangs and silent infinities.  Each test failed before its fix.
# ---------------------------------------------------------------------------

def test_range_model_on_10k_landmarks_stores_per_row_noise():
    # A dense 10⁴×10⁴ R (and its Cholesky) took over 60 s; per-row noise is O(n).
    lm = np.random.default_rng(0).random((10_000, 2)) * 100.0
    t0 = time.perf_counter()
    model = MeasurementModel.range(lm, 1.0)
    z = model.predict([50.5, 50.5, 1.0, 0.0])
    H = model.jacobian([50.5, 50.5, 1.0, 0.0])
    assert time.perf_counter() - t0 < 5.0
    assert model.dim == 10_000 and z.shape == (10_000,) and H.shape == (10_000, 4)
    np.testing.assert_allclose(z, np.hypot(*(lm - 50.5).T), rtol=1e-14)
    small = MeasurementModel.range_bearing(lm[:3], 0.5, 0.1)  # R is still the public dense covariance
    np.testing.assert_array_equal(small.R, np.diag(np.tile(np.square([0.5, 0.1]), 3)))


def test_segments_and_chull_control_on_10k_point_path_are_fast():
    from safenav import Corridor
    from safenav.navigation import ChullAction, chull_control

    s = np.linspace(0.0, 100_000.0, 10_000)  # 10⁴ vertices, ~10⁴ segments of 10 m: 7 s before
    path = np.column_stack([s, 5.0 * np.sin(s / 50.0)])
    t0 = time.perf_counter()
    corridor = Corridor(path)
    seg = corridor.segments()
    decisions = [chull_control(seg, Bmm(), [x, 5.0 * np.sin(x / 50.0) + 0.3, 1.0, 0.0], 1.0, 3.0, 0.5)
                 for x in np.linspace(0.0, 99_990.0, 50)]
    assert time.perf_counter() - t0 < 3.0
    assert len(seg) == np.ceil(corridor.length / 10.0) and all(d.action == ChullAction.KEEP for d in decisions)
    # the polyline of a segment runs through the path vertices between its cuts
    k = 5678
    pts, cum = seg.points(k), corridor.vertex_arc_lengths
    inner = path[(cum > seg.breaks[k]) & (cum < seg.breaks[k + 1])]
    assert len(inner) > 0 and all(np.min(np.hypot(*(pts - v).T)) < 1e-9 for v in inner)


@pytest.mark.parametrize("args, match", [
    ((0,), r"dof must be a positive integer, got 0"),
    ((4, 0), r"n_runs must be a positive integer, got 0"),
    ((4, 1, 1.5), r"probability = 1\.5 must be in \(0, 1\)"),
    ((4, 1, float("nan")), r"probability = nan must be in \(0, 1\)"),
    ((2.5,), r"dof must be a positive integer, got 2\.5"),
    ((10**300,), r"dof·n_runs = 10+·1 exceeds 1000000000"),
    ((4, 10**9), r"dof·n_runs = 4·1000000000 exceeds"),
])
def test_chi2_interval_validates(args, match):
    with pytest.raises(ValueError, match=match):
        metrics.chi2_interval(*args)


def test_chi2_interval_values():
    # chi-square with 2 dof is exponential with mean 2: quantile(p) = −2·ln(1 − p)
    lo, hi = metrics.chi2_interval(2, 1, 0.95)
    assert (lo, hi) == pytest.approx((-2 * np.log(0.975), -2 * np.log(0.025)), rel=1e-12)
    lo, hi = metrics.chi2_interval(4, 10**6, 0.95)  # large dof·n_runs: near 4 ± 1.96·sqrt(8/10⁶)
    assert (lo, hi) == pytest.approx((4 - 1.96 * np.sqrt(8e-6), 4 + 1.96 * np.sqrt(8e-6)), abs=1e-4)


def test_ekf_predict_overflow_raises_and_keeps_the_state():
    f = Ekf(PARAMS, X0, np.eye(4) * 1e308)
    with pytest.raises(ValueError, match=r"EKF predict P\[\d, \d\] = inf is not finite.*P = 1e\+308"):
        f.predict([1.0, 0.1])
    np.testing.assert_array_equal(f.P, np.eye(4) * 1e308)
    np.testing.assert_array_equal(f.x, X0)


def test_bmm_overflow_raises():
    x, u = np.array([0.0, 0.0, 1.0, 0.3]), np.array([1.0, 0.1])
    # the declared ranges (safenav/params.hpp) keep the parameters where Q stays finite
    with pytest.raises(ValueError, match=r"dt = 1e\+308: must be in \(0, 10\] s"):
        BmmParams(dt=1e308)
    assert np.isfinite(Bmm(BmmParams(dt=10.0, max_speed=100.0, speed_noise=10.0)).process_cov(x, u)).all()
    with pytest.raises(ValueError, match=r"Bmm.transition x'\[0\] = inf .*state \(1e\+308"):
        Bmm().transition([1e308, 0.0, 1.0, 0.0], u, [1e308, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"BmmParams.position_noise = 1e\+200 is invalid: must be >= 0 with a finite square"):
        BmmParams(position_noise=1e200)
    # within the declared ranges a step moves at most v_max·Δt = 1000 m: f stays finite near the float limit
    assert np.isfinite(Bmm(BmmParams(dt=10.0, max_speed=100.0)).predict([1.7e308, 0.0, 100.0, 0.0], u)).all()


@pytest.mark.parametrize("bad, exc, match", [
    (None, TypeError, r"angle must be a number .*got NoneType"),
    ([1.0, None], TypeError, r"angle must be a number .*got list"),
    ("1", TypeError, r"got str"),
    (float("nan"), ValueError, r"angle = nan is not finite"),
    ([0.0, float("inf")], ValueError, r"angle\[1\] = inf is not finite"),
])
def test_wrap_angle_bad_input(bad, exc, match):
    from safenav import wrap_angle

    with pytest.raises(exc, match=match):
        wrap_angle(bad)


def test_wrap_angle_keeps_scalars_and_shapes():
    from safenav import wrap_angle

    assert isinstance(wrap_angle(4.0), float) and wrap_angle(4.0) == pytest.approx(4.0 - 2 * np.pi)
    assert wrap_angle(np.zeros((2, 3))).shape == (2, 3)


def test_wrs_tiny_weight_raises():
    with pytest.raises(ValueError, match=r"half_width = 2 with weight 1e-310 gives WRS"):
        metrics.wrs(np.array([[0.0, 1.0]]), np.array([[0.0, 0.0], [1.0, 0.0]]),
                    RiskZones(half_width=2.0, weights=[1e-310, 4.0, 6.0, 8.0]))


def test_distances_on_huge_coordinates_are_exact_or_raise():
    from safenav import Corridor

    a, b = np.array([[1e308, 0.0]]), np.array([[0.9e308, 0.0]])
    assert metrics.ade(a, b) == metrics.fde(a, b) == pytest.approx(1e307, rel=1e-15)
    assert metrics.path_length([[0.0, 0.0], [1e200, 1e200]]) == pytest.approx(np.sqrt(2) * 1e200, rel=1e-15)
    far = np.array([[5.0, 1e300], [1e308, 1e308], [3.0, -4.0]])
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    d = metrics.distance_to_path(far, path)
    np.testing.assert_allclose(d, [1e300, np.hypot(1e308 - 10.0, 1e308), 4.0], rtol=1e-15)
    np.testing.assert_allclose(Corridor(path).signed_offset(far), [1e300, d[1], -4.0], rtol=1e-15)
    np.testing.assert_allclose(Corridor(path).arc_length(far), [5.0, 10.0, 3.0], rtol=1e-15)
    assert Corridor([[0.0, 0.0], [1e200, 0.0]]).length == 1e200
    # not representable: a clear error naming the values
    with pytest.raises(ValueError, match=r"ADE: the distance from \(1e\+308, 0\) to \(-1e\+308, -?0\) overflows"):
        metrics.ade(a, -a)
    with pytest.raises(ValueError, match=r"FDE: the distance"):
        metrics.fde(a, -a)
    with pytest.raises(ValueError, match=r"path length overflows"):
        metrics.path_length([[0.0, 0.0], [1.5e308, 0.0], [0.0, 0.0]])
    with pytest.raises(ValueError, match=r"point 0 = \(-1\.7e\+308, 1\.7e\+308\) is farther than 1\.8e308"):
        metrics.distance_to_path([[-1.7e308, 1.7e308]], path)
    with pytest.raises(ValueError, match=r"point \(-1\.7e\+308, 1\.7e\+308\) is farther than 1\.8e308"):
        Corridor(path).signed_offset([[-1.7e308, 1.7e308]])


def test_fuzz_findings_ranges_nees_and_filters():
    # found by tests/test_fuzz.py; each returned inf or NaN before
    far = MeasurementModel.range([[-1e308, 0.0], [3.0, 4.0]], 1.0)
    np.testing.assert_allclose(far.predict([4.0, 0.0, 1.0, 0.0]), [1e308, np.hypot(1.0, 4.0)], rtol=1e-15)
    assert np.isfinite(far.jacobian([4.0, 0.0, 1.0, 0.0])).all()
    with pytest.raises(ValueError, match=r"landmark 0 at \(-1e\+308, 0\) is farther than 1\.8e308 from the vehicle"):
        far.predict([1e308, 0.0, 1.0, 0.0])
    with pytest.raises(ValueError, match=r"NEES: row 0: e\^T P\^-1 e = -?(inf|nan) is not finite \(covariance diagonal 1e-310"):
        metrics.nees(np.ones((1, 4)), np.zeros((1, 4)), np.eye(4)[None] * 1e-310)
    ekf = make_ekf(x0=np.array([-1e308, -1e308, 1.0, 0.0]))
    with pytest.raises(ValueError, match=r"EKF position update: NIS = -?(inf|nan) is not finite"):
        ekf.update(MeasurementModel.position(), [5.0, 5.0])
    assert ekf.x[0] == -1e308
    # The PF and EIF overflows needed a speed or step beyond the BMM's declared
    # ranges, which BmmParams now refuses by name (their guards stay in the core).
    with pytest.raises(ValueError, match=r"max_speed = 1e\+154: must be in \(0, 100\] m/s"):
        ParticleFilter(BmmParams(max_speed=1e154, dt=1e300), X0, P0, n_particles=50, seed=1)
    with pytest.raises(ValueError, match=r"dt = 1e\+308: must be in \(0, 10\] s"):
        InformationFilter(BmmParams(dt=1e308, max_speed=0.1), X0, P0)


def test_complex_input_is_refused_not_truncated():
    # numpy would drop the imaginary part with only a ComplexWarning
    with pytest.raises(ValueError, match=r"landmarks must be real, got complex values"):
        MeasurementModel.range([[1.0 + 2j, 0.0]], 1.0)


@pytest.mark.parametrize("field, value, message", [
    ("max_steps", 2**31, r"max_steps = 2147483648 is too large \(at most 2147483647\)"),
    ("max_steps", -1, r"max_steps must be an integer >= 0, got -1"),
    ("n_particles", 0, r"n_particles must be a positive integer, got 0"),
    ("n_particles", 2**40, r"n_particles = 1099511627776 is too large"),
    ("position_every", 1.5, r"position_every must be a positive integer, got 1\.5"),
    ("planner_seed", -3, r"planner_seed must be an integer in \[0, 2\*\*64\), got -3"),
])
def test_make_navigator_checks_its_overrides(field, value, message):
    # before: int() then pybind's TypeError (2**31), or a silent int(1.5) = 1
    from safenav import navigation as nv
    from safenav.scenario import default_scenario

    path = [[10.0, 10.0], [60.0, 10.0]]
    with pytest.raises(ValueError, match=message):
        nv.make_navigator(default_scenario(), path, **{field: value})


def test_an_automatic_step_budget_beyond_the_core_limit_is_refused():
    # before: 3·L/(v·dt) + 200 overflowed int, max_steps = -2147483448, then "vector::reserve"
    from safenav import _core
    from safenav.scenario import default_scenario

    sc = default_scenario()
    assert _core.NAVIGATION_MAX_STEPS == 10_000_000
    problem = _core.NavigationProblem()
    problem.path = np.array([[0.0, 0.0], [5e6, 0.0]])
    problem.zones = sc.risk_zones()
    problem.bmm = sc.bmm_params()
    s = _core.NavigationSettings()
    s.cruise_speed = 0.01
    with pytest.raises(ValueError, match=r"automatic max_steps = .* exceeds 10000000 \(path length L = 5e\+06 m"):
        _core.Navigator(problem, s, _core.SensorSettings())
    s.max_steps = 10_000_001
    with pytest.raises(ValueError, match=r"settings.max_steps = 10000001: must be in \[0, 10000000\]"):
        _core.Navigator(problem, s, _core.SensorSettings())

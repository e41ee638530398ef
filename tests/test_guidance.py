"""The online API: :class:`Localizer` and :class:`Guidance` (guidance.hpp, localizer.hpp).

The localizer is checked against the core filters it wraps, input by input
(it must add nothing but timing): a motion input is the EKF's predict over
the timestamps' step (BMM of [SafeNav eqs. 3–9] with Δt = the step, noise
per nominal step scaled by Δt/Δt₀), a landmark observation the EKF update of
[SafeNav eqs. 12–14] with that landmark's range/bearing model.  Then the time
rules (late, ahead, catch-up), the gate, initialization from data, and
guidance's statuses and events on hand-built problems."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from safenav import _core
from safenav import guidance as gd
from safenav import navigation as nv
from safenav import planning as P
from safenav.filters import Ekf
from safenav.measurement import MeasurementModel
from safenav.motion import BmmParams

LANDMARKS = np.array([(20.0, 10.0), (20.0, -10.0), (40.0, 10.0), (40.0, -10.0), (0.0, 10.0)])
IDS = [11, 12, 13, 14, 15]
X0 = np.array([0.0, 0.0, 1.0, 0.1])
P0 = np.diag([0.5, 0.5, 0.2, 0.1]) ** 2


def localizer(gate=0.99, filter="ekf", **kw):
    loc = gd.Localizer(gd.localizer_settings(filter=filter, gate=gate, **kw), LANDMARKS, IDS)
    loc.initialize(0.0, X0, P0)
    return loc


# --------------------------------------------------------------------------- against the core filters

def test_motion_and_observations_equal_the_core_ekf_step_by_step():
    loc = localizer(gate=0.0)
    ekf = Ekf(BmmParams(), X0, P0)
    t = 0.0
    for k in range(40):
        t = (k + 1) * 0.05
        u = np.array([2.0, 0.02 * math.sin(k)])
        loc.motion(t, *u)
        ekf.predict(u)
        np.testing.assert_array_equal(loc.x, ekf.x)
        row = k % 5
        x = ekf.x
        r = float(np.hypot(*(LANDMARKS[row] - x[:2]))) + 0.05 * math.cos(k)
        b = float(np.arctan2(*(LANDMARKS[row] - x[:2])[::-1]) - x[3]) + 0.01
        kind = k % 3
        if kind == 0:
            res = loc.observe(t, IDS[row], range=r, range_std=0.3)
            ekf.update(MeasurementModel.range(LANDMARKS[row:row + 1], 0.3), [r])
        elif kind == 1:
            res = loc.observe(t, IDS[row], bearing=b, bearing_std=0.02)
            ekf.update(MeasurementModel.bearing(LANDMARKS[row:row + 1], 0.02), [b])
        else:
            res = loc.observe(t, IDS[row], range=r, bearing=b, range_std=0.3, bearing_std=0.02)
            ekf.update(MeasurementModel.range_bearing(LANDMARKS[row:row + 1], 0.3, 0.02), [r, b])
        assert res.status == gd.InputStatus.APPLIED and res.dim == (2 if kind == 2 else 1)
        np.testing.assert_allclose(loc.x, ekf.x, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(loc.P, ekf.P, rtol=1e-10, atol=1e-14)
        ekf.set_state(loc.x, loc.P)  # keep both on the same bits for the next step
    assert loc.counts.applied == 40 and loc.counts.motion == 40


def test_fix_and_imu_equal_the_core_ekf_bit_for_bit():
    loc = localizer(gate=0.0)
    ekf = Ekf(BmmParams(), X0, P0)
    R = np.diag([0.0142, 0.039]) ** 2
    Ri = np.diag([0.05, 0.02]) ** 2
    for k in range(20):
        t = (k + 1) * 0.05
        loc.motion(t, 2.0, 0.01)
        ekf.predict([2.0, 0.01])
        z = ekf.x[:2] + [0.01, -0.02]
        loc.fix(t, *z, R)
        ekf.update(MeasurementModel.position(R), z)
        loc.speed_heading(t, 1.9, 0.12, 0.05, 0.02)
        ekf.update(MeasurementModel.speed_heading(Ri), [1.9, 0.12])
        np.testing.assert_array_equal(loc.x, ekf.x)
        np.testing.assert_array_equal(loc.P, ekf.P)


@settings(max_examples=40, deadline=None)
@given(dt=st.floats(0.001, 2.0), speed=st.floats(0.0, 8.0), turn=st.floats(-1.0, 1.0))
def test_a_step_of_any_length_is_the_bmm_with_that_step(dt, speed, turn):
    """Bmm::with_step: Δt → dt in eqs. 3–9, σ² per nominal step × dt/Δt₀."""
    loc = localizer(gate=0.0)
    loc.motion(dt, speed, turn)
    p = BmmParams()
    s = math.sqrt(dt / p.dt)
    q = BmmParams(dt=dt, speed_noise=p.speed_noise * s, heading_noise=p.heading_noise * s,
                  position_noise=p.position_noise * s)
    if abs(dt - p.dt) <= 1e-6 * p.dt:
        q = p  # timestamp rounding: the nominal step
    ekf = Ekf(q, X0, P0)
    ekf.predict([speed, turn])
    np.testing.assert_allclose(loc.x, ekf.x, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(loc.P, ekf.P, rtol=1e-12, atol=1e-15)
    assert loc.time == dt


# --------------------------------------------------------------------------- time

def test_a_late_measurement_is_not_applied():
    """Older than max_delay (tests/test_late.py has those within it), or a late motion input."""
    loc = localizer()
    loc.motion(0.1, 1.0, 0.0)
    loc.motion(0.7, 1.0, 0.0)
    x, P = loc.x.copy(), loc.P.copy()
    for res in (loc.observe(0.05, 11, range=20.0), loc.fix(0.09, 0.0, 0.0, np.eye(2)),
                loc.speed_heading(0.0, 1.0, 0.1, 0.1, 0.1), loc.motion(0.68, 1.0, 0.0)):
        assert res.status == gd.InputStatus.LATE
    np.testing.assert_array_equal(loc.x, x)
    np.testing.assert_array_equal(loc.P, P)
    assert loc.counts.late == 4 and loc.time == 0.7


def test_a_measurement_ahead_predicts_to_its_time_and_the_motion_input_catches_up():
    """Between motion inputs at constant rates, a measurement (here one that
    carries no information: σ huge) at 0.13 s splits the step; the next input
    applies only what its distance and heading change still owe, so the end
    state is the unsplit one."""
    split, whole = localizer(gate=0.0), localizer(gate=0.0)
    for loc in (split, whole):
        loc.motion(0.1, 1.0, 0.02)
    res = split.observe(0.13, 11, range=20.0, range_std=1e9)
    assert res.applied and split.time == pytest.approx(0.13)
    split.motion(0.2, 1.0, 0.02)
    whole.motion(0.2, 1.0, 0.02)
    assert split.time == whole.time == 0.2
    # Same heading and speed; the position differs only by where the turn is
    # applied (eq. 7 moves along the updated heading): at most v·Δt·|Δθ|.
    np.testing.assert_allclose(split.x[2:], whole.x[2:], rtol=0, atol=1e-12)
    assert np.hypot(*(split.x[:2] - whole.x[:2])) <= 1.0 * 0.1 * 0.02


def test_equal_times_apply_in_call_order():
    a, b = localizer(gate=0.0), localizer(gate=0.0)
    for loc in (a, b):
        loc.motion(0.05, 1.0, 0.0)
    a.observe(0.05, 11, range=19.0, range_std=0.5)
    a.observe(0.05, 12, range=23.0, range_std=0.5)
    b.observe(0.05, 11, range=19.0, range_std=0.5)
    assert a.time == b.time == 0.05
    assert a.counts.applied == 2 and not np.array_equal(a.x, b.x)


# --------------------------------------------------------------------------- gate

@pytest.mark.parametrize("filter", ["ekf", "pf"])
def test_the_gate_rejects_a_gross_outlier_and_keeps_the_estimate(filter):
    loc = localizer(filter=filter, n_particles=300)
    loc.motion(0.05, 1.0, 0.0)
    x, P = loc.x.copy(), loc.P.copy()
    res = loc.observe(0.05, 11, range=80.0, range_std=0.2)
    assert res.status == gd.InputStatus.REJECTED and res.nis > _core.chi2_quantile(0.99, 1)
    np.testing.assert_array_equal(loc.x, x)
    np.testing.assert_array_equal(loc.P, P)
    good = loc.observe(0.05, 11, range=float(np.hypot(*(LANDMARKS[0] - x[:2]))), range_std=0.2)
    assert good.applied and loc.counts.rejected == 1


def test_gate_zero_applies_everything():
    loc = localizer(gate=0.0)
    assert loc.observe(0.0, 11, range=80.0, range_std=0.2).applied


def test_the_online_gate_is_on_by_default():
    assert gd.LocalizerSettings().filter.gate_probability == 0.99
    assert gd.LocalizerSettings().get_param("gate_probability") == 0.99


def test_particle_filter_localizer_is_fixed_by_its_seed():
    runs = []
    for _ in range(2):
        loc = localizer(filter="pf", n_particles=200, seed=7)
        for k in range(10):
            t = (k + 1) * 0.05
            loc.motion(t, 1.0, 0.0)
            loc.observe(t, 11, range=float(np.hypot(*(LANDMARKS[0] - loc.x[:2]))), bearing=0.3)
        runs.append(loc.x.copy())
    np.testing.assert_array_equal(*runs)


# --------------------------------------------------------------------------- start from data

def _drive(loc, seconds, *, ranges=True, fixes=False, rng=None, heading=0.3, speed=1.5):
    """A vehicle on a straight line from the origin; odometry at 10 Hz, ranges to every landmark at 5 Hz."""
    rng = rng or np.random.default_rng(0)
    truth = []
    for k in range(1, int(seconds * 10) + 1):
        t = k * 0.1
        p = speed * t * np.array([math.cos(heading), math.sin(heading)])
        loc.odometry(t, speed * 0.1, 0.0)
        if k % 2 == 0:
            if ranges:
                for row, lm in enumerate(LANDMARKS):
                    loc.observe(t, IDS[row], range=float(np.hypot(*(lm - p)) + 0.05 * rng.normal()), range_std=0.05)
            if fixes:
                loc.fix(t, *(p + 0.05 * rng.normal(size=2)), np.eye(2) * 0.05 ** 2)
        truth.append((t, *p))
    return np.array(truth)


@pytest.mark.parametrize("source", ["ranges", "fixes"])
def test_starts_from_the_data_alone(source):
    loc = gd.Localizer(gd.localizer_settings(), LANDMARKS, IDS)
    assert not loc.initialized and np.isnan(loc.x).all()
    truth = _drive(loc, 30.0, ranges=source == "ranges", fixes=source == "fixes")
    assert loc.initialized and loc.counts.buffered > 0
    assert np.hypot(*(loc.x[:2] - truth[-1, 1:])) < 0.3
    assert abs(loc.x[3] - 0.3) < 0.05


def test_an_imu_heading_starts_it_at_the_first_position():
    loc = gd.Localizer(gd.localizer_settings(), LANDMARKS, IDS)
    loc.speed_heading(0.0, 0.0, 0.3, 0.1, 0.01)
    assert loc.fix(0.0, 1.0, 2.0, np.eye(2) * 0.01).status == gd.InputStatus.BUFFERED
    assert loc.initialized and loc.x[3] == pytest.approx(0.3)


# --------------------------------------------------------------------------- bad input

@pytest.mark.parametrize("call, match", [
    (lambda l: l.motion(float("nan"), 1.0, 0.0), "time t = nan"),
    (lambda l: l.motion(1.0, float("inf"), 0.0), "not finite"),
    (lambda l: l.observe(1.0, 99, range=3.0), "unknown landmark id 99"),
    (lambda l: l.observe(1.0, 11), "neither a range nor a bearing"),
    (lambda l: l.observe(1.0, 11, range=-1.0), "range = -1"),
    (lambda l: l.observe(1.0, 11, range=1.0, range_std=0.0), "range_std = 0"),
    (lambda l: l.fix(1.0, 0.0, 0.0, np.array([[1.0, 0.0], [0.0, -1.0]])), "positive definite"),
    (lambda l: l.fix(1.0, float("nan"), 0.0, np.eye(2)), "not finite"),
])
def test_bad_input_names_the_value(call, match):
    with pytest.raises(ValueError, match=match):
        call(localizer())


@pytest.mark.parametrize("filter", ["ekf", "pf"])
def test_a_fix_covariance_symmetric_to_rounding_is_taken(filter):
    """A trilaterated fix's off-diagonal can cancel to ~1e-11 of its
    diagonal and carry the diagonal's rounding: R01 and R10 then differ in
    their own leading digits, by far less than the matrix's own rounding
    (such a fix stopped a certified PF trial).  Symmetry is judged against
    the largest entry, as for every other covariance: that fix is taken, and
    one whose off-diagonals differ by more than 1e-9 of it is refused."""
    R = np.array([[0.00116454, -2.28529e-11], [-2.28529e-11 * (1 + 1e-6), 0.00293006]])
    loc = localizer(filter=filter, gate=0.0)
    assert loc.fix(0.1, X0[0] + 0.01, X0[1] - 0.01, R).status == gd.InputStatus.APPLIED
    bad = R.copy()
    bad[1, 0] += 2e-9 * R.max()
    with pytest.raises(ValueError, match="symmetric"):
        localizer(filter=filter, gate=0.0).fix(0.1, X0[0], X0[1], bad)


def test_bad_construction():
    with pytest.raises(ValueError, match="appears twice"):
        gd.Localizer(gd.LocalizerSettings(), LANDMARKS[:2], [3, 3])
    with pytest.raises(ValueError, match="2 ids for 5 landmarks"):
        gd.Localizer(gd.LocalizerSettings(), LANDMARKS, [1, 2])
    s = gd.LocalizerSettings()
    with pytest.raises(ValueError, match="gate_probability"):
        s.set_param("gate_probability", 1.5)


# --------------------------------------------------------------------------- guidance

def _problem(path, obstacles=()):
    p = _core.NavigationProblem()
    p.path = np.asarray(path, float)
    p.zones = _core.RiskZones()
    p.map = P.make_map(lower=(-20, -40), upper=(120, 40), polygons=[np.asarray(o, float) for o in obstacles],
                       clearance=0.5)
    p.bmm = BmmParams()
    return p


def _guidance(path, obstacles=(), method="centroid", seed=0):
    s = _core.NavigationSettings()
    s.method = nv.METHODS[method]
    s.planner = P.PlannerSettings(max_iterations=1500, corridor_bias=0.5, smooth=True)
    return gd.Guidance(_problem(path, obstacles), s, gd.localizer_settings(), LANDMARKS, IDS, seed)


def _fly(g, steps, *, dt=0.05):
    """Drive guidance with a perfect vehicle (fixes at the true position)."""
    p = g.problem.path[0]
    truth = np.array([p[0], p[1], 0.0, 0.0])
    g.localizer.initialize(0.0, truth, np.diag([0.01, 0.01, 0.01, 0.01]))
    bmm = _core.Bmm(BmmParams())
    cmds = []
    for k in range(steps):
        c = g.command(k * dt)
        cmds.append(c)
        if c.status != gd.GuidanceStatus.GUIDING:
            break
        truth = bmm.predict(truth, c.control)
        g.motion((k + 1) * dt, c.speed, c.heading_change)
        g.fix((k + 1) * dt, truth[0], truth[1], np.eye(2) * 1e-4)
        g.speed_heading((k + 1) * dt, truth[2], truth[3], 0.05, 0.02)
    return cmds


@pytest.mark.parametrize("method", ["centroid", "chull"])
def test_guidance_arrives_and_says_so(method):
    g = _guidance([(0.0, 0.0), (30.0, 0.0)], method=method)
    assert g.command(0.0).status == gd.GuidanceStatus.INITIALIZING
    cmds = _fly(g, 2000)
    assert cmds[-1].status == gd.GuidanceStatus.ARRIVED
    assert gd.event_names(cmds[-1].events) == ["arrived"]
    assert all(c.status == gd.GuidanceStatus.GUIDING for c in cmds[:-1])
    assert np.isfinite(cmds[0].position_std) and cmds[0].speed > 0


def test_guidance_plans_a_detour_round_an_obstacle_on_the_path():
    box = [(40.0, -3.0), (46.0, -3.0), (46.0, 3.0), (40.0, 3.0)]
    g = _guidance([(0.0, 0.0), (90.0, 0.0)], obstacles=[box], seed=3)
    cmds = _fly(g, 4000)
    flags = [gd.event_names(c.events) for c in cmds if c.events]
    assert ["detour_planned", "path_spliced"] in flags
    assert cmds[-1].status == gd.GuidanceStatus.ARRIVED and g.replans >= 1
    assert len(g.path) > 2   # the detour is spliced into the path followed


def test_lost_localization_stops_guidance():
    g = _guidance([(0.0, 0.0), (30.0, 0.0)])
    g.localizer.initialize(0.0, np.array([0.0, 0.0, 0.0, 0.0]), np.diag([400.0, 400.0, 1.0, 1.0]))
    c = g.command(0.0)
    assert c.status == gd.GuidanceStatus.LOST_LOCALIZATION and c.speed == 0.0
    assert gd.event_names(c.events) == ["lost_localization"] and "position std" in g.detail


def test_fresh_runs_are_independent_and_repeatable():
    g = _guidance([(0.0, 0.0), (30.0, 0.0)])
    a = [c.heading_change for c in _fly(g.fresh(5), 50)]
    b = [c.heading_change for c in _fly(g.fresh(5), 50)]
    assert a == b


def test_guidance_can_plan_its_safe_path_first():
    """Guidance.planned: RAw-RRT* [SafeNav eq. 19] from start to goal round an obstacle, then guidance on it."""
    box = [(40.0, -3.0), (46.0, -3.0), (46.0, 3.0), (40.0, 3.0)]
    problem = _problem([(0.0, 0.0), (90.0, 0.0)], obstacles=[box])
    planning = P.PlanningProblem(map=problem.map, start=np.array([0.0, 0.0]), goal=np.array([90.0, 0.0]),
                                 central_path=np.array([(0.0, 0.0), (90.0, 0.0)]), zones=problem.zones)
    s = _core.NavigationSettings()
    g = gd.Guidance.planned(planning, P.PlannerSettings(max_iterations=2000, seed=1, smooth=True), problem, s,
                            gd.localizer_settings(), LANDMARKS, IDS, 0)
    path = g.problem.path
    assert np.array_equal(path[0], [0.0, 0.0]) and np.array_equal(path[-1], [90.0, 0.0]) and len(path) > 2
    checker = _core.ObstacleChecker(problem.map)
    assert all(checker.segment_free(a, b) for a, b in zip(path[:-1], path[1:]))
    assert _fly(g, 4000)[-1].status == gd.GuidanceStatus.ARRIVED
    blocked = P.PlanningProblem(map=problem.map, start=np.array([0.0, 0.0]), goal=np.array([43.0, 0.0]),
                                zones=problem.zones)
    with pytest.raises(ValueError):
        gd.Guidance.planned(blocked, P.PlannerSettings(max_iterations=100, seed=1), problem, s)


def test_the_guard_looks_with_the_camera_in_one_place():
    """look_with_camera maps a camera onto the guard's look (FOV at most 2π, at
    least one landmark); guidance and the simulator's Navigator agree."""
    g = _core.GuardSettings()
    g.look_with_camera(7.0, 12.5, 0, False)
    assert (g.field_of_view, g.look_range, g.look_min_landmarks, g.occlusion) == (2 * math.pi, 12.5, 1, False)
    sc = __import__("safenav").default_scenario()
    safe = np.array([(5.0, 20.0), (55.0, 20.0)])
    a = gd.make_guidance(sc, safe).settings.guard
    b = nv.make_navigator(sc, safe).settings.guard
    for name in ("field_of_view", "look_range", "look_min_landmarks", "occlusion"):
        assert getattr(a, name) == getattr(b, name), name
    assert a.field_of_view == pytest.approx(math.radians(sc.camera.field_of_view_deg))
    assert a.look_range == sc.detection.max_range_m


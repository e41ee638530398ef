"""The belief-aware roadmap planner (safenav.planning.plan_belief; RRBT-style
search with a k-sigma chance constraint) beside the paper's RAw-RRT*."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from safenav import _core
from safenav import planning as P
from safenav.belief import robust_sight, start_covariance

from test_belief import corridor_world

START, GOAL = (5.0, 20.0), (55.0, 20.0)
RADIUS, MARGIN = 0.5, 0.25
P0 = np.diag([1e-4, 1e-4, 2.5e-3, 4e-4])  # a start with a fix (the default heading toward the goal sees none)


def plan(m, bmm, se, **kw):
    args = dict(sensors=se, bmm=bmm, vehicle_radius=RADIUS, margin=MARGIN, seed=3, start_cov=P0)
    args.update(kw)
    return P.plan_belief(m, START, GOAL, **args)


def through_corridor(path):
    """The path runs through the narrow corridor (15 < x < 45 at y < 21.5)."""
    v = np.asarray(path)
    t = np.linspace(0.0, 1.0, 50)[:, None]
    p = np.concatenate([a + t * (b - a) for a, b in zip(v[:-1], v[1:])])
    mid = (p[:, 0] > 16) & (p[:, 0] < 44)
    return bool(mid.any()) and p[mid, 1].max() < 21.5


def test_belief_planner_takes_the_lane_with_landmarks_where_raw_rrt_star_takes_the_blind_corridor():
    m, bmm, se = corridor_world()
    # The straight line through the corridor is in the roadmap (a guide path):
    # the constraint, not the sampling, must turn it down.
    res = plan(m, bmm, se, k_sigma=3.0, guide_paths=[np.array([START, GOAL])])
    assert res.success and res.status == P.BeliefPlanStatus.EXACT, res.detail
    assert not through_corridor(res.path) and np.asarray(res.path)[:, 1].max() > 32
    assert res.result.planning_time < 2.0
    prof = res.profile
    # The chance constraint holds at every stage of the returned path.
    need = np.asarray(prof.clearance) - RADIUS - MARGIN
    assert np.all(3.0 * np.asarray(prof.sigma_toward) <= need + 1e-9)
    assert res.collision_probability < 1e-6
    np.testing.assert_array_equal(res.sigma, prof.sigma)
    assert np.isclose(res.result.cost, prof.length)  # alpha = 1, sigma_weight = 0

    # RAw-RRT* (the paper's planner, plain RRT* here: no central path) goes straight through.
    mc = P.make_map(upper=(60, 40), polygons=[np.asarray(p) for p in m.polygons], clearance=RADIUS + MARGIN)
    rrt = P.plan(P.PlanningProblem(map=mc, start=START, goal=GOAL), beta=0.0, max_iterations=3000, seed=1)
    assert rrt.success and through_corridor(rrt.path)
    blind = P.propagate_belief(rrt.path, sensors=se, map=m, bmm=bmm, vehicle_radius=RADIUS, margin=MARGIN,
                               step=0.25, start_cov=P0, **robust_sight())
    # The lane sees its landmarks through the planner's robust camera
    # (robust_sight), so its σ grows too, but less than blind.
    assert blind.sigma.max() > 1.3 * res.sigma.max()
    assert blind.collision_probability > 0.05 > res.collision_probability
    assert np.asarray(blind.landmarks)[np.asarray(blind.positions)[:, 0] > 16].max() == 0


def test_a_looser_constraint_takes_the_short_corridor():
    m, bmm, se = corridor_world()
    res = plan(m, bmm, se, k_sigma=0.5, guide_paths=[np.array([START, GOAL])])
    assert res.success and through_corridor(res.path)
    assert res.profile.length < 60


def test_shortcuts_shorten_and_keep_the_constraint():
    m, bmm, se = corridor_world()
    raw = plan(m, bmm, se, shortcut=False)
    cut = plan(m, bmm, se, shortcut=True)
    assert raw.success and cut.success
    assert cut.profile.length < raw.profile.length and len(cut.path) < len(raw.path)
    assert not through_corridor(cut.path)
    need = np.asarray(cut.profile.clearance) - RADIUS - MARGIN
    assert np.all(3.0 * np.asarray(cut.profile.sigma_toward) <= need + 1e-9)
    # Every shortcut edge is free of the grown obstacles.
    grown = P.make_map(upper=(60, 40), polygons=[np.asarray(p) for p in m.polygons], clearance=RADIUS + MARGIN)
    assert P.path_is_free(grown, cut.path)


def test_the_cost_is_length_plus_the_sigma_integral():
    m, bmm, se = corridor_world()
    res = plan(m, bmm, se, k_sigma=3.0, sigma_weight=2.0, alpha=1.5)
    prof = res.profile
    seg = np.linalg.norm(np.diff(np.asarray(prof.positions), axis=0), axis=1)
    expect = 1.5 * prof.length + 2.0 * np.sum(np.asarray(prof.sigma)[1:] * seg)
    assert np.isclose(res.result.cost, expect, rtol=1e-9)


def test_same_seed_same_path_and_guides_join_the_roadmap():
    m, bmm, se = corridor_world()
    a, b = plan(m, bmm, se), plan(m, bmm, se)
    np.testing.assert_array_equal(a.path, b.path)
    # No samples: the roadmap is start, goal and the guide paths only.
    lane = np.array([START, (10.0, 36.0), (50.0, 36.0), GOAL])
    straight = np.array([START, GOAL])
    res = plan(m, bmm, se, samples=0, guide_paths=[straight, lane])
    assert res.success, res.detail
    assert not through_corridor(res.path)
    res = plan(m, bmm, se, samples=0, guide_paths=[straight])
    assert res.status == P.BeliefPlanStatus.INFEASIBLE and "3*sigma" in res.detail
    assert plan(m, bmm, se, samples=0, guide_paths=[straight], k_sigma=0.5).success


def test_infeasible_and_unreachable_problems_say_why():
    m, bmm, se = corridor_world()
    # The lane closed: only the blind corridor is left.
    shut = P.make_map(upper=(60, 40), polygons=list(m.polygons) + [np.array([[15.0, 32], [45, 32], [45, 40], [15, 40]])])
    res = plan(shut, bmm, se)
    assert not res.success and res.status == P.BeliefPlanStatus.INFEASIBLE
    assert res.path.shape == (0, 2) and np.isnan(res.collision_probability) and res.profile is None
    # A start covariance that breaks the constraint at once.
    res = plan(m, bmm, se, start_cov=np.diag([16.0, 16.0, 0.01, 0.01]))
    assert res.status == P.BeliefPlanStatus.INFEASIBLE and "start" in res.detail
    # A goal inside an obstacle; a goal walled in.
    res = P.plan_belief(m, START, (30.0, 10.0), sensors=se, bmm=bmm)
    assert res.status == P.BeliefPlanStatus.NO_PATH and "goal" in res.detail
    box = [np.array([[50.0, 15], [58, 15], [58, 16], [50, 16]]), np.array([[50.0, 24], [58, 24], [58, 25], [50, 25]]),
           np.array([[50.0, 15], [51, 15], [51, 25], [50, 25]]), np.array([[57.0, 15], [58, 15], [58, 25], [57, 25]])]
    walled = P.make_map(upper=(60, 40), polygons=list(m.polygons) + box)
    res = P.plan_belief(walled, START, GOAL, sensors=se, bmm=bmm, vehicle_radius=RADIUS, margin=MARGIN)
    assert res.status == P.BeliefPlanStatus.NO_PATH and "does not join" in res.detail
    res = plan(m, bmm, se, max_expansions=3)
    assert res.status == P.BeliefPlanStatus.BUDGET


@pytest.mark.parametrize("kwargs, err, match", [
    ({"k_sigma": -1.0}, ValueError, "k_sigma"),
    ({"samples": -5}, ValueError, "samples"),
    ({"speed": 0.0}, ValueError, "speed"),
    ({"seed": -1}, ValueError, "seed"),
    ({"max_beliefs": 0}, ValueError, "max_beliefs"),
    ({"max_turn": 0.0}, ValueError, "max_turn"),
    ({"max_turn": 3.2}, ValueError, "max_turn"),
    ({"max_turn": float("nan")}, ValueError, "max_turn"),
    ({"turn_window": -1.0}, ValueError, "turn_window"),
    ({"turn_window": float("inf")}, ValueError, "turn_window"),
    ({"frobnicate": 1}, TypeError, "frobnicate"),
])
def test_bad_settings_name_the_value(kwargs, err, match):
    m, bmm, se = corridor_world()
    with pytest.raises(err, match=match):
        plan(m, bmm, se, **kwargs)


def test_the_default_start_covariance_is_the_navigation_loops_prior():
    m, bmm, se = corridor_world()
    no_fix = start_covariance(se, m, np.array(START), 0.0)  # heading +x: no landmark in the field of view
    fix = start_covariance(se, m, np.array(START), np.pi / 2)  # heading +y: the landmarks along the top
    assert np.allclose(np.diag(no_fix)[:2], 1.0)
    np.testing.assert_allclose(fix[:2, :2], se.position.reported_cov())
    assert np.allclose(np.diag(fix)[2:], [se.imu_speed_std ** 2, se.imu_heading_std ** 2])
    res = P.plan_belief(m, START, GOAL, sensors=se, bmm=bmm, vehicle_radius=RADIUS, margin=MARGIN, seed=3)
    assert res.success and np.isclose(res.sigma[0], 1.0)


def test_bad_problem_names_the_value():
    m, bmm, se = corridor_world()
    with pytest.raises(ValueError, match="start"):
        P.plan_belief(m, (np.nan, 1.0), GOAL, sensors=se)
    with pytest.raises(ValueError, match="goal"):
        P.plan_belief(m, START, START, sensors=se)
    with pytest.raises(ValueError, match="start_cov"):
        P.plan_belief(m, START, GOAL, sensors=se, start_cov=np.zeros((4, 4)))
    with pytest.raises(ValueError, match=r"guide_paths\[0\]"):
        P.plan_belief(m, START, GOAL, sensors=se, guide_paths=[[[0.0, 1.0, 2.0]]])


@pytest.mark.parametrize("core_type", [_core.BeliefSettings, _core.BeliefPlannerSettings], ids=lambda t: t.__name__)
def test_every_declaration_is_complete_and_its_default_in_range(core_type):
    specs = core_type.params()
    assert specs and len({s.name for s in specs}) == len(specs)
    obj = core_type()
    obj.check_params()  # the member initialisers lie in the declared ranges
    for s in specs:
        v = obj.get_param(s.name)
        assert s.doc and s.hi >= s.lo, s.name
        assert (s.lo < v if s.lo_open else s.lo <= v) and v <= s.hi, s.name


def test_settings_declare_their_parameters():
    names = {p.name for p in _core.BeliefPlannerSettings.params()}
    assert {"k_sigma", "belief.speed", "belief.inflation.vehicle_radius", "max_beliefs"} <= names
    s = _core.BeliefPlannerSettings()
    assert s.k_sigma == 3.0 and s.belief.step == 0.25
    with pytest.raises(ValueError, match="k_sigma"):
        s.set_param("k_sigma", -2.0)


def turns(path) -> np.ndarray:
    """The turn at each inner vertex of a polyline [rad, 0..π]."""
    d = np.diff(np.asarray(path, dtype=float), axis=0)
    u, w = d[:-1], d[1:]
    return np.arctan2(np.abs(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]), np.einsum("ij,ij->i", u, w))


def window_turns(path, window: float) -> np.ndarray:
    """At each inner vertex, the sum of the turns there and at the later
    vertices less than ``window`` metres of path after it."""
    t = turns(path)
    legs = np.linalg.norm(np.diff(np.asarray(path, dtype=float), axis=0), axis=1)
    out = t.copy()
    for i in range(len(t)):
        run = 0.0
        for j in range(i + 1, len(t)):
            run += legs[j]  # from vertex i+1 (turn i) to vertex j+1 (turn j)
            if run >= window:
                break
            out[i] += t[j]
    return out


@pytest.mark.parametrize("world, loose", [(23, dict(max_turn=np.pi, turn_window=0.0)), (29, dict(turn_window=0.0))],
                         ids=["doubles-back", "two-turns"])
def test_a_planned_path_does_not_turn_around_to_look_at_the_landmarks_behind(world, loose):
    """Generated worlds 23 and 29 (no benchmark was tuned on them): P1 runs
    blind with landmarks behind or beside it.  Without the turn limit the
    planner turns the belief's camera, which turns with each leg at once, to
    them: world 23's path drives 16 m and doubles back 1 m (turns of 160°);
    with the limit at single vertices only, world 29's turns 57° one way and
    88° the other within 2.9 m, a glance aside.  The controllers aim 5 m ahead and cut both, so no driven
    vehicle got those fixes (bench_certified.py: RMS error 9–11× the
    predicted).  With the defaults no 5 m of the path turns by more than
    90° in all, and the plan holds its chance constraint without the look."""
    from safenav import certify as C
    from safenav.generate import generate_scenario

    sc = generate_scenario(world)
    raw = np.asarray(C.plan_or_none(sc, "P1").path)
    k, _ = C.risk_k(sc, raw)
    window = sc.navigation.lookahead
    res = C.plan_belief_path(sc, raw, k, **loose)
    assert res.success and window_turns(res.path, window).max() > np.deg2rad(130)
    res = C.plan_belief_path(sc, raw, k)
    assert res.success, res.detail
    assert window_turns(res.path, window).max() <= np.pi / 2 + 1e-12
    kw = C.mission_inputs(sc, raw)
    need = np.asarray(res.profile.clearance) - kw["vehicle_radius"] - kw["margin"]
    assert np.all(k * np.asarray(res.profile.sigma_toward) <= need + 1e-9)


@settings(max_examples=8, deadline=None)
@given(max_turn=st.floats(np.deg2rad(20), np.pi), window=st.sampled_from([0.0, 5.0, 12.0]),
       seed=st.integers(0, 3))
def test_no_stretch_of_a_planned_path_turns_more_than_max_turn(max_turn, window, seed):
    m, bmm, se = corridor_world()
    assert plan(m, bmm, se, k_sigma=3.0, max_turn=np.pi, turn_window=0.0, seed=seed).success
    res = plan(m, bmm, se, k_sigma=3.0, max_turn=max_turn, turn_window=window, seed=seed)
    if res.success:
        assert window_turns(res.path, window).max(initial=0.0) <= max_turn + 1e-12
    else:
        assert res.status in (P.BeliefPlanStatus.INFEASIBLE, P.BeliefPlanStatus.NO_PATH), res.detail


def test_guides_that_meet_at_a_point_do_not_hide_a_hairpin():
    """Around the wall's end the roadmap turns by 172° at P, or by 86° twice
    within a few metres, both beyond the 90° limit, however the guides
    reach P: through one guide, a guide that repeats P, or two guides that
    meet there.  Coincident guide points are one roadmap vertex, so no edge has
    zero length (a leg of no length has no heading to turn from)."""
    wall = np.array([[0.0, 21.5], [20.0, 21.5], [20.0, 22.5], [0.0, 22.5]])
    m = P.make_map(upper=(60.0, 40.0), polygons=[wall])
    xs = np.arange(0.0, 61.0, 5.0)
    _, bmm, se = corridor_world()
    se.landmarks = np.r_[np.c_[xs, np.full_like(xs, 39.5)], np.c_[xs, np.full_like(xs, 0.5)]]
    s, g, apex = (5.0, 19.0), (5.0, 25.0), (50.0, 22.0)
    for guides in ([np.array([s, apex, g])], [np.array([s, apex, apex, g])], [np.array([s, apex]), np.array([apex, g])]):
        kw = dict(sensors=se, bmm=bmm, vehicle_radius=0.2, margin=0.05, seed=3, start_cov=P0, samples=0,
                  k_sigma=0.0, guide_paths=guides, shortcut=False)
        assert P.plan_belief(m, s, g, max_turn=np.pi, turn_window=0.0, **kw).success
        res = P.plan_belief(m, s, g, **kw)
        assert res.status == P.BeliefPlanStatus.INFEASIBLE and "max_turn" in res.detail, res.path


def test_pruning_keeps_a_belief_that_can_still_make_the_next_turn():
    """Two guide routes reach f: A, shorter, turning by 44° at f; B straight.
    Beyond f the path turns by 60° at v, 30 m on, so within a 50 m window
    only B may take it (44 + 60 > 90).  A's belief is cheaper and as
    certain; it must not prune B's (they came along different edges)."""
    d = lambda deg: np.array([np.cos(np.deg2rad(deg)), np.sin(np.deg2rad(deg))])
    f = np.array([100.0, 80.0])
    v, y = f + 30 * d(0), f - 30 * d(0)
    u = v + 40 * d(60)
    goal, w1 = u + 40 * d(60), y - 40 * d(40)
    start = w1 - 40 * d(80)
    a_dir = (f - start) / np.linalg.norm(f - start)
    route_b = np.array([start, w1, y, f, v, u, goal])
    route_a = np.array([start, 0.5 * (start + f), f - 1e-3 * a_dir])
    gx, gy = np.meshgrid(np.arange(0, 221, 20.0), np.arange(0, 181, 20.0))
    _, bmm, se = corridor_world()
    se.landmarks = np.c_[gx.ravel(), gy.ravel()]
    m = P.make_map(upper=(220.0, 180.0))
    kw = dict(sensors=se, bmm=bmm, vehicle_radius=0.2, margin=0.05, start_cov=P0, samples=0, k_sigma=0.0,
              max_edge=1.0, guide_spacing=1000.0, turn_window=50.0, shortcut=False)
    only_b = P.plan_belief(m, start, goal, guide_paths=[route_b], **kw)
    assert only_b.success
    both = P.plan_belief(m, start, goal, guide_paths=[route_b, route_a], **kw)
    assert both.success, both.detail
    assert window_turns(both.path, 50.0).max() <= np.pi / 2 + 1e-12

"""Hazard-aware planning: the exact in-hazard length, the
hazard term of the RAw-RRT* cost, forbidden hazards, obstacle inflation and the
PathSafety report; the defaults leave the paper's planner bit for bit unchanged."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from safenav import _core, planning
from safenav.scenario import NavigationParams, PlannerParams, default_scenario

HZ = _core.HazardZone
SQUARE = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])


def checker(*hazards, **kw) -> _core.ObstacleChecker:
    return _core.ObstacleChecker(planning.make_map(lower=(-100, -100), upper=(100, 100), hazards=hazards, **kw))


def brute_length(ck, a, b, n=20000) -> float:
    """Length inside the (single) hazard by the midpoint rule on n cells."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    t = (np.arange(n) + 0.5) / n
    pts = a + t[:, None] * (b - a)
    return float(np.count_nonzero(ck.hazard_risk(pts) > 0)) / n * float(np.linalg.norm(b - a))


# ---------------------------------------------------------------- exact length

@pytest.mark.parametrize("a, b, expect", [
    ((2, 0), (8, 0), 6.0),                                 # along an edge (the boundary is inside)
    ((-5, 0), (15, 0), 10.0),                              # along a whole edge and beyond
    ((-5, -5), (15, 15), 10 * math.sqrt(2)),               # through two vertices, the diagonal
    ((-5, -5), (5, 5), 5 * math.sqrt(2)),                  # through a vertex into the inside
    ((-5, 5), (5, -5), 0.0),                               # touches a vertex only
    ((-5, 3), (15, 3), 10.0),                              # straight across
    ((3, 3), (3, 3), 0.0),                                 # zero length, inside
    ((2, 2), (8, 7), math.hypot(6, 5)),                    # wholly inside
    ((20, 20), (30, 40), 0.0),                             # far away
])
def test_polygon_degenerate_cases(a, b, expect):
    ck = checker(HZ.from_polygon(SQUARE, 0.5))
    got = ck.hazard_lengths(np.array(a, float), np.array(b, float))
    assert got.shape == (1,) and got[0] == pytest.approx(expect, abs=1e-9)
    assert ck.hazard_integral(np.array(a, float), np.array(b, float)) == pytest.approx(0.5 * expect, abs=1e-9)


def test_disc_degenerate_cases():
    ck = checker(HZ.from_circle(np.array([0.0, 0.0]), 5.0, 1.0))
    L = lambda a, b: ck.hazard_lengths(np.array(a, float), np.array(b, float))[0]  # noqa: E731
    assert L((-10, 5), (10, 5)) <= 1e-6          # tangent: one point, no length
    assert L((-10, 0), (10, 0)) == pytest.approx(10.0, abs=1e-12)
    assert L((0, 0), (0, 2)) == pytest.approx(2.0, abs=1e-12)   # inside
    assert L((0, 0), (0, 0)) == 0.0              # zero length
    assert L((-10, 3), (10, 3)) == pytest.approx(8.0, abs=1e-12)
    assert L((0, 0), (10, 0)) == pytest.approx(5.0, abs=1e-12)  # starts at the centre


def test_concave_polygon_crossed_twice():
    # A U: the segment y = 8 crosses both arms (2 m each) and the gap between them.
    u = np.array([[0, 0], [10, 0], [10, 10], [8, 10], [8, 2], [2, 2], [2, 10], [0, 10]], float)
    ck = checker(HZ.from_polygon(u, 1.0))
    assert ck.hazard_lengths(np.array([-5.0, 8.0]), np.array([15.0, 8.0]))[0] == pytest.approx(4.0, abs=1e-9)
    # along the inner edge y = 2 from x = 2 to 8 and the bottom bar's inside
    assert ck.hazard_lengths(np.array([-5.0, 2.0]), np.array([15.0, 2.0]))[0] == pytest.approx(10.0, abs=1e-9)


coord = st.floats(-30, 30, allow_nan=False, allow_infinity=False)


@st.composite
def star_polygon(draw):
    """A simple (star-shaped) polygon: vertices at increasing angles around a centre."""
    n = draw(st.integers(3, 9))
    cx, cy = draw(coord), draw(coord)
    angles = np.sort(np.array(draw(st.lists(st.floats(0, 2 * np.pi, exclude_max=True), min_size=n, max_size=n,
                                            unique=True))))
    if np.min(np.diff(np.r_[angles, angles[0] + 2 * np.pi])) < 0.05:
        angles = np.linspace(0, 2 * np.pi, n, endpoint=False) + angles[0]
    radii = np.array(draw(st.lists(st.floats(1, 20), min_size=n, max_size=n)))
    return np.c_[cx + radii * np.cos(angles), cy + radii * np.sin(angles)]


@settings(max_examples=60, deadline=None)
@given(poly=star_polygon(), a=st.tuples(coord, coord), b=st.tuples(coord, coord))
def test_polygon_length_matches_fine_sampling(poly, a, b):
    ck = checker(HZ.from_polygon(poly, 1.0))
    a, b = np.array(a), np.array(b)
    n = 20000
    exact = ck.hazard_lengths(a, b)[0]
    # each boundary crossing can shift the midpoint rule by one cell
    tol = (len(poly) + 2) * np.linalg.norm(b - a) / n + 1e-9
    assert abs(exact - brute_length(ck, a, b, n)) <= tol
    assert 0.0 <= exact <= np.linalg.norm(b - a) + 1e-9


@settings(max_examples=60, deadline=None)
@given(c=st.tuples(coord, coord), r=st.floats(0.5, 20), a=st.tuples(coord, coord), b=st.tuples(coord, coord))
def test_disc_length_matches_fine_sampling(c, r, a, b):
    ck = checker(HZ.from_circle(np.array(c), r, 0.3))
    a, b = np.array(a), np.array(b)
    n = 20000
    exact = ck.hazard_lengths(a, b)[0]
    assert abs(exact - brute_length(ck, a, b, n)) <= 3 * np.linalg.norm(b - a) / n + 1e-6


def test_overlapping_hazards_add():
    ck = checker(HZ.from_polygon(SQUARE, 0.5), HZ.from_circle(np.array([5.0, 5.0]), 2.0, 0.25))
    a, b = np.array([-5.0, 5.0]), np.array([15.0, 5.0])
    np.testing.assert_allclose(ck.hazard_lengths(a, b), [10.0, 4.0], atol=1e-12)
    assert ck.hazard_integral(a, b) == pytest.approx(0.5 * 10 + 0.25 * 4)


# ---------------------------------------------------------------- PathSafety

def test_path_safety_report():
    m = planning.make_map(upper=(60, 40), circles=[(30, 28, 4)], clearance=2.0,
                          hazards=[HZ.from_circle(np.array([45.0, 20.0]), 3.0, 0.9),
                                   HZ.from_polygon(SQUARE + [10, 15], 0.5)])
    s = planning.path_safety([(0, 20), (30, 20), (60, 20)], m)
    assert s.length == pytest.approx(60)
    assert s.min_clearance == pytest.approx(4.0)          # y = 20 to the disc at y = 28 minus r = 4
    np.testing.assert_allclose(s.hazard_length, [6.0, 10.0], atol=1e-12)
    assert s.exposure == pytest.approx(0.9 * 6 + 0.5 * 10)
    assert planning.path_safety([(30, 20), (30, 40)], m).min_clearance == 0.0   # through the obstacle
    assert planning.path_safety([(14, 10)], m).min_clearance == pytest.approx(math.hypot(16, 18) - 4)  # one point
    empty = planning.make_map(upper=(10, 10))
    assert math.isinf(planning.path_safety([(1, 1), (2, 2)], empty).min_clearance)


# ---------------------------------------------------------------- planning

def band_map(forbidden_risk=None, risk=0.9):
    """A hazard band across the straight line from (5, 20) to (55, 20), open above and below."""
    band = HZ.from_polygon(np.array([[28.0, 10.0], [32.0, 10.0], [32.0, 30.0], [28.0, 30.0]]), risk)
    return planning.make_map(upper=(60, 40), circles=[(15, 30, 3)], clearance=1.0, hazards=[band],
                             forbidden_risk=forbidden_risk)


def test_forbidden_hazard_is_avoided_and_reports_zero_exposure():
    through = planning.plan(planning.PlanningProblem(map=band_map(), start=(5, 20), goal=(55, 20)),
                            max_iterations=1500, seed=3, smooth=True)
    assert through.success and through.safety.exposure > 0          # allowed: the straight way crosses it
    m = band_map(forbidden_risk=0.8)
    r = planning.plan(planning.PlanningProblem(map=m, start=(5, 20), goal=(55, 20)),
                      max_iterations=3000, seed=3, smooth=True)
    assert r.success
    assert r.safety.hazard_length[0] == 0.0 and r.safety.exposure == 0.0 and r.cost.hazard == 0.0
    assert planning.path_is_free(m, r.path)
    assert not planning.point_is_free(m, (30, 20)) and planning.point_is_free(band_map(), (30, 20))
    # a forbidden hazard is grown by the clearance like an obstacle
    assert not planning.point_is_free(m, (27.5, 20)) and planning.point_is_free(m, (26.9, 20))
    with pytest.raises(ValueError, match="start .* forbidden hazard"):
        planning.plan(planning.PlanningProblem(map=m, start=(30, 20), goal=(55, 20)), max_iterations=10)


def disc_hazard_problem():
    m = planning.make_map(upper=(100, 60), hazards=[HZ.from_circle(np.array([50.0, 30.0]), 10.0, 1.0)])
    return planning.PlanningProblem(map=m, start=(5, 30), goal=(95, 30))


def test_hazard_weight_cuts_exposure_tenfold_for_little_length():
    prob = disc_hazard_problem()
    plain = planning.plan(prob, max_iterations=3000, seed=1, smooth=True)
    aware = planning.plan(prob, max_iterations=3000, seed=1, smooth=True, hazard_weight=5.0)
    assert plain.success and aware.success
    assert plain.safety.exposure > 15.0                              # ≈ 20 m across the disc
    assert aware.safety.exposure * 10 <= plain.safety.exposure
    assert aware.safety.length <= 1.10 * plain.safety.length
    # the cost's hazard term is the reported exposure, and total = length + beta_h * hazard here
    assert aware.cost.hazard == pytest.approx(aware.safety.exposure, rel=1e-12)
    assert aware.cost.total == pytest.approx(aware.cost.length + 5.0 * aware.cost.hazard, rel=1e-12)
    assert plain.cost.total == pytest.approx(plain.cost.length, rel=1e-12)     # beta_h = 0: the paper's cost


def test_min_clearance_respects_inflation():
    infl = _core.Inflation(vehicle_radius=1.5, margin=0.75)
    assert infl.clearance == 2.25
    m = planning.make_map(upper=(60, 40), circles=[(30, 20, 5), (15, 12, 3)],
                          polygons=[np.array([[40, 15], [46, 15], [46, 30], [40, 30]])], clearance=infl.clearance)
    r = planning.plan(planning.PlanningProblem(map=m, start=(5, 20), goal=(55, 20)), max_iterations=2000, seed=5,
                      smooth=True)
    assert r.success and r.safety.min_clearance >= infl.clearance


# ---------------------------------------------------------------- bad input

@pytest.mark.parametrize("value", [-1.0, float("nan"), float("inf")])
def test_bad_hazard_weight(value):
    with pytest.raises(ValueError, match="hazard_weight"):
        planning.PlannerSettings(hazard_weight=value)


@pytest.mark.parametrize("value", [0.0, -0.5, float("nan")])
def test_bad_forbidden_risk(value):
    with pytest.raises(ValueError, match="forbidden_risk"):
        planning.make_map(forbidden_risk=value)


def test_bad_geometry_inputs():
    ck = checker(HZ.from_polygon(SQUARE, 0.5))
    with pytest.raises(ValueError, match="not finite"):
        ck.hazard_lengths(np.array([np.nan, 0.0]), np.array([1.0, 1.0]))
    with pytest.raises(ValueError, match="not finite"):
        planning.path_safety([(0, 0), (np.nan, 1)], planning.make_map())
    with pytest.raises(ValueError, match="vehicle_radius"):
        _core.Inflation(vehicle_radius=-1.0)
    with pytest.raises(ValueError, match="margin"):
        _core.Inflation(margin=float("nan"))
    with pytest.raises(ValueError, match="vehicle_radius"):
        NavigationParams(vehicle_radius=float("nan"))
    with pytest.raises(ValueError, match="hazard_weight"):
        PlannerParams(hazard_weight=-2.0)
    with pytest.raises(ValueError, match="clearance"):
        NavigationParams(clearance=-1.0)


# ---------------------------------------------------------------- scenario fields

def test_scenario_clearance_from_radius_and_margin():
    nav = default_scenario().navigation
    assert (nav.vehicle_radius, nav.clearance_margin, nav.clearance) == (1.0, 1.0, None)
    assert nav.planning_clearance == 2.0                     # today's clearance, exactly
    assert NavigationParams(vehicle_radius=0.5, clearance_margin=0.25).planning_clearance == 0.75
    # an old scenario file's navigation.clearance takes precedence
    old = NavigationParams.from_dict({"clearance": 3.0, "vehicle_radius": 0.5})
    assert old.planning_clearance == 3.0 and old.to_dict()["clearance"] == 3.0
    assert "clearance" not in nav.to_dict()
    p = default_scenario().planner
    assert (p.hazard_weight, p.forbidden_risk) == (5.0, 2.0)   # ours: hazard-aware by default


# ---------------------------------------------------------------- defaults unchanged

#: planned by main's build (commit 320a8b4) before hazards existed: the same
#: problem and seed must give these paths bit for bit with the defaults.
MAIN_PATH = [[5.0, 20.0], [9.732964522132269, 20.35347689816699], [14.257118394127593, 20.04065094503755],
             [15.656920092714838, 19.989737654726117], [17.938115820449426, 19.206063581101745],
             [21.224510727148502, 20.53117647592742], [23.972734478034955, 19.775653825707813],
             [26.060037765471932, 19.54540163330953], [28.22833449003922, 20.093881688075935],
             [29.41269212558879, 19.975426486385327], [33.36441945269416, 20.054858364857317],
             [34.99163254795385, 20.20431507191597], [39.8171446171137, 19.634309433726926],
             [42.265680748893885, 20.00860755015563], [45.2689904703579, 19.585933112474333],
             [49.42826213454912, 20.062681393541368], [55.0, 20.0]]
MAIN_TOTAL = 52.11977487985014
MAIN_SMOOTH_PATH = [[5.0, 20.0], [6.14254740934585, 20.08533005315712], [7.466429603121271, 20.08604938824163],
                    [9.604120677302282, 20.086972108277383], [13.096704437420662, 20.08588782962922],
                    [19.75509372435738, 20.055582407166614], [34.72286044171634, 19.991063899861576],
                    [38.889866315197594, 19.95306160178387], [45.102567317635135, 19.95962143725955],
                    [54.09101768790412, 20.010225943754445], [55.0, 20.0]]
MAIN_SMOOTH_TOTAL = 50.06445362010905


def test_defaults_leave_a_fixed_seed_plan_bit_for_bit_unchanged():
    m = planning.make_map(upper=(60, 40), circles=[(30, 28, 4)],
                          polygons=[np.array([[20., 5], [26, 5], [26, 12], [20, 12]])], clearance=2.0)
    m.hazards = [HZ.from_polygon(np.array([[28.0, 14], [34, 14], [34, 24], [28, 24]]), 0.6),
                 HZ.from_circle(np.array([45.0, 20.0]), 3.0, 0.9)]
    prob = planning.PlanningProblem(map=m, start=(5, 20), goal=(55, 20), central_path=[(5, 20), (55, 20)])
    for kw, path, total in (({}, MAIN_PATH, MAIN_TOTAL), ({"smooth": True}, MAIN_SMOOTH_PATH, MAIN_SMOOTH_TOTAL)):
        r = planning.plan(prob, max_iterations=1500, seed=7, **kw)
        assert r.path.tolist() == path and r.cost.total == total
        assert r.safety.exposure > 0        # the default plan crosses the hazards (reported, not avoided)

"""Occlusion by obstacles (ours): the core's one line-of-sight query
(``ObstacleChecker::line_of_sight`` / ``visible_from``, ``World.line_of_sight``
/ ``World.visible_from``) and its use by the simulated camera
(``SensorSettings.occlusion``) and the scenario (``detection.occlusion``).

The reference is exact: a brute-force line of sight in rational arithmetic
(``fractions.Fraction``) — segment–segment intersection with collinear
overlaps for polygon edges, exact point-in-polygon (boundary included), and
the exact squared distance from a circle's centre to the segment."""

from __future__ import annotations

import dataclasses
from fractions import Fraction as Q

import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st

import safenav
from safenav import _core
from safenav import navigation as nv
from safenav import planning as P
from safenav.motion import BmmParams
from safenav.scenario import DetectionParams, ScenarioError
from safenav.world import Circle, Field, Hazard, Landmark, Polygon, World

from exact_geometry import disc_meets_segment, in_disc, in_polygon, q, segments_meet

# --------------------------------------------------------------------------- the exact reference


def los_reference(a, b, circles, polygons):
    """Brute force: b is seen from a unless an obstacle that contains neither
    end (boundary included) touches the closed segment a–b."""
    a, b = q(a), q(b)
    if a == b:
        return True
    for cx, cy, r in circles:
        c, r = q((cx, cy)), Q(float(r))
        if in_disc(c, r, a) or in_disc(c, r, b):
            continue
        if disc_meets_segment(c, r, a, b):
            return False
    for poly in polygons:
        pq = [q(v) for v in poly]
        if in_polygon(pq, a) or in_polygon(pq, b):
            continue
        if any(segments_meet(a, b, pq[i], pq[(i + 1) % len(pq)]) for i in range(len(pq))):
            return False
    return True


def _checker(circles=(), polygons=(), **kw):
    return _core.ObstacleChecker(P.make_map(lower=(-100, -100), upper=(100, 100), circles=circles,
                                            polygons=[np.asarray(p, dtype=float) for p in polygons], **kw))


# --------------------------------------------------------------------------- strategies

#: half-integer grid coordinates: exact in binary, and they make the degenerate
#: configurations (collinear edges, vertex hits, tangents) common
grid = st.integers(-24, 24).map(lambda v: v / 2.0)
anywhere = st.floats(-30, 30, allow_nan=False, allow_infinity=False)
point = st.tuples(grid, grid) | st.tuples(anywhere, anywhere)

#: polygons on the grid: convex and concave (an L and a U), translated
TEMPLATES = [
    [(0, 0), (4, 0), (4, 4), (0, 4)],                                     # square
    [(0, 0), (6, 0), (2, 3)],                                             # triangle
    [(0, 0), (6, 0), (6, 2), (2, 2), (2, 6), (0, 6)],                     # L (concave)
    [(0, 0), (6, 0), (6, 6), (4, 6), (4, 2), (2, 2), (2, 6), (0, 6)],     # U (concave)
]
grid_polygon = st.builds(lambda t, dx, dy: [(x + dx, y + dy) for x, y in TEMPLATES[t]],
                         st.integers(0, len(TEMPLATES) - 1), st.integers(-12, 8), st.integers(-12, 8))


@st.composite
def star_polygon(draw):
    """A simple (star-shaped) polygon with float vertices."""
    n = draw(st.integers(3, 8))
    cx, cy = draw(anywhere), draw(anywhere)
    angles = sorted(draw(st.lists(st.floats(0, 2 * np.pi, exclude_max=True), min_size=n, max_size=n, unique=True)))
    if min(np.diff(angles + [angles[0] + 2 * np.pi])) < 1e-3:
        angles = list(np.linspace(0, 2 * np.pi, n, endpoint=False))
    radii = draw(st.lists(st.floats(0.5, 8), min_size=n, max_size=n))
    return [(cx + r * np.cos(t), cy + r * np.sin(t)) for r, t in zip(radii, angles)]


circle = st.tuples(grid, grid, st.sampled_from([0.5, 1.0, 1.5, 2.0, 2.5, 5.0])) | st.tuples(
    anywhere, anywhere, st.floats(0.1, 8))
obstacles = st.tuples(st.lists(circle, max_size=4), st.lists(grid_polygon | star_polygon(), max_size=3))


# --------------------------------------------------------------------------- properties


@settings(max_examples=400, deadline=None)
@given(obstacles, point, point)
def test_line_of_sight_equals_the_exact_reference(obs, a, b):
    circles, polygons = obs
    chk = _checker(circles, polygons)
    assert chk.line_of_sight(a, b) == los_reference(a, b, circles, polygons)
    assert chk.line_of_sight(b, a) == chk.line_of_sight(a, b)        # symmetric


@settings(max_examples=300, deadline=None)
@given(obstacles, point, point)
def test_placement_sight_test_is_the_same_rule(obs, a, b):
    """Landmark placement's sight test (placement.hpp's sight_blocked, which its exact shadows
    follow) and the world's line-of-sight query are one rule: they agree on every segment."""
    circles, polygons = obs
    try:
        occ = _core.Occluders(np.array(circles, dtype=float).reshape(-1, 3), [np.asarray(p, float) for p in polygons])
    except ValueError as e:   # placement rejects what is not a simple polygon (a few star draws)
        assert "not a simple polygon" in str(e)
        assume(False)
    assert _core.sight_blocked(occ, a, b) == (not _checker(circles, polygons).line_of_sight(a, b))


@settings(max_examples=150, deadline=None)
@given(obstacles, point, st.lists(point, max_size=12))
def test_visible_from_is_line_of_sight_row_by_row(obs, p, targets):
    circles, polygons = obs
    chk = _checker(circles, polygons)
    t = np.array(targets, dtype=float).reshape(-1, 2)
    got = chk.visible_from(p, t)
    assert got.shape == (len(t),) and got.dtype == bool
    assert list(got) == [los_reference(p, q, circles, polygons) for q in t]


@settings(max_examples=100, deadline=None)
@given(obstacles, point, point, st.floats(0.0, 10.0))
def test_the_clearance_and_hazards_play_no_part(obs, a, b, clearance):
    circles, polygons = obs
    hz = [_core.HazardZone.from_circle((float(a[0] + b[0]) / 2, float(a[1] + b[1]) / 2), 3.0, 1.0)]
    plain = _checker(circles, polygons)
    grown = _checker(circles, polygons, clearance=clearance, hazards=hz, forbidden_risk=0.5)
    assert grown.line_of_sight(a, b) == plain.line_of_sight(a, b)


# --------------------------------------------------------------------------- degenerate cases

SQUARE = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)]
CASES = [
    # (circles, polygons, a, b, seen, what)
    ([(0, 0, 1)], [], (-2, 1), (2, 1), False, "segment tangent to a circle: touching blocks"),
    ([(0, 0, 1)], [], (-2, np.nextafter(1, 2)), (2, np.nextafter(1, 2)), True, "one ulp past the tangent"),
    ([(0, 0, 5)], [], (-10, 5), (10, 5), False, "tangent to a larger circle"),
    ([(0, 0, 1)], [], (1, 0), (5, 0), True, "a on the circle's boundary: it does not block"),
    ([(0, 0, 1)], [], (0, 0), (5, 0), True, "a inside the circle (a landmark on a boulder)"),
    ([(0, 0, 1), (3, 0, 1)], [], (0, 0), (6, 0), False, "a inside one circle, another between"),
    ([(0, 0, 1)], [], (-1.5, 0), (1.5, 0), False, "through a circle"),
    ([(0, 0, 1)], [], (-1.5, -1.5), (-1.5, 1.5), True, "past a circle"),
    ([], [SQUARE], (-1, 1), (1, -1), False, "through a polygon vertex only"),
    ([], [SQUARE], (-1, np.nextafter(1, 0)), (np.nextafter(1, 0), -1), True, "one ulp short of the vertex"),
    ([], [SQUARE], (-2, 0), (6, 0), False, "along a polygon edge"),
    ([], [SQUARE], (-2, 0), (-1, 0), True, "on the edge's line, short of it"),
    ([], [SQUARE], (-2, 0), (0, 0), True, "ending at a vertex: the polygon contains b"),
    ([], [SQUARE], (2, 0), (2, 8), True, "from the polygon's edge across it: it contains a"),
    ([], [SQUARE], (2, 2), (2, 2), True, "zero-length segment inside a polygon"),
    ([], [SQUARE], (9, 9), (9, 9), True, "zero-length segment outside"),
    ([], [SQUARE], (-1, 2), (5, 2), False, "through a polygon"),
    ([], [TEMPLATES[3]], (3, 5), (3, 7), True, "inside the U's notch, out of it"),
    ([], [TEMPLATES[3]], (-1, 4), (7, 4), False, "across the U's arms"),
    ([], [SQUARE, [(4.0, 1.0), (6.0, 1.0), (6.0, 3.0), (4.0, 3.0)]], (2, 2), (5, 2), True,
     "a in one polygon, b in another touching it"),
    ([(2, 2, 1)], [SQUARE], (2, 2), (2, 10), True, "a inside a circle inside a polygon"),
]


@pytest.mark.parametrize("circles, polygons, a, b, seen, what", CASES, ids=[c[-1] for c in CASES])
def test_degenerate_cases(circles, polygons, a, b, seen, what):
    chk = _checker(circles, polygons)
    assert los_reference(a, b, circles, polygons) == seen, what           # the reference agrees with the table
    assert chk.line_of_sight(a, b) == seen, what
    assert chk.line_of_sight(b, a) == seen, what
    assert list(chk.visible_from(a, np.array([b], dtype=float))) == [seen]


def test_no_obstacles_sees_everything_and_no_target_gives_an_empty_answer():
    chk = _checker()
    assert chk.line_of_sight((0, 0), (99, -99))
    assert chk.visible_from((0, 0), np.zeros((0, 2))).shape == (0,)


# --------------------------------------------------------------------------- symmetry, at any distance

#: far coordinates: the reported 1.8e19, and beyond what a double can square (1e160, 1e300)
FAR = [1e19, -1e19, 1.8e19, -1.8e19, 1e160, -1e160, 1e300, -1e300]
far = st.sampled_from(FAR) | st.floats(-1e20, 1e20, allow_nan=False, allow_infinity=False)


@st.composite
def scene_and_ends(draw):
    """Obstacles and two ends drawn to make the hard cases common: far ends, ends on the line
    of a polygon's edge (collinear, near or far along it), on a vertex, on a circle's boundary,
    and tangent lines."""
    circles, polygons = draw(obstacles)

    def end():
        kind = draw(st.integers(0, 4))
        if kind == 1 or (kind >= 3 and not (polygons or circles)):
            return draw(st.tuples(far, far) | st.tuples(grid, far) | st.tuples(far, grid))
        if kind == 3 and polygons:                 # on an edge's line: t = 0, 1 are its ends
            poly = draw(st.sampled_from(polygons))
            i = draw(st.integers(0, len(poly) - 1))
            (x0, y0), (x1, y1) = poly[i], poly[(i + 1) % len(poly)]
            t = draw(st.sampled_from([-1e18, -3.0, -0.5, 0.0, 0.5, 1.0, 2.0, 1e18]))
            return (x0 + t * (x1 - x0), y0 + t * (y1 - y0))
        if kind == 4 and circles:                  # on a circle's boundary or its tangent, near or far
            cx, cy, r = draw(st.sampled_from(circles))
            return draw(st.sampled_from([(cx + r, cy), (cx, cy - r), (cx - 1e19, cy + r), (cx + 1e19, cy + r)]))
        return draw(point)

    return circles, polygons, end(), end()


@settings(max_examples=400, deadline=None)
@given(scene_and_ends())
def test_line_of_sight_is_symmetric_and_exact_at_any_distance(scene):
    circles, polygons, a, b = scene
    chk = _checker(circles, polygons)
    seen = chk.line_of_sight(a, b)
    assert chk.line_of_sight(b, a) == seen                               # the very same answer both ways
    assert seen == los_reference(a, b, circles, polygons)                # and the exact one
    assert list(chk.visible_from(b, np.array([a], dtype=float))) == [seen]


@settings(max_examples=200, deadline=None)
@given(scene_and_ends())
def test_placement_sight_test_is_the_world_predicate_at_any_distance(scene):
    circles, polygons, a, b = scene
    try:
        occ = _core.Occluders(np.array(circles, dtype=float).reshape(-1, 3), [np.asarray(p, float) for p in polygons])
    except ValueError as e:   # placement rejects what is not a simple polygon (a few star draws)
        assert "not a simple polygon" in str(e)
        assume(False)
    blocked = _core.sight_blocked(occ, a, b)
    assert _core.sight_blocked(occ, b, a) == blocked
    assert blocked == (not _checker(circles, polygons).line_of_sight(a, b))


def test_the_reported_far_endpoint_is_seen_alike_both_ways():
    """The default world from (117.15, 31.27) to (1.8e19, 1.8e19): one answer both ways, the exact one."""
    w = safenav.default_scenario().world
    circles, polygons = w.obstacle_arrays()
    a, b = (117.15, 31.27), (1.8e19, 1.8e19)
    ref = los_reference(a, b, circles, polygons)
    assert w.line_of_sight(a, b) == ref and w.line_of_sight(b, a) == ref


@pytest.mark.parametrize("circles, polygons, a, b, seen, what", [
    ([], [SQUARE], (-1e19, 0), (1e19, 0), False, "along a polygon edge's line, far both ways"),
    ([], [SQUARE], (-2, 0), (1e300, 0), False, "along an edge, to beyond what a double can square"),
    ([], [SQUARE], (-2, 0), (-1e300, 0), True, "on the edge's line, away from it"),
    ([], [SQUARE], (-1e19, -1e19), (1e19, 1e19), False, "through two opposite vertices, far"),
    ([], [SQUARE], (-1e19, 1e19), (1e19, -1e19), False, "through a vertex only, far"),
    ([(0, 0, 1)], [], (-1e19, 1), (1e19, 1), False, "tangent to a circle, far both ways"),
    ([(0, 0, 1)], [], (-1e300, 1), (1e300, 1), False, "tangent, beyond what a double can square"),
    ([(0, 0, 1)], [], (-1e19, np.nextafter(1, 2)), (1e19, np.nextafter(1, 2)), True, "one ulp past the tangent, far"),
    ([(0, 0, 1)], [], (1, 0), (1e300, 0), True, "from the circle's boundary outwards"),
])
def test_far_degenerate_cases(circles, polygons, a, b, seen, what):
    chk = _checker(circles, polygons)
    assert los_reference(a, b, circles, polygons) == seen, what
    assert chk.line_of_sight(a, b) == seen, what
    assert chk.line_of_sight(b, a) == seen, what


def test_placement_sight_test_names_a_non_finite_end():
    occ = _core.Occluders(np.array([(0.0, 0.0, 1.0)]))
    with pytest.raises(ValueError, match=r"sight_blocked: a = \(nan, 0\) is not finite"):
        _core.sight_blocked(occ, (np.nan, 0.0), (1.0, 1.0))
    with pytest.raises(ValueError, match=r"sight_blocked: b = \(1, inf\) is not finite"):
        _core.sight_blocked(occ, (0.0, 0.0), (1.0, np.inf))


# --------------------------------------------------------------------------- World


def _wall_world():
    return World(field=Field(-50, -50, 50, 50),
                 obstacles=(Polygon(vertices=((-10, 4), (10, 4), (10, 5), (-10, 5))), Circle(center=(20, 0), radius=2)),
                 hazards=(Hazard(shape=Circle(center=(-20, 0), radius=3), risk=1.0),),
                 landmarks=(Landmark(id=0, position=(0, 10), cluster=0),))


def test_world_line_of_sight_and_visible_from():
    w = _wall_world()
    assert not w.line_of_sight((0, 0), (0, 10))                          # behind the wall
    assert w.line_of_sight((0, 0), (-30, 0))                              # hazards hide nothing
    assert not w.line_of_sight((0, 0), (30, 0)) and w.line_of_sight((20, 0), (30, 0))
    pts = np.array([(0, 10), (-30, 0), (30, 0), (0, -10), (10, 4)], dtype=float)
    np.testing.assert_array_equal(w.visible_from((0, 0), pts), [False, True, False, True, True])
    circles, polygons = w.obstacle_arrays()
    assert [los_reference((0, 0), q, circles, polygons) for q in pts] == list(w.visible_from((0, 0), pts))


@pytest.mark.parametrize("call, match", [
    (lambda w: w.line_of_sight((np.nan, 0), (1, 1)), r"a\[0\] = nan is not finite"),
    (lambda w: w.line_of_sight((0, 0), (1, np.inf)), r"b\[1\] = inf is not finite"),
    (lambda w: w.line_of_sight((0, 0, 0), (1, 1)), r"a must have shape \(2,\), got \(3,\)"),
    (lambda w: w.visible_from((0, np.nan), [(1, 1)]), r"p\[1\] = nan is not finite"),
    (lambda w: w.visible_from((0, 0), [(1, 1), (2, np.nan)]), r"points\[\(1, 1\)\] = nan is not finite"),
    (lambda w: w.visible_from((0, 0), [1, 2, 3]), r"points must have shape \(N, 2\), got \(3,\)"),
    (lambda w: w.line_of_sight("ab", (1, 1)), r"a must be numeric"),
])
def test_world_bad_input_is_a_value_error_naming_it(call, match):
    with pytest.raises(ValueError, match=match):
        call(_wall_world())


@pytest.mark.parametrize("call, match", [
    (lambda c: c.line_of_sight((np.nan, 0), (1, 1)), r"line of sight: a = \(nan, 0\) is not finite"),
    (lambda c: c.line_of_sight((0, 0), (1, -np.inf)), r"line of sight: b = \(1, -inf\) is not finite"),
    (lambda c: c.visible_from((np.inf, 0), np.zeros((1, 2))), r"visible_from: from = \(inf, 0\) is not finite"),
    (lambda c: c.visible_from((0, 0), np.array([(0, 0), (np.nan, 1)])), r"target 1 \(nan, 1\) is not finite"),
])
def test_core_bad_input_is_a_value_error_naming_it(call, match):
    with pytest.raises(ValueError, match=match):
        call(_checker([(0, 0, 1)]))


# --------------------------------------------------------------------------- the simulated camera

#: landmarks behind a wall (y = 20, the wall at y = 10..11) and in the open (y = -10, -16)
HIDDEN = [(0.0, 20.0), (20.0, 20.0), (40.0, 20.0), (60.0, 20.0)]
OPEN = [(-5.0, -10.0), (10.0, -16.0), (25.0, -10.0), (40.0, -16.0), (55.0, -10.0), (70.0, -16.0)]
WALL = np.array([(-15.0, 10.0), (95.0, 10.0), (95.0, 11.0), (-15.0, 11.0)])


def _walled_navigator(occlusion: bool):
    p = _core.NavigationProblem()
    p.path = np.array([(0.0, 0.0), (60.0, 0.0)])
    p.zones = _core.RiskZones()
    p.map = P.make_map(lower=(-20, -40), upper=(100, 40), polygons=[WALL])
    p.bmm = BmmParams()
    s = _core.NavigationSettings()
    s.guard.enabled = False
    s.record = True
    se = _core.SensorSettings()
    se.landmarks = np.array(HIDDEN + OPEN)
    se.field_of_view = 2 * np.pi                      # all round: only range and obstacles hide
    se.fix_model = _core.FixModel.RANGES              # counts every landmark observation
    se.occlusion = occlusion
    return _core.Navigator(p, s, se)


def _seen(x, occlusion):
    """The landmarks in view of the true state x, by the exact reference."""
    out = 0
    for lm in HIDDEN + OPEN:
        dx, dy = lm[0] - x[0], lm[1] - x[1]
        if dx * dx + dy * dy > 30.0 ** 2:
            continue
        out += not occlusion or los_reference(x[:2], lm, [], [WALL])
    return out


def test_a_landmark_behind_a_wall_is_observed_only_without_occlusion():
    on, off = _walled_navigator(True).run(7), _walled_navigator(False).run(7)
    assert on.outcome_name == off.outcome_name == "arrived"
    # Every step's fix counts the landmarks in view of the truth: exactly the reference's.
    assert on.observations == sum(_seen(x, True) for x in on.truth)
    assert off.observations == sum(_seen(x, False) for x in off.truth)
    # The wall hides the landmarks behind it all the way: on sees only the open ones.
    assert on.observations == sum(_seen(x, False) - _hidden_in_range(x) for x in on.truth)
    assert off.observations > on.observations and on.position_fixes > 0


def _hidden_in_range(x):
    return sum((lm[0] - x[0]) ** 2 + (lm[1] - x[1]) ** 2 <= 30.0 ** 2 for lm in HIDDEN)


def test_landmarks_in_view_skips_only_landmarks_an_obstacle_hides():
    se = _core.SensorSettings()
    se.landmarks = np.array(HIDDEN + OPEN)
    se.field_of_view = 2 * np.pi
    chk = _checker(polygons=[WALL])
    x = np.array([30.0, 0.0, 0.0, 0.0])
    assert se.landmarks_in_view(x) == 6                                   # no map: nothing hidden
    assert se.landmarks_in_view(x, chk) == 4                              # the wall hides the two in range
    se.occlusion = False
    assert se.landmarks_in_view(x, chk) == 6
    se.occlusion = True
    se.field_of_view = np.deg2rad(85)
    north = np.array([30.0, 0.0, 0.0, np.pi / 2])                         # facing the wall: two in range and FOV
    assert se.landmarks_in_view(north) == 2 and se.landmarks_in_view(north, chk) == 0
    assert se.landmarks_in_view(x) == se.landmarks_in_view(x, chk) == 1   # east: (55, -10), in the open


# --------------------------------------------------------------------------- the scenario and the papers' loop


def test_detection_occlusion_is_a_scenario_field_declared_in_the_core():
    spec = next(s for s in _core.SensorSettings.params() if s.name == "occlusion")
    assert spec.kind == _core.ParamKind.BOOLEAN and "hide landmarks" in spec.doc
    d = DetectionParams()
    assert d.occlusion is True and _core.SensorSettings().occlusion is True
    assert DetectionParams.from_dict({"occlusion": False}).occlusion is False
    core = DetectionParams(occlusion=False).apply(_core.SensorSettings())
    assert core.occlusion is False
    with pytest.raises(ScenarioError, match=r"occlusion = 'yes': must be true or false"):
        DetectionParams(occlusion="yes")
    with pytest.raises(ScenarioError, match=r"occlusion = 1: must be true or false"):
        DetectionParams(occlusion=1)
    sc = safenav.default_scenario()
    assert sc.to_dict()["detection"]["occlusion"] is True


def test_make_navigator_turns_occlusion_off_in_the_papers_loop_only():
    sc = safenav.default_scenario()
    path = nv.plan_safe_path(sc, "P1").path
    assert nv.make_navigator(sc, path, record=False).sensors.occlusion is True
    assert nv.make_navigator(sc, path, record=False).settings.guard.occlusion is True
    paper = nv.make_navigator(sc, path, record=False, paper=True)
    assert paper.sensors.occlusion is False and paper.settings.guard.occlusion is False
    off = dataclasses.replace(sc, detection=dataclasses.replace(sc.detection, occlusion=False))
    n = nv.make_navigator(off, path, record=False)
    assert n.sensors.occlusion is False and n.settings.guard.occlusion is False


def test_landmarks_in_view_names_a_non_finite_state():
    se = _core.SensorSettings()
    with pytest.raises(ValueError, match=r"landmarks_in_view: state \(nan, 0, 0, 0\) is not finite"):
        se.landmarks_in_view(np.array([np.nan, 0.0, 0.0, 0.0]), _checker())

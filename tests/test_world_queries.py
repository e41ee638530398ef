"""The world's collision queries, answered by the core's ObstacleChecker, against an independent reference.

The reference (``_distance``) is written here from scratch: even-odd ray
casting for the inside of a polygon and point-to-edge projection for the
distance, in NumPy.  A point query must agree with it up to 1e-9 m; a segment
query must agree with dense sampling of the segment up to half the sampling
step.  Degenerate cases (points on edges and vertices, segments through a
vertex, collinear with an edge, of zero length) are asserted exactly: the
boundary belongs to the obstacle.
"""

import math
import pickle

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from safenav import _core
from safenav.world import Circle, Field, Hazard, Polygon, ScenarioError, World

FIELD = Field(0, 0, 100, 100)
TOL = 1e-9          # [m] the reference's own rounding
STEP = 0.01         # [m] dense sampling of a segment


# --------------------------------------------------------------------------- the reference

def _distance(shape, pts) -> np.ndarray:
    """Distance of each point to the shape, 0 inside (ray casting + edge projection)."""
    p = np.asarray(pts, dtype=float).reshape(-1, 2)
    if isinstance(shape, Circle):
        return np.maximum(np.hypot(p[:, 0] - shape.center[0], p[:, 1] - shape.center[1]) - shape.radius, 0.0)
    v = shape.array()
    d = np.full(len(p), np.inf)
    inside = np.zeros(len(p), dtype=bool)
    for (x1, y1), (x2, y2) in zip(v, np.roll(v, -1, axis=0)):
        ex, ey = x2 - x1, y2 - y1
        t = np.clip(((p[:, 0] - x1) * ex + (p[:, 1] - y1) * ey) / (ex * ex + ey * ey), 0.0, 1.0)
        d = np.minimum(d, np.hypot(p[:, 0] - (x1 + t * ex), p[:, 1] - (y1 + t * ey)))
        crosses = (y1 > p[:, 1]) != (y2 > p[:, 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            x_at = x1 + (p[:, 1] - y1) * ex / ey
        inside ^= crosses & (p[:, 0] < x_at)
    return np.where(inside, 0.0, d)


def _dense(a, b) -> np.ndarray:
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = int(np.linalg.norm(b - a) / STEP) + 2
    return a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)


# --------------------------------------------------------------------------- shapes on a 0.5 m grid

half = st.integers(0, 200).map(lambda k: k / 2)           # 0, 0.5, ..., 100: many exact coincidences


@st.composite
def polygons(draw):
    cx, cy = draw(st.integers(30, 70)) / 2 + 25, draw(st.integers(30, 70)) / 2 + 25
    n = draw(st.integers(3, 8))
    angles = sorted(draw(st.lists(st.integers(0, 359), min_size=n, max_size=n, unique=True)))
    radii = draw(st.lists(st.integers(2, 40), min_size=n, max_size=n))
    verts = [(round(2 * (cx + r / 2 * math.cos(math.radians(a)))) / 2,
              round(2 * (cy + r / 2 * math.sin(math.radians(a)))) / 2) for a, r in zip(angles, radii)]
    try:
        return Polygon(verts)
    except ScenarioError:       # rounding made it non-simple or flat
        assume(False)


circles = st.builds(lambda x, y, r: Circle((x, y), r), st.integers(40, 160).map(lambda k: k / 2),
                    st.integers(40, 160).map(lambda k: k / 2), st.integers(1, 40).map(lambda k: k / 2))
shapes = st.one_of(polygons(), circles)
margins = st.sampled_from([0.0, 0.5, 1.25, 3.0])


def _special_points(shape) -> np.ndarray:
    """Vertices and edge midpoints (exact on the 0.5 grid): on the boundary."""
    if isinstance(shape, Circle):
        (x, y), r = shape.center, shape.radius
        return np.array([(x + r, y), (x, y - r)])
    v = shape.array()
    return np.vstack([v, (v + np.roll(v, -1, axis=0)) / 2])


@st.composite
def points_for(draw, shape):
    special = _special_points(shape)
    if draw(st.booleans()):
        return special[draw(st.integers(0, len(special) - 1))]
    return np.array([draw(half), draw(half)])


# --------------------------------------------------------------------------- property tests

@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(st.data(), shapes, margins)
def test_point_query_matches_the_reference(data, shape, margin):
    pts = np.array([data.draw(points_for(shape)) for _ in range(20)])
    world = World(FIELD, (shape,))
    got = world.obstacle_mask(pts, margin)
    d = _distance(shape, pts)
    assert not np.any((d <= margin - TOL) & ~got), (pts[(d <= margin - TOL) & ~got], margin)
    assert not np.any(got & (d > margin + TOL)), (pts[got & (d > margin + TOL)], margin)
    np.testing.assert_array_equal(shape.contains(pts, margin), got)
    np.testing.assert_array_equal(world.first_obstacle_at(pts, margin), np.where(got, 0, -1))
    assert shape.contains(_special_points(shape)).all()            # the boundary is inside, exactly


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(st.data(), shapes, margins)
def test_segment_query_matches_dense_sampling(data, shape, margin):
    a = data.draw(points_for(shape))
    kind = data.draw(st.sampled_from(["free", "zero", "collinear", "to_vertex"]))
    if kind == "collinear" and isinstance(shape, Circle):
        kind = "free"
    special = _special_points(shape)
    if kind == "zero":
        b = a.copy()
    elif kind == "collinear":                                   # along edge k, beyond its end vertex
        v = shape.array()
        k = data.draw(st.integers(0, len(v) - 1))
        a, b = v[k], 2 * v[(k + 1) % len(v)] - v[k]
    elif kind == "to_vertex":
        b = special[data.draw(st.integers(0, len(special) - 1))]
    else:
        b = np.array([data.draw(half), data.draw(half)])
    world = World(FIELD, (shape,))
    hit = world.segment_hits_obstacle(a, b, margin)
    d = _distance(shape, _dense(a, b)).min()
    if d <= margin - TOL:
        assert hit, (a, b, margin, d)
    if hit:      # the segment's true distance is at most STEP / 2 below the samples'
        assert d <= margin + STEP / 2 + TOL, (a, b, margin, d)
    assert world.segment_hits_obstacle(b, a, margin) == hit              # symmetric
    assert shape.segment_hits(a, b, margin) == hit
    if kind in ("collinear", "to_vertex"):                              # touches the boundary
        assert hit
    if kind == "zero":
        assert hit == world.point_in_obstacle(a, margin)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(st.data(), st.lists(st.tuples(shapes, st.sampled_from([0.25, 0.5, 1.0])), min_size=1, max_size=4))
def test_hazard_risk_is_the_highest_covering_level_against_the_reference(data, zones):
    world = World(FIELD, (), tuple(Hazard(s, r) for s, r in zones))
    pts = np.array([data.draw(points_for(zones[data.draw(st.integers(0, len(zones) - 1))][0])) for _ in range(20)])
    got = world.hazard_risk(pts)
    d = np.array([_distance(s, pts) for s, _ in zones])              # (H, N)
    risks = np.array([r for _, r in zones])[:, None]
    inside = np.max(np.where(d == 0.0, risks, 0.0), axis=0)            # surely inside (ray casting)
    near = np.max(np.where(d <= TOL, risks, 0.0), axis=0)              # inside or on the boundary
    assert np.all(inside <= got) and np.all(got <= near), (pts, got, inside, near)


# --------------------------------------------------------------------------- exact cases

SQUARE = Polygon([(10, 10), (20, 10), (20, 20), (10, 20)])


def test_degenerate_segments_and_boundary_points():
    w = World(FIELD, (SQUARE, Circle((50, 50), 5)))
    assert w.segment_hits_obstacle((0, 0), (10, 10))                  # ends on a vertex
    assert not w.segment_hits_obstacle((0, 10), (9.5, 10))            # collinear with an edge, short of it
    assert w.segment_hits_obstacle((0, 10), (10, 10))                 # collinear, ends on the vertex
    assert w.segment_hits_obstacle((12, 10), (18, 10))                # lies on an edge
    assert w.segment_hits_obstacle((5, 5), (5, 5), margin=math.hypot(5, 5))   # zero length, exactly at the margin
    assert not w.segment_hits_obstacle((5, 5), (5, 5), margin=7.07)
    assert w.segment_hits_obstacle((40, 45), (60, 45))                # tangent to the circle
    assert not w.segment_hits_obstacle((40, 44.99), (60, 44.99))
    assert w.point_in_obstacle((20, 15)) and w.point_in_obstacle((20, 20)) and w.point_in_obstacle((55, 50))
    assert w.point_in_obstacle((23, 14), margin=3.0)                  # exactly 3 from the edge x = 20
    assert not w.point_in_obstacle((23, 14), margin=2.999999)
    assert w.point_in_obstacle((23, 24), margin=5.0)                  # 3-4-5 from the corner (20, 20)
    assert not w.point_in_obstacle((23, 24), margin=4.999999)


def test_a_polygons_farthest_vertex_is_not_culled():
    """The bounding-circle cull squared a rounded square root: radius² fell below the
    farthest vertex's d², so that vertex itself counted as outside (and as free for
    the planner).  Found by test_point_query_matches_the_reference."""
    tri = Polygon([(41, 40), (43, 40), (39, 39.5)])
    assert tri.contains([(39, 39.5)])[0] and tri.segment_hits((30, 39.5), (39, 39.5))
    assert not _core.point_is_free(_core.PlanningMap(polygons=[tri.array()]), (39.0, 39.5))


def test_the_margin_is_exact_with_no_hidden_tolerance():
    """The old NumPy kernel counted points within 1e-9 m outside a polygon's edge as inside
    (a tolerance for matplotlib's ambiguous boundary test); the core's exact
    predicates do not.  The core is right: the distance is 1e-10 > 0 = margin."""
    w = World(FIELD, (SQUARE,))
    p = (20 + 1e-10, 15.0)
    assert not w.point_in_obstacle(p)
    assert w.point_in_obstacle(p, margin=2e-10)
    assert not w.segment_hits_obstacle(p, (30, 15))
    assert w.segment_hits_obstacle(p, (30, 15), margin=2e-10)


def test_obstacle_indices_follow_the_worlds_order():
    w = World(FIELD, (SQUARE, Circle((15, 15), 2), Polygon([(40, 40), (45, 40), (42, 44)]), Circle((80, 80), 3)))
    pts = [(15, 15), (11, 11), (42, 41), (80, 80), (1, 1)]
    np.testing.assert_array_equal(w.first_obstacle_at(pts), [0, 0, 2, 3, -1])
    assert w.obstacles_at((15, 15)) == [0, 1]
    np.testing.assert_array_equal(w.obstacles_containing(pts)[:, 1], [True, False, False, False, False])
    assert w.obstacles_hit_by([(0, 15), (60, 15), (42, 42), (80, 80)]) == [0, 1, 2, 3]
    assert w.obstacles_hit_by([(0, 15), (5, 50), (80, 90)]) == []
    assert w.obstacles_hit_by([(0, 15)]) == []
    empty = World(FIELD)
    np.testing.assert_array_equal(empty.first_obstacle_at(pts), [-1] * 5)
    assert not empty.polyline_hits_obstacle(pts) and empty.hazard_risk(pts).tolist() == [0.0] * 5


def test_a_world_pickles_after_queries_and_answers_the_same():
    w = World(FIELD, (SQUARE,), (Hazard(Circle((50, 50), 5), 0.5),))
    assert w.point_in_obstacle((15, 15))
    w2 = pickle.loads(pickle.dumps(w))
    assert w2 == w and w2.point_in_obstacle((15, 15)) and w2.hazard_risk([(50, 50)])[0] == 0.5


@pytest.mark.parametrize("call, message", [
    (lambda w: w.obstacle_mask([(1.0, float("nan"))]), r"point 0 \(1, nan\) is not finite"),
    (lambda w: w.segment_hits_obstacle((0, 0), (float("inf"), 1)), r"segment end 0 \(inf, 1\) is not finite"),
    (lambda w: w.obstacle_mask([(1, 1)], margin=-1.0), r"margin must be finite and >= 0, got -1"),
    (lambda w: w.hazard_risk([(float("nan"), 0)]), r"point 0 \(nan, 0\) is not finite"),
])
def test_bad_query_input_is_a_one_line_error(call, message):
    with pytest.raises(ValueError, match=message):
        call(World(FIELD, (SQUARE,)))


def test_core_hazard_zones_are_validated():
    with pytest.raises(ValueError, match=r"hazard 0 risk must be in \(0, 1\], got 0"):
        _core.PlanningMap(hazards=[_core.HazardZone.from_circle((1, 1), 1.0, 0.0)])
    with pytest.raises(ValueError, match=r"hazard 0 needs >= 3 vertices, got 2"):
        _core.PlanningMap(hazards=[_core.HazardZone.from_polygon(np.array([[0.0, 0.0], [1.0, 1.0]]), 0.5)])
    with pytest.raises(ValueError, match=r"hazard 0 radius must be > 0"):
        _core.PlanningMap(hazards=[_core.HazardZone.from_circle((1, 1), -1.0)])

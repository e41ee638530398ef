"""World model: validation, geometry helpers against direct computation, the generator."""

import math
import time

import numpy as np
import pytest

from safenav.generate import DEFAULT_SEED, GeneratorConfig, _dense, generate_scenario, generate_world
from safenav.world import (MAX_LANDMARKS, MAX_OBSTACLES, MAX_VERTICES, Circle, Field, Hazard, Landmark, PathType, Polygon,
                           ScenarioError, World)

SQUARE = Polygon([(10, 10), (20, 10), (20, 20), (10, 20)])
TRI = Polygon([(50, 50), (70, 52), (58, 68)])


def small_world(**kw):
    lms = [Landmark(i, (30 + 3 * math.cos(i), 40 + 3 * math.sin(i)), "tower", 1) for i in range(3)]
    lms += [Landmark(10 + i, (80 + 2 * i, 80 - i, 5.0), "rock", 2) for i in range(4)]
    args = dict(field=Field(0, 0, 100, 100), obstacles=(Circle((40, 70), 5), SQUARE, TRI),
                hazards=(Hazard(Circle((30, 30), 15), 0.5), Hazard(SQUARE, 1.0)), landmarks=tuple(lms))
    args.update(kw)
    return World(**args)


# --------------------------------------------------------------------------- validation

@pytest.mark.parametrize("make, needle", [
    (lambda: Circle((1, 2), -2.0), "radius = -2.0"),
    (lambda: Circle((1, 2), 0), "radius = 0"),
    (lambda: Circle((1, float("nan")), 1), "center[1] = nan"),
    (lambda: Circle((1, 2, 3), 1), "center"),
    (lambda: Circle((1, 2), "3"), "radius = '3'"),
    (lambda: Circle((1, 2), True), "radius = True"),
    (lambda: Polygon([(0, 0), (1, 1)]), "at least 3 vertices"),
    (lambda: Polygon([(0, 0), (1, 1), (2, 2)]), "zero area"),
    (lambda: Polygon([(0, 0), (2, 2), (2, 0), (0, 2)]), "not simple"),
    (lambda: Polygon([(0, 0), (1, 0), (0, float("inf"))]), "vertices[2][1] = inf"),
    (lambda: Field(0, 0, -5, 10), "x_max = -5.0"),
    (lambda: Field(0, 0, 10, 0), "y_max = 0.0"),
    (lambda: Hazard(Circle((1, 1), 1), 1.5), "risk = 1.5"),
    (lambda: Hazard(Circle((1, 1), 1), 0.0), "risk = 0.0"),
    (lambda: Landmark(1, (1, 2, 3, 4)), "position"),
    (lambda: Landmark(-1, (1, 2)), "id = -1"),
    (lambda: Landmark(1, (1, 2), "", 0), "class = ''"),
    (lambda: PathType("P", (3,)), "start and a destination"),
    (lambda: PathType("P", (3, 3)), "clusters[1] = 3"),
    (lambda: small_world(obstacles=(Circle((97, 50), 5),)), "obstacles[0].radius = 5.0"),
    (lambda: small_world(obstacles=(Circle((150, 50), 5),)), "obstacles[0].center"),
    (lambda: small_world(obstacles=(SQUARE, Polygon([(90, 90), (101, 95), (95, 99)]))), "obstacles[1].vertices[1]"),
    (lambda: small_world(hazards=(Hazard(Circle((2, 2), 5)),)), "hazards[0].radius"),
    (lambda: small_world(landmarks=(Landmark(1, (50, 120)),)), "landmarks[0].position"),
    (lambda: small_world(landmarks=(Landmark(1, (5, 5)), Landmark(1, (6, 6)))), "landmarks[1].id = 1"),
])
def test_invalid_objects_name_field_and_value(make, needle):
    with pytest.raises(ScenarioError) as exc:
        make()
    assert needle in str(exc.value)
    assert isinstance(exc.value, ValueError)


def _star(n, crossing=False):
    """A simple star polygon with ``n`` vertices; ``crossing`` moves one to the far side."""
    k = np.arange(n)
    r = np.where(k % 2, 40.0, 30.0)
    v = np.c_[50 + r * np.cos(2 * np.pi * k / n), 50 + r * np.sin(2 * np.pi * k / n)]
    if crossing:
        v[n // 3] = 100 - v[n // 3]             # to the far side: its edges cross the others
    return v.tolist()


def test_large_polygon_validates_in_n_log_n():
    """A 1000-vertex polygon (the limit) took ~11 s with the old pairwise loop (95 s for 3000)."""
    t0 = time.perf_counter()
    p = Polygon(_star(MAX_VERTICES))
    assert len(p.vertices) == MAX_VERTICES and time.perf_counter() - t0 < 2.0
    with pytest.raises(ScenarioError, match=r"^vertices = .{1,80}: the polygon is not simple"):
        Polygon(_star(MAX_VERTICES, crossing=True))
    with pytest.raises(ScenarioError, match=r"vertices = .*: has 1001 entries, at most 1000"):
        Polygon(_star(MAX_VERTICES + 1))


@pytest.mark.parametrize("verts, simple", [
    ([(0, 0), (4, 0), (4, 4), (0, 4)], True),
    ([(0, 0), (4, 0), (2, 1), (4, 4), (0, 4)], True),           # concave
    ([(0, 0), (4, 2), (4, 0), (0, 3)], False),                  # bow tie
    ([(0, 0), (4, 0), (2, 2), (4, 4), (0, 4), (2, 2)], False),  # touches itself at a vertex
    ([(0, 0), (4, 0), (4, 4), (4, 4), (0, 4)], False),          # repeated vertex
    ([(0, 0), (4, 0), (4, 4), (2, 0), (0, 4)], False),          # a vertex on another edge
])
def test_polygon_simplicity(verts, simple):
    if simple:
        assert Polygon(verts).vertices[0] == (0.0, 0.0)
    else:
        with pytest.raises(ScenarioError, match="not simple"):
            Polygon(verts)


def test_sizes_and_ranges_are_limited():
    lm = Landmark(1, (5, 5))
    with pytest.raises(ScenarioError, match=r"^obstacles = .*: has 1001 entries, at most 1000 allowed$"):
        World(obstacles=(Circle((50, 50), 1),) * (MAX_OBSTACLES + 1))
    with pytest.raises(ScenarioError, match=r"^landmarks = .*: has 10001 entries"):
        World(landmarks=(lm,) * (MAX_LANDMARKS + 1))
    with pytest.raises(ScenarioError, match=r"x_max = 1000000000000.0: must be in \[-1e\+06, 1e\+06\]"):
        Field(0, 0, 1e12, 10)
    with pytest.raises(ScenarioError, match=r"x_max = 1000000.0: makes the field's width 1e\+06 m"):
        Field(0, 0, 1e6, 10)
    with pytest.raises(ScenarioError, match=r"y_max = 0.5: makes the field's height 0.5 m"):
        Field(0, 0, 10, 0.5)
    assert Field(-5e4, -5e4, 5e4, 5e4).width == 1e5
    with pytest.raises(ScenarioError, match=r"id = 2147483648: must be in \[0, 2147483647\]"):
        Landmark(2**31, (1, 2))
    with pytest.raises(ScenarioError, match=r"class = 'xxx.*: has 1000 characters"):
        Landmark(1, (1, 2), "x" * 1000)
    with pytest.raises(ScenarioError, match=r"^radius = 10+\.\.\.0+: must be finite$"):
        Circle((1, 2), 10**400)
    with pytest.raises(ScenarioError, match=r"clusters = .*: has 101 entries"):
        PathType("P", list(range(101)))


def test_error_values_are_cut():
    with pytest.raises(ScenarioError) as exc:
        Circle(list(range(10**6)), 1)
    assert len(str(exc.value)) < 150 and "center = [0, 1, 2, 3, ...]" in str(exc.value)
    with pytest.raises(ScenarioError) as exc:
        Landmark(1, (1, 2), "c" * 10**7)
    assert len(str(exc.value)) < 150


def test_values_are_normalised_and_frozen():
    c = Circle([1, 2], 3)
    assert c.center == (1.0, 2.0) and isinstance(c.radius, float)
    with pytest.raises(AttributeError):
        c.radius = 4.0
    assert Polygon([[0, 0], [1, 0], [0, 1]]) == Polygon(((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)))


# --------------------------------------------------------------------------- planner arrays

def test_obstacle_and_hazard_arrays():
    w = small_world()
    circles, polys = w.obstacle_arrays()
    np.testing.assert_array_equal(circles, [[40, 70, 5]])
    assert len(polys) == 2 and polys[0].shape == (4, 2) and polys[1].shape == (3, 2)
    np.testing.assert_array_equal(polys[1], [[50, 50], [70, 52], [58, 68]])
    hc, hp, hr = w.hazard_arrays()
    np.testing.assert_array_equal(hc, [[30, 30, 15, 0.5]])
    np.testing.assert_array_equal(hr, [1.0])
    assert w.landmark_array().shape == (7, 3) and w.landmark_array()[0, 2] == 0.0
    empty = World()
    assert empty.obstacle_arrays()[0].shape == (0, 3) and empty.obstacle_arrays()[1] == []


# --------------------------------------------------------------------------- geometry vs direct computation

def _ray_cast(poly: np.ndarray, p) -> bool:
    x, y = p
    inside = False
    for (x1, y1), (x2, y2) in zip(poly, np.roll(poly, -1, axis=0)):
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside


def _boundary_distance(poly: np.ndarray, p) -> float:
    best = np.inf
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0, 1)
        best = min(best, np.linalg.norm(p - (a + t * (b - a))))
    return best


def test_point_in_obstacle_matches_direct_computation():
    w = small_world()
    rng = np.random.default_rng(1)
    pts = rng.uniform(0, 100, (3000, 2))
    circles, polys = w.obstacle_arrays()
    for margin in (0.0, 1.5):
        want = np.array([
            any(math.hypot(*(p - c[:2])) <= c[2] + margin for c in circles)
            or any(_ray_cast(P, p) or _boundary_distance(P, p) <= margin for P in polys)
            for p in pts])
        got = w.obstacle_mask(pts, margin)
        np.testing.assert_array_equal(got, want)
        assert all(w.point_in_obstacle(p, margin) == g for p, g in zip(pts[:200], got[:200]))
    assert w.point_in_obstacle((15, 15)) and w.point_in_obstacle((45, 70))   # inside square, on circle
    assert w.point_in_obstacle((20, 15)) and not w.point_in_obstacle((20.01, 15))  # boundary counts
    assert w.obstacles_at((15, 15)) == [1]
    hazards_as_obstacles = World(w.field, tuple(h.shape for h in w.hazards))     # overlapping: first one wins
    np.testing.assert_array_equal(hazards_as_obstacles.first_obstacle_at([(20, 20), (12, 12), (90, 10)]), [0, 1, -1])
    np.testing.assert_array_equal(w.first_obstacle_at(pts[:300], 1.5),
                                  [(w.obstacles_at(p, 1.5) or [-1])[0] for p in pts[:300]])


def test_segment_hits_obstacle_agrees_with_dense_sampling():
    w = small_world()
    rng = np.random.default_rng(2)
    step = 0.01
    n_hit = 0
    for _ in range(300):
        a, b = rng.uniform(0, 100, (2, 2))
        n = int(np.linalg.norm(b - a) / step) + 2
        dense = a + np.linspace(0, 1, n)[:, None] * (b - a)
        exact = w.segment_hits_obstacle(a, b)
        n_hit += exact
        if w.obstacle_mask(dense).any():
            assert exact
        if exact:   # a miss by dense sampling is at most a sliver of width ~step
            assert w.obstacle_mask(dense, margin=step).any()
    assert 30 < n_hit < 270


def test_segment_grazing_a_corner_is_a_hit():
    w = World(Field(0, 0, 100, 100), (SQUARE,))
    assert w.segment_hits_obstacle((0, 0), (30, 30))            # through the diagonal corners
    assert w.segment_hits_obstacle((20, 0), (20, 40))           # along an edge
    assert w.segment_hits_obstacle((0, 30), (10, 20))           # touches (10, 20) only
    assert not w.segment_hits_obstacle((0, 30), (9.5, 20.5))    # 0.707 m short of the corner
    assert w.segment_hits_obstacle((0, 30), (9.5, 20.5), margin=0.71)
    assert w.segment_hits_obstacle((12, 12), (13, 13))          # wholly inside
    assert w.polyline_hits_obstacle([(0, 0), (5, 50), (15, 50), (15, 15)])
    assert w.obstacles_hit_by([(0, 0), (5, 50)]) == []


def test_hazard_risk_is_the_highest_covering_level():
    w = small_world()
    np.testing.assert_array_equal(w.hazard_risk([(15, 15), (30, 30), (90, 10), (22, 25), (20, 20)]), [1.0, 0.5, 0.0, 0.5, 1.0])


def test_clusters_centroids_and_path_polyline():
    w = small_world()
    assert w.cluster_ids == (1, 2)
    assert [lm.id for lm in w.clusters()[2]] == [10, 11, 12, 13]
    xy = np.array([lm.position[:2] for lm in w.landmarks])
    np.testing.assert_allclose(w.cluster_centroid(1), xy[:3].mean(axis=0), rtol=0, atol=1e-12)
    np.testing.assert_allclose(w.cluster_centroids()[2], xy[3:].mean(axis=0), rtol=0, atol=1e-12)
    pl = w.path_polyline(PathType("X", (1, 2, 1)))
    np.testing.assert_array_equal(pl, [w.cluster_centroid(1), w.cluster_centroid(2), w.cluster_centroid(1)])
    np.testing.assert_array_equal(w.path_polyline([2, 1]), pl[1:])
    with pytest.raises(ScenarioError, match="cluster = 7"):
        w.path_polyline([1, 7])
    # 3D distance: the landmarks of cluster 2 are 5 m high
    c2 = w.cluster_centroid(2)
    assert len(w.landmarks_in_range(c2, 5.0, cluster=2)) == 0
    assert len(w.landmarks_in_range(c2, 8.0, cluster=2)) == 4
    assert len(w.landmarks_in_range(w.cluster_centroid(1), 3.0 + 1e-9)) == 3


def test_world_dict_round_trip():
    w = small_world()
    assert World.from_dict(w.to_dict()) == w


# --------------------------------------------------------------------------- generator (SafeNav V-A)

@pytest.mark.parametrize("seed", [0, 1, DEFAULT_SEED])
def test_generator_matches_the_paper(seed):
    cfg = GeneratorConfig()
    s = generate_scenario(seed)
    w = s.world
    assert (w.field.width, w.field.height) == (200.0, 200.0)
    assert len(w.obstacles) == 25 and len(w.hazards) == 25
    for cid, lms in w.clusters().items():
        assert len(lms) >= 3
        assert len(w.landmarks_in_range(w.cluster_centroid(cid), cfg.detection_range, cluster=cid)) == len(lms)
    assert s.detection.max_range_m == cfg.detection_range and s.detection.min_landmarks == 3
    routes = {p.name: (p.start, p.destination) for p in s.path_types}
    assert routes == {"P1": (6, 3), "P2": (4, 3), "P3": (7, 3)}
    lm_xy = w.landmark_array()[:, :2]
    assert not w.obstacle_mask(lm_xy, margin=cfg.landmark_clearance - 1e-6).any()
    for h in w.hazards:
        assert not h.shape.contains(lm_xy).any()
    for c in w.cluster_centroids().values():
        assert not w.point_in_obstacle(c, margin=cfg.centroid_clearance - 1e-6)
    n_blocked = 0
    for p in s.path_types:
        pl = w.path_polyline(p)
        hit = w.obstacles_hit_by(pl)
        n_blocked += len(hit)
        assert hit, f"{p.name}: no obstacle for the planner to avoid"
        assert w.obstacle_mask(_dense(pl)).mean() <= cfg.max_blocked_fraction
    assert n_blocked == cfg.n_blocking
    centers = [o.bounding_circle() for o in w.obstacles]
    for i in range(len(centers)):
        for j in range(i):
            (ci, ri), (cj, rj) = centers[i], centers[j]
            assert np.hypot(*(ci - cj)) >= ri + rj + cfg.obstacle_gap - 1e-9


def test_generator_is_deterministic():
    assert generate_world(3) == generate_world(3)
    assert generate_world(3) != generate_world(4)
    assert generate_scenario(5).to_dict() == generate_scenario(5).to_dict()


def test_generator_rejects_bad_input():
    with pytest.raises(ValueError, match="seed = -1"):
        generate_world(-1)
    with pytest.raises(ValueError, match="n_blocking"):
        GeneratorConfig(n_obstacles=2, n_blocking=3)

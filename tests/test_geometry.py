"""Corridor geometry (SafeNav V-A(iii), Algorithms 1 and 2) against direct
computation and trusted peers (scipy ConvexHull, matplotlib Path, numpy)."""

import numpy as np
import pytest
from matplotlib.path import Path as MplPath
from scipy.spatial import ConvexHull

from safenav import geometry as g
from safenav import metrics
from safenav.metrics import RiskZones

# A winding path with a sharp corner, a shallow bend and a repeated vertex.
PATH = np.array([[0.0, 0.0], [20.0, 0.0], [20.0, 0.0], [25.0, 15.0], [40.0, 18.0], [55.0, 5.0], [60.0, 30.0]])


def _signed_area(poly):
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)


def _halfplane_inside(poly, pts, tol=0.0):
    """Inside a CCW convex polygon: left of (or on) every edge."""
    a, b = poly, np.roll(poly, -1, axis=0)
    e = b - a
    cross = e[None, :, 0] * (pts[:, None, 1] - a[None, :, 1]) - e[None, :, 1] * (pts[:, None, 0] - a[None, :, 0])
    return np.all(cross >= -tol, axis=1), np.min(np.abs(cross) / np.linalg.norm(e, axis=1), axis=1)


def _is_convex_ccw(poly):
    a, b, c = poly, np.roll(poly, -1, axis=0), np.roll(poly, -2, axis=0)
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - b[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - b[:, 0])
    return np.all(cross > 0)


def _subset_rows(sub, full):
    return all(np.any(np.all(full == r, axis=1)) for r in sub)


@pytest.fixture(scope="module")
def corridor():
    return g.Corridor(PATH, RiskZones(half_width=2.0, weights=[2.0, 4.0, 6.0, 8.0]))


@pytest.fixture(scope="module")
def segs(corridor):
    return corridor.segments(count=7, spacing=0.5, sub_segments=5)


# ------------------------------------------------------------------ hulls
@pytest.mark.parametrize("seed", range(5))
def test_convex_hull_matches_scipy(seed):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(300, 2)) * [3.0, 1.0]
    hull = g.convex_hull(pts)
    ref = pts[ConvexHull(pts).vertices]  # scipy: CCW in 2-D
    assert _subset_rows(hull, pts)
    assert {tuple(r) for r in hull} == {tuple(r) for r in ref}
    assert _is_convex_ccw(hull)
    assert _signed_area(hull) == pytest.approx(ConvexHull(pts).volume, rel=1e-12)


def test_convex_hull_degenerate_inputs():
    assert g.convex_hull([[1.0, 2.0]]).shape == (1, 2)
    line = g.convex_hull([[0, 0], [1, 1], [2, 2], [3, 3]])
    assert {tuple(r) for r in line} == {(0.0, 0.0), (3.0, 3.0)}


@pytest.mark.parametrize("seed", range(3))
def test_points_in_polygon_matches_matplotlib(seed):
    rng = np.random.default_rng(seed)
    # a non-convex simple polygon (star)
    ang = np.linspace(0, 2 * np.pi, 14, endpoint=False)
    r = np.where(np.arange(14) % 2 == 0, 5.0, 2.0)
    poly = np.c_[r * np.cos(ang), r * np.sin(ang)]
    pts = rng.uniform(-6, 6, size=(4000, 2))
    ours = g.points_in_polygon(pts, poly)
    mpl = MplPath(poly).contains_points(pts)
    # matplotlib's boundary handling is unspecified: compare away from edges
    a, b = poly, np.roll(poly, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("pkj,kj->pk", pts[:, None, :] - a[None], ab) / np.sum(ab * ab, axis=1), 0, 1)
    dist = np.linalg.norm(pts[:, None, :] - (a[None] + t[..., None] * ab[None]), axis=2).min(axis=1)
    far = dist > 1e-9
    assert ours.dtype == bool and far.sum() > 3900
    np.testing.assert_array_equal(ours[far], mpl[far])
    # vertices count as inside; so do points exactly on an edge (exactly representable here:
    # a rounded midpoint of a slanted edge may lie a hair outside, and CGAL's predicates are exact)
    assert g.points_in_polygon(poly, poly).all()
    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    np.testing.assert_array_equal(g.points_in_polygon([[1, 0], [2, 1], [0, 0.5], [1, 1], [2.0 + 1e-15, 1]], square),
                                  [True, True, True, True, False])


def test_segment_hulls_contain_points_and_are_ccw_subsets(corridor, segs):
    assert len(segs) == 7
    for k in range(len(segs)):
        hull, inp, pts = segs.hull(k), segs.hull_input(k), segs.points(k)
        assert _subset_rows(hull, inp)
        assert _is_convex_ccw(hull)
        assert {tuple(r) for r in hull} == {tuple(r) for r in inp[ConvexHull(inp).vertices]}
        assert segs.hull_contains(k, pts).all()
        assert segs.hull_contains(k, inp).all()
        inside, _ = _halfplane_inside(hull, pts, tol=1e-9)
        assert inside.all()
        # densified central points: within spacing, on the path, spanning the segment's arc lengths
        assert np.all(np.linalg.norm(np.diff(pts, axis=0), axis=1) <= 0.5 + 1e-12)
        np.testing.assert_allclose(corridor.distance(pts), 0.0, atol=1e-9)
        s = corridor.arc_length(pts)
        assert s[0] == pytest.approx(segs.breaks[k], abs=1e-9)
        assert s[-1] == pytest.approx(segs.breaks[k + 1], abs=1e-9)


def test_segment_hull_covers_the_safe_buffer(corridor, segs):
    """Every point within W of a segment's central polyline lies in its hull."""
    rng = np.random.default_rng(1)
    W = corridor.half_width
    for k in range(len(segs)):
        s = rng.uniform(segs.breaks[k], segs.breaks[k + 1], 2000)
        r = W * np.sqrt(rng.uniform(0, 1, 2000))
        a = rng.uniform(0, 2 * np.pi, 2000)
        pts = corridor.points_at(s) + np.c_[r * np.cos(a), r * np.sin(a)]
        assert segs.hull_contains(k, pts).all()
        # and the hull is not much bigger than needed: hull area <= buffer hull area with 2 % radius slack
        hull = segs.hull(k)
        circle = np.c_[np.cos(np.linspace(0, 2 * np.pi, 400)), np.sin(np.linspace(0, 2 * np.pi, 400))]
        poly = segs.points(k)
        tight = ConvexHull((poly[:, None, :] + 1.02 * W * circle[None]).reshape(-1, 2))
        assert _signed_area(hull) <= tight.volume


def test_point_in_hull_matches_halfplane_brute_force(segs):
    rng = np.random.default_rng(2)
    pts = rng.uniform([-5, -5], [65, 35], size=(5000, 2))
    for k in range(len(segs)):
        ours = segs.hull_contains(k, pts)
        ref, margin = _halfplane_inside(segs.hull(k), pts)
        far = margin > 1e-9
        np.testing.assert_array_equal(ours[far], ref[far])
    # which segments contain a point: consistent with per-hull tests
    loc = segs.locate(pts[:500])
    for p, first in zip(pts[:500], loc):
        every = [k for k in range(len(segs)) if segs.hull_contains(k, p[None])[0]]
        assert segs.segments_containing(p) == every
        assert first == (every[0] if every else -1)
        for k in range(len(segs)):
            nxt = k + 1 < len(segs) and (k + 1) in every
            assert segs.in_current_or_next(k, p) == ((k in every) or nxt)


# -------------------------------------------------------------- centroids
def _polyline_between(path, cum, s0, s1):
    inner = path[(cum > s0) & (cum < s1)]
    at = lambda s: np.array([np.interp(s, cum, path[:, 0]), np.interp(s, cum, path[:, 1])])  # noqa: E731
    return np.vstack([at(s0), inner, at(s1)])


def test_centroids_match_direct_computation(corridor, segs):
    path = corridor.path
    cum = np.r_[0, np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))]
    m = 5
    cents = segs.centroids
    assert cents.shape == (len(segs) * m, 2)
    for k in range(len(segs)):
        edges = np.linspace(segs.breaks[k], segs.breaks[k + 1], m + 1)
        for j in range(m):
            q = _polyline_between(path, cum, edges[j], edges[j + 1])
            lens = np.linalg.norm(np.diff(q, axis=0), axis=1)
            ref = (lens[:, None] * 0.5 * (q[1:] + q[:-1])).sum(axis=0) / lens.sum()
            np.testing.assert_allclose(cents[k * m + j], ref, atol=1e-10)
            # the same as the mean of a dense uniform arc-length sampling
            dense = corridor.points_at(np.linspace(edges[j], edges[j + 1], 20001))
            np.testing.assert_allclose(cents[k * m + j], dense.mean(axis=0), atol=2e-3)
            assert segs.centroid_arc_lengths[k * m + j] == pytest.approx(0.5 * (edges[j] + edges[j + 1]))
        np.testing.assert_array_equal(segs.segment_centroids(k), cents[k * m:(k + 1) * m])


def test_nearest_centroid_ahead_matches_brute_force(corridor, segs):
    rng = np.random.default_rng(3)
    cents, cs = segs.centroids, segs.centroid_arc_lengths
    for p in corridor.points_at(rng.uniform(0, corridor.length, 200)) + rng.normal(0, 1.0, (200, 2)):
        t = segs.nearest_centroid_ahead(p)
        s = corridor.arc_length(p[None])[0]
        ahead = np.flatnonzero(cs > s)
        if ahead.size:
            best = ahead[np.argmin(np.linalg.norm(cents[ahead] - p, axis=1))]
            assert t.ahead and t.index == best
        else:
            assert not t.ahead and t.index == len(cents) - 1
        assert (t.segment, t.sub_segment) == divmod(t.index, 5)
        np.testing.assert_array_equal(t.point, cents[t.index])
    end = segs.nearest_centroid_ahead(corridor.path[-1] + [0.0, 1.0])
    assert not end.ahead and end.index == len(cents) - 1


def test_segmentation_by_length(corridor):
    segs = corridor.segments(length=12.0)
    L = corridor.length
    K = int(np.ceil(L / 12.0))
    assert len(segs) == K
    np.testing.assert_allclose(segs.breaks, np.linspace(0, L, K + 1))
    assert np.all(np.diff(segs.breaks) <= 12.0 + 1e-12)
    assert len(g.Corridor([[0, 0], [30, 0]]).segments(length=10.0)) == 3  # exact multiple: no sliver
    assert segs.segment_at(0.0) == 0 and segs.segment_at(L) == K - 1 and segs.segment_at(segs.breaks[1]) == 1
    assert segs.segment_at(-5.0) == 0 and segs.segment_at(L + 5) == K - 1


# --------------------------------------------------------------- corridor
def test_corridor_distance_zone_wrs_match_metrics(corridor):
    rng = np.random.default_rng(4)
    pts = corridor.points_at(rng.uniform(0, corridor.length, 3000)) + rng.normal(0, 1.5, (3000, 2))
    zones = corridor.zones
    d = corridor.distance(pts)
    np.testing.assert_allclose(d, metrics.distance_to_path(pts, PATH), atol=1e-12)
    np.testing.assert_allclose(corridor.wrs(pts), metrics.wrs(pts, PATH, zones), atol=1e-12)
    np.testing.assert_allclose(corridor.wrs(pts), metrics.wrs_of_deviation(d, zones), atol=1e-12)
    assert corridor.awrs(pts) == pytest.approx(metrics.awrs(pts, PATH, zones), abs=1e-12)
    W, n = corridor.half_width, corridor.zone_count
    ref_zone = np.where(d >= W, n, np.minimum(np.floor(d / (W / n)), n - 1))
    np.testing.assert_array_equal(corridor.zone(pts), ref_zone)
    np.testing.assert_array_equal(corridor.contains(pts), d <= W)
    assert 0 < corridor.contains(pts).mean() < 1


def test_side_and_signed_offset():
    c = g.Corridor([[0, 0], [10, 0], [10, 10]])
    pts = np.array([[5.0, 1.0], [5.0, -1.0], [5.0, 0.0], [11.0, 5.0], [9.0, 5.0], [12.0, -1.0]])
    np.testing.assert_array_equal(c.side(pts), [1, -1, 0, -1, 1, -1])
    np.testing.assert_allclose(c.signed_offset(pts), [1, -1, 0, -1, 1, -np.sqrt(5)])
    p = c.project([5.0, 1.0])
    assert p.arc_length == pytest.approx(5.0) and p.distance == pytest.approx(1.0) and p.side == 1
    np.testing.assert_allclose(p.foot, [5.0, 0.0])
    np.testing.assert_allclose(c.tangent_at(12.0), [0.0, 1.0])


def test_arc_length_point_at_roundtrip(corridor):
    rng = np.random.default_rng(5)
    s = np.sort(rng.uniform(0, corridor.length, 500))
    pts = corridor.points_at(s)
    np.testing.assert_allclose(corridor.arc_length(pts), s, atol=1e-9)
    np.testing.assert_allclose(corridor.distance(pts), 0.0, atol=1e-9)
    np.testing.assert_allclose(corridor.points_at(corridor.vertex_arc_lengths), corridor.path, atol=1e-12)
    # off-path points: point_at(s(p)) is the nearest path point
    off = pts + rng.normal(0, 0.7, pts.shape)
    feet = corridor.points_at(corridor.arc_length(off))
    np.testing.assert_allclose(np.linalg.norm(off - feet, axis=1), corridor.distance(off), atol=1e-9)
    # clamping beyond the ends; the duplicate vertex was dropped
    np.testing.assert_allclose(corridor.point_at(-3.0), PATH[0])
    np.testing.assert_allclose(corridor.point_at(corridor.length + 3.0), PATH[-1])
    assert len(corridor.path) == len(PATH) - 1
    assert corridor.length == pytest.approx(metrics.path_length(PATH))


# -------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: g.Corridor([[0, 0], [np.nan, 1]]), "nan|not finite"),
        (lambda: g.Corridor([[0, 0]]), "at least 2"),
        (lambda: g.Corridor([[1, 1], [1, 1], [1, 1]]), "zero length"),
        (lambda: g.Corridor(PATH, half_width=0.0), "half_width"),
        (lambda: g.Corridor(PATH, half_width=-1.0), "half_width"),
        (lambda: g.Corridor(PATH, half_width=np.nan), "half_width"),
        (lambda: g.Corridor(PATH).segments(count=0), "count"),
        (lambda: g.Corridor(PATH).segments(count=2, length=3.0), "not both"),
        (lambda: g.Corridor(PATH).segments(length=0.0), "length"),
        (lambda: g.Corridor(PATH).segments(length=1e-9), "limit"),
        (lambda: g.Corridor(PATH).segments(spacing=-1.0), "spacing"),
        (lambda: g.Corridor(PATH).segments(sub_segments=0), "sub_segments"),
        (lambda: g.Corridor(PATH).segments(disc_sides=2), "disc_sides"),
        (lambda: g.Corridor(PATH).segments(count=2).hull(2), "out of range"),
        (lambda: g.Corridor(PATH).segments(count=2).hull(-1), "out of range"),
        (lambda: g.Corridor(PATH).point_at(np.nan), "nan"),
        (lambda: g.Corridor(PATH).points_at([1.0, np.nan]), "not finite"),
        (lambda: g.Corridor(PATH).distance([[0, 0], [np.inf, 0]]), "not finite"),
        (lambda: g.Corridor(PATH).project([np.nan, 0]), "not finite"),
        (lambda: g.Corridor(PATH).awrs(np.zeros((0, 2))), "at least 1"),
        (lambda: g.Corridor(PATH).segments(count=2).nearest_centroid_ahead([0, np.nan]), "not finite"),
        (lambda: g.convex_hull(np.zeros((0, 2))), "at least 1"),
        (lambda: g.points_in_polygon([[0, 0]], [[0, 0], [1, 0]]), "at least 3"),
        (lambda: g.points_in_polygon([[0, 0]], [[0, 0], [1, 1], [1, 0], [0, 1]]), "not simple"),
        (lambda: g.Corridor([[0, 0, 0], [1, 1, 1]]), "shape"),
    ],
)
def test_bad_input_raises_value_error(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_core_rejects_bad_input_directly():
    """The C++ core validates on its own (embedding programs skip the Python checks)."""
    from safenav import _core

    with pytest.raises(ValueError, match="not finite"):
        _core.Corridor(np.array([[0.0, 0.0], [np.nan, 1.0]]), RiskZones())
    with pytest.raises(ValueError, match="count"):
        _core.SegmentOptions(count=-1)
    c = _core.Corridor(PATH, RiskZones())
    with pytest.raises(ValueError, match="not finite"):
        c.segments(_core.SegmentOptions(count=2)).hull_contains_point(0, np.array([np.nan, 0.0]))

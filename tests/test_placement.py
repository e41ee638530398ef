"""Landmark placement (the landmark placement paper): Lemmas 1–2 and
Corollary 1 against direct geometry, the greedy k-cover against brute force,
exact coverage after placement (and dense sampling with direct geometry),
the ILP against greedy and brute force, infeasible input, the tour heuristic
against enumeration, and the bearing-only EIF on a placed instance.  The
command line is test_placement_cli.py's."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from safenav import _core
from safenav import placement as P

CAM = P.CameraParams()  # R = 2 m, alpha = 50 deg, p = 0.05 m (the paper's section III)
TABLE_CAND = P.candidate_grid((0, 0), P.PAPER_AREA, 0.5, margin=2.0)
FINE_CAND = P.candidate_grid((0, 0), P.PAPER_AREA, 0.25, margin=2.0)


def feasible_route(rng, n, cand=TABLE_CAND, k=2, corners=False):
    """A Table I style route that the candidates can cover (some random
    instances cannot: candidates within p of another edge are removed)."""
    for _ in range(50):
        targets = P.random_instance(n, rng)
        route = targets[P.plan_tour(targets)]
        if P.place_along_route(route, cand, CAM, k=k, corners=corners, allow_uncovered=True).covered:
            return route
    raise AssertionError("no feasible instance in 50 draws")


def visible_direct(cam: P.CameraParams, t, d, landmark_local):
    """Direct geometry in the edge frame: camera at (t, 0) looking along +x."""
    t = np.asarray(t, float)
    rel = np.asarray(landmark_local, float)[None, :] - np.stack([t, np.zeros_like(t)], axis=1)
    dist = np.hypot(rel[:, 0], rel[:, 1])
    ok = (dist <= cam.range) & (dist > 0)
    if cam.fov == "sector":
        ok &= np.abs(np.arctan2(rel[:, 1], rel[:, 0])) <= cam.angle / 2
    return ok


# ---------------------------------------------------------------------------
# Lemma 1, Lemma 2, Corollary 1
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("fov,angle", [("sector", 50.0), ("sector", 120.0), ("sector", 180.0), ("circular", 50.0)])
def test_visibility_interval_matches_direct_geometry(fov, angle):
    cam = P.CameraParams(range=2.0, angle_deg=angle, fov=fov)
    core = cam.to_core()
    rng = np.random.default_rng(1)
    n_seen = 0
    for _ in range(300):
        d = rng.uniform(0.3, 4.0)
        lm = rng.uniform((-2.5, -2.2), (d + 2.5, 2.2))
        iv = _core.visibility_interval(lm, d, core)
        ts = np.linspace(0, d, 4001)
        vis = visible_direct(cam, ts, d, lm)
        if iv is None:
            assert not vis.any()
            continue
        n_seen += 1
        a, b = iv
        inside = (ts >= a) & (ts <= b)
        # identical except within one sample of the ends
        h = d / 4000
        diff = vis != inside
        assert not (diff & (np.abs(ts - a) > h) & (np.abs(ts - b) > h)).any()
        if fov == "sector":  # Lemma 2 as printed, eqs. (1)-(2)
            x, y = lm
            assert a == pytest.approx(max(x - math.sqrt(cam.range**2 - y**2), 0.0))
            assert b == pytest.approx(min(x - abs(y) / math.tan(cam.angle / 2), d), abs=1e-12)
        else:  # Corollary 1 with the typo fixed: t_d = min(x + sqrt(R^2 - y^2), d)
            x, y = lm
            assert b == pytest.approx(min(x + math.sqrt(cam.range**2 - y**2), d))
    assert n_seen > 30


def test_lemma1_region_is_where_the_interval_is_not_empty():
    core = CAM.to_core()
    rng = np.random.default_rng(2)
    agree = 0
    for _ in range(3000):
        d = rng.uniform(0.3, 3.0)
        lm = rng.uniform((-1.0, -1.0), (d + 2.5, 1.0))
        assert _core.in_region_of_influence(lm, d, core) == (_core.visibility_interval(lm, d, core) is not None)
        agree += 1
    assert agree == 3000


def test_edge_frame_is_a_rigid_transform():
    rng = np.random.default_rng(3)
    for _ in range(50):
        a, b = rng.uniform(-5, 5, (2, 2))
        f = _core.EdgeFrame(a, b)
        np.testing.assert_allclose(f.to_local(b), [np.hypot(*(b - a)), 0.0], atol=1e-12)
        np.testing.assert_allclose(f.to_local(a), [0.0, 0.0], atol=1e-12)
        p = rng.uniform(-5, 5, 2)
        np.testing.assert_allclose(f.to_world(f.to_local(p)), p, atol=1e-12)
        assert np.hypot(*f.to_local(p)) == pytest.approx(np.hypot(*(p - a)))


# ---------------------------------------------------------------------------
# Greedy k-cover (Algorithm 1, Proposition 1) against brute force
# ---------------------------------------------------------------------------

def covered_k_times(intervals, d, k, eps=1e-9):
    """Brute-force check: every point of [0, d] in >= k closed intervals."""
    if len(intervals) == 0:
        return False
    iv = np.asarray(intervals, float)
    pts = np.unique(np.clip(np.concatenate([iv.ravel(), [0.0, d]]), 0, d))
    probe = np.concatenate([pts, (pts[:-1] + pts[1:]) / 2])
    cnt = ((iv[None, :, 0] - eps <= probe[:, None]) & (probe[:, None] <= iv[None, :, 1] + eps)).sum(axis=1)
    gaps = np.diff(pts)
    ok_mid = cnt[len(pts):] >= k
    # pieces shorter than eps are rounding, as in the core
    return bool((cnt[:len(pts)] >= k).all() and (ok_mid | (gaps <= eps)).all())


def brute_force_cover(intervals, d, k):
    n = len(intervals)
    for size in range(k, n + 1):
        for sub in itertools.combinations(range(n), size):
            if covered_k_times([intervals[i] for i in sub], d, k):
                return size
    return None


def random_edge_intervals(rng, n):
    d = rng.uniform(0.5, 3.0)
    lms = rng.uniform((-0.5, -0.9), (d + 2.0, 0.9), size=(4 * n, 2))
    core = CAM.to_core()
    iv = [x for x in (_core.visibility_interval(p, d, core) for p in lms) if x is not None]
    return d, iv[:n]


@pytest.mark.parametrize("k", [1, 2, 3])
def test_greedy_equals_brute_force_on_random_edges(k):
    rng = np.random.default_rng(10 + k)
    n_feasible = n_infeasible = 0
    for _ in range(120 if k == 2 else 60):
        d, iv = random_edge_intervals(rng, int(rng.integers(4, 12)))
        if not iv:
            continue
        chosen, uncovered = _core.greedy_cover(np.array(iv), d, k, np.zeros((0, 2)))
        best = brute_force_cover(iv, d, k)
        if best is None:
            n_infeasible += 1
            assert uncovered, "greedy claims a cover where none exists"
        else:
            n_feasible += 1
            assert not uncovered
            assert len(chosen) == best
            assert covered_k_times([iv[i] for i in chosen], d, k)
    assert n_feasible >= {1: 40, 2: 40, 3: 10}[k] and n_infeasible >= 5


def test_greedy_count_equals_brute_force_on_200_coverable_edges():
    """The issue's acceptance test for Proposition 1 at the default k = 2:
    at least 200 random small edges that can be 2-covered, where the greedy's
    count must equal the brute-force optimum (and its picks must 2-cover)."""
    rng = np.random.default_rng(99)
    core = CAM.to_core()
    compared = tried = 0
    while compared < 200:
        tried += 1
        assert tried < 2000, "too few coverable edges drawn"
        d = rng.uniform(0.3, 2.0)
        lms = rng.uniform((-0.5, -0.9), (d + 2.0, 0.9), size=(40, 2))
        iv = [x for x in (_core.visibility_interval(p, d, core) for p in lms) if x is not None]
        iv = iv[: int(rng.integers(5, 11))]
        if len(iv) < 2:
            continue
        best = brute_force_cover(iv, d, 2)
        chosen, uncovered = _core.greedy_cover(np.array(iv), d, 2, np.zeros((0, 2)))
        if best is None:
            assert uncovered
            continue
        assert not uncovered and len(chosen) == best, (d, iv, chosen, best)
        assert covered_k_times([iv[i] for i in chosen], d, 2)
        compared += 1


def test_greedy_with_preplaced_intervals_is_optimal():
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(80):
        d, iv = random_edge_intervals(rng, 12)
        if len(iv) < 6:
            continue
        pre, pool = iv[:3], iv[3:]
        chosen, uncovered = _core.greedy_cover(np.array(pool), d, 2, np.array(pre))
        best = None
        for size in range(0, len(pool) + 1):
            if any(covered_k_times(pre + [pool[i] for i in sub], d, 2)
                   for sub in itertools.combinations(range(len(pool)), size)):
                best = size
                break
        if best is None:
            assert uncovered
        else:
            assert not uncovered and len(chosen) == best
            checked += 1
    assert checked >= 20


def test_paper_algorithm1_trace():
    # Two intervals at the entrance with the largest ends, then the one
    # covering the smaller frontier that reaches farthest (section II-A).
    iv = np.array([[0, 1.0], [0, 2.0], [0, 0.5], [0.8, 2.5], [1.5, 3.0], [2.0, 3.0]])
    chosen, unc = _core.greedy_cover(iv, 3.0, 2, np.zeros((0, 2)))
    # point 2.9 needs both [1.5, 3] and [2, 3]; 1.2 needs [0, 2] and [0.8, 2.5]; 0 needs two of 0, 1, 2
    assert chosen == [1, 0, 3, 4, 5] and not unc
    assert brute_force_cover(iv.tolist(), 3.0, 2) == 5


def test_uncovered_stretch_is_named():
    iv = np.array([[0, 1.0], [0, 1.2], [1.5, 3.0], [1.4, 3.0]])
    chosen, unc = _core.greedy_cover(iv, 3.0, 2, np.zeros((0, 2)))
    assert len(unc) == 1
    a, b = unc[0]
    assert a == pytest.approx(1.0) and b == pytest.approx(1.5)


# ---------------------------------------------------------------------------
# Placement on routes: exact coverage, dense sampling, clearance
# ---------------------------------------------------------------------------

def dense_counts(route, landmarks, cam: P.CameraParams, per_metre=400, rng=None):
    """Landmarks in view (direct geometry, distinct bearings) at random points of every edge."""
    rng = rng or np.random.default_rng(0)
    worst = np.inf
    for a, b in zip(route[:-1], route[1:]):
        d = np.hypot(*(b - a))
        t = rng.uniform(0, 1, max(50, int(per_metre * d)))
        pos = a + t[:, None] * (b - a)
        heading = math.atan2(*(b - a)[::-1])
        rel = landmarks[None, :, :] - pos[:, None, :]
        dist = np.hypot(rel[..., 0], rel[..., 1])
        brg = np.angle(np.exp(1j * (np.arctan2(rel[..., 1], rel[..., 0]) - heading)))
        ok = (dist <= cam.range) & (np.abs(brg) <= cam.angle / 2)
        for row in range(len(t)):
            worst = min(worst, len(np.unique(np.round(brg[row][ok[row]], 9))))
    return worst


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("k", [1, 2, 3])
def test_placement_covers_every_point(seed, k):
    rng = np.random.default_rng(seed)
    cand = TABLE_CAND if k < 3 else FINE_CAND
    route = feasible_route(rng, 6, cand, k=k)
    res = P.place_along_route(route, cand, CAM, k=k)
    rep = res.check()
    assert rep.min_count >= k and len(rep.start) == 0
    assert rep.min_distance > CAM.clearance
    assert dense_counts(route, res.landmarks, CAM, rng=rng) >= k
    # the union holds each edge's own picks
    assert set(itertools.chain.from_iterable(res.edge_landmarks)) == set(res.indices)


def test_corner_option_covers_the_turns_and_plain_does_not():
    rng = np.random.default_rng(5)
    route = feasible_route(rng, 7, corners=True)
    plain = P.place_along_route(route, TABLE_CAND, CAM)
    corner = P.place_along_route(route, TABLE_CAND, CAM, corners=True)
    assert plain.check(corners=True).min_count < 2       # the paper's gap at the corners
    rep = corner.check(corners=True)
    assert rep.min_count >= 2 and len(rep.start) == 0
    assert set(plain.indices) <= set(corner.indices)
    # direct geometry: headings swept at each vertex
    for v in range(1, len(route) - 1):
        h_in = math.atan2(*(route[v] - route[v - 1])[::-1])
        turn = _core.turn_angles(route)[v - 1]
        for s in np.linspace(0, 1, 97):
            seen = CAM.in_view(route[v], h_in + s * turn, corner.landmarks)
            assert seen.sum() >= 2


def test_clearance_removes_candidates_near_the_route():
    route = np.array([[0.0, 0.0], [3.0, 0.0]])
    cand = P.candidate_grid((-1, -2), (5, 2), 0.25)
    res = P.place_along_route(route, cand, P.CameraParams(clearance=0.3))
    d = _core.distance_to_route(route, cand)
    np.testing.assert_array_equal(np.sort(res.too_close), np.flatnonzero(d <= 0.3))
    assert (d[res.indices] > 0.3).all()


def test_non_coincidence_rule():
    rng = np.random.default_rng(11)
    hits = 0
    for _ in range(6):
        route = feasible_route(rng, 6)
        verbatim = P.place_along_route(route, TABLE_CAND, CAM, distinct_bearings=False, allow_uncovered=True)
        ruled = P.place_along_route(route, TABLE_CAND, CAM)
        assert ruled.check().min_count >= 2
        if verbatim.check().min_count < 2:  # Algorithm 1 alone lets two picks align
            assert not verbatim.covered  # and its certificate says so
            hits += 1
            assert ruled.count > verbatim.count
    assert hits >= 1


def test_reuse_never_needs_more_than_the_union():
    rng = np.random.default_rng(12)
    for _ in range(4):
        route = feasible_route(rng, 7)
        union = P.place_along_route(route, TABLE_CAND, CAM)
        reuse = P.place_along_route(route, TABLE_CAND, CAM, reuse=True)
        assert reuse.check().min_count >= 2
        assert reuse.count <= union.count + 1  # greedy per edge; usually fewer


# Issue #12: routes through candidate-grid nodes have candidates on each
# edge's own line, which all share one bearing (0 ahead) wherever two are in
# view.  The greedy used to certify such routes with min_count = 1 and the ILP
# to raise KeyError on them.
ON_NODE_ROUTES = [[[0, 0], [1.5, 0]], [[0, 0], [2, 0]], [[1, 1], [1, 3]], [[0, 0], [2, 0], [2, 2]],
                  [[0, 0], [1, 0.5], [2, 1]]]


@pytest.mark.parametrize("corners", [False, True])
@pytest.mark.parametrize("route", ON_NODE_ROUTES)
def test_on_node_routes_certificate_is_the_exact_check(route, corners):
    route = np.array(route, float)
    cand = P.candidate_grid(route.min(0), route.max(0), 0.5, margin=2.0)
    optimum = P.place_optimal(route, cand, CAM, corners=corners, allow_uncovered=True)
    for res in (P.place_along_route(route, cand, CAM, corners=corners, allow_uncovered=True),
                P.place_along_route(route, cand, CAM, corners=corners, reuse=True, allow_uncovered=True), optimum):
        rep = res.check()
        assert res.covered == (rep.min_count >= 2 and len(rep.start) == 0), res.method
        if res.covered:
            assert dense_counts(route, res.landmarks, CAM) >= 2
        else:  # the L-shaped route: the clearance of its second edge leaves a stretch of the first uncoverable
            assert len(route) == 3 and not optimum.covered


def test_on_line_candidates_one_per_side():
    """On the edge (0, 0) -> (1.5, 0) the candidates (2, 0), (2.5, 0), (3, 0)...
    lie ahead on the edge's line: the greedy takes at most one of them."""
    route = np.array([[0.0, 0.0], [1.5, 0.0]])
    cand = P.candidate_grid((0, 0), (1.5, 0), 0.5, margin=2.0)
    res = P.place_along_route(route, cand, CAM)
    ahead = [p for p in res.landmarks if p[1] == 0 and p[0] > 1.5]
    assert len(ahead) <= 1 and res.check().min_count >= 2


def test_ilp_handles_alpha_180_and_tiny_edges():
    route = np.array([[0.0, 0.0], [1e-10, 0.0], [1e-10, 1.5]])
    cand = P.candidate_grid((0, 0), (0, 1.5), 0.5, margin=2.0)
    for cam in (CAM, P.CameraParams(angle_deg=180.0)):
        for corners in (False, True):
            o = P.place_optimal(route, cand, cam, corners=corners, allow_uncovered=True)
            g = P.place_along_route(route, cand, cam, corners=corners, allow_uncovered=True)
            for res in (o, g):
                rep = res.check()
                assert res.covered == (rep.min_count >= 2 and len(rep.start) == 0)
            if g.covered:
                assert o.count <= g.count


def test_abeam_landmark_at_180_degrees_is_in_view():
    """α = 180°: cot(α/2) is 6e-17, not 0, so Lemma 2 gave an interval empty
    by 1e-17 m for a landmark abeam of the edge's start; found by the
    property tests (the brute force sees it there)."""
    cam = P.CameraParams(range=1.5, angle_deg=180.0, clearance=0.0)
    assert _core.visibility_interval(np.array([0.0, 1.0]), 1.0, cam.to_core()) == (0.0, 0.0)
    route = np.array([[0.0, 0.0], [1e-10, 0.0], [1e-10, 1.0]])
    assert P.check_coverage(route, [[-1.0, 1.0], [0.0, -1.5]], cam, k=1).min_count == 1


def test_inputs_are_checked_alike_by_greedy_ilp_and_check():
    route = np.array([[0.0, 0.0], [2.0, 0.0]])
    calls = {"greedy": lambda c, k: P.place_along_route(route, c, CAM, k=k, allow_uncovered=True),
             "ilp": lambda c, k: P.place_optimal(route, c, CAM, k=k, allow_uncovered=True),
             "check": lambda c, k: P.check_coverage(route, c, CAM, k=k)}
    dup = [[0, 1], [1, 1], [0, 1]]
    for name, call in calls.items():
        with pytest.raises(ValueError, match=r"\[0\] and \w+\[2\] coincide at \(0, 1\)"):
            call(dup, 2)
        for k in (0, -1, 1.5, True):
            with pytest.raises(ValueError, match=r"k must be a positive integer"):
                call(TABLE_CAND[:5], k)
        for k in (_core.PLACEMENT_MAX_K + 1, 100_000, 2**31, 2**70):
            with pytest.raises(ValueError, match=rf"k = {k} must be <= {_core.PLACEMENT_MAX_K}"):
                call(TABLE_CAND[:5], k)
    with pytest.raises(ValueError, match=r"k = 1001 must be in \[1, 1000\]"):  # the core checks too
        _core.greedy_cover(np.array([[0.0, 1.0]]), 1.0, 1001, np.zeros((0, 2)))


def test_largest_k_is_quick_and_honest():
    """k at its bound: the greedy's cost does not grow with k (it used to run
    for minutes at k = 100000), and the placement is honestly uncovered."""
    route = np.array([[0.0, 0.0], [2.0, 0.0]])
    cand = P.candidate_grid((0, 0), (2, 0), 0.5, margin=2.0)
    res = P.place_along_route(route, cand, CAM, k=_core.PLACEMENT_MAX_K, allow_uncovered=True)
    assert not res.covered and res.check().min_count < _core.PLACEMENT_MAX_K
    chosen, unc = _core.greedy_cover(np.array([[0.0, 0.5], [0.2, 1.0]]), 1.0, _core.PLACEMENT_MAX_K,
                                     np.zeros((0, 2)))
    assert sorted(chosen) == [0, 1] and unc == [(0.0, 1.0)]


# ---------------------------------------------------------------------------
# ILP
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("corners", [False, True])
def test_ilp_never_worse_than_greedy_and_covers(corners):
    rng = np.random.default_rng(20)
    for _ in range(2):
        route = feasible_route(rng, 5, corners=corners)
        g = P.place_along_route(route, TABLE_CAND, CAM, corners=corners)
        o = P.place_optimal(route, TABLE_CAND, CAM, corners=corners)
        assert o.optimal
        assert o.count <= g.count
        rep = o.check()
        assert rep.min_count >= 2 and len(rep.start) == 0 and rep.min_distance > CAM.clearance


def test_ilp_equals_brute_force_on_tiny_instances():
    rng = np.random.default_rng(21)
    done = 0
    for _ in range(40):
        route = np.cumsum(rng.uniform(-0.6, 0.6, (3, 2)), axis=0) + [1.5, 1.5]
        if (np.hypot(*np.diff(route, axis=0).T) < 0.2).any():
            continue
        cand = rng.uniform(route.min(0) - 1.0, route.max(0) + 1.5, (14, 2))
        vis = _core.edge_visibility(route, cand, CAM.to_core())
        useful = np.unique(vis.candidate)
        if len(useful) > 12:
            useful = useful[:12]
        best = None
        for size in range(2, len(useful) + 1):
            for sub in itertools.combinations(useful, size):
                if _core.check_coverage(route, cand[list(sub)], CAM.to_core(), 2, False).min_count >= 2:
                    best = size
                    break
            if best is not None:
                break
        if best is None:
            continue
        o = P.place_optimal(route, cand[useful], CAM)
        assert o.count == best
        done += 1
        if done >= 6:
            break
    assert done >= 4


# ---------------------------------------------------------------------------
# Bad input
# ---------------------------------------------------------------------------

def test_infeasible_and_bad_input_messages():
    route = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0]])
    sparse = P.candidate_grid((-1, -1), (5, 5), 1.5)
    with pytest.raises(ValueError, match=r"cannot keep 2 landmarks in view on edge \d+ from"):
        P.place_along_route(route, sparse, CAM)
    res = P.place_along_route(route, sparse, CAM, allow_uncovered=True)
    assert res.uncovered and res.uncovered[0][0] == "edge"
    with pytest.raises(ValueError, match="cannot keep"):
        P.place_optimal(route, sparse, CAM)
    with pytest.raises(ValueError, match=r"range R = 0.05 must exceed the clearance p = 0.05"):
        P.CameraParams(range=0.05, clearance=0.05)
    with pytest.raises(ValueError, match=r"angle alpha = 0.0 deg must be in \(0, 180\]"):
        P.CameraParams(angle_deg=0.0)
    with pytest.raises(ValueError, match=r"angle alpha = 190.0 deg"):
        P.CameraParams(angle_deg=190.0)
    with pytest.raises(ValueError, match=r"route\[2\] = \(3, 0\) repeats route\[1\]"):
        P.place_along_route([[0, 0], [3, 0], [3, 0], [3, 3]], TABLE_CAND, CAM)
    with pytest.raises(ValueError, match=r"route\[1\] = .* repeats route\[0\]"):  # the core checks too
        _core.place_landmarks(np.array([[1.0, 1], [1, 1]]), TABLE_CAND, CAM.to_core(), _core.PlacementOptions())
    with pytest.raises(ValueError, match=r"candidates\[\(1, 0\)\] = nan is not finite"):
        P.place_along_route(route, [[0, 1], [np.nan, 1]], CAM)
    with pytest.raises(ValueError, match=r"candidates\[0\] and candidates\[2\] coincide"):
        P.place_along_route(route, [[0, 1], [1, 1], [0, 1]], CAM)
    with pytest.raises(ValueError, match="k must be a positive integer"):
        P.place_along_route(route, TABLE_CAND, CAM, k=0)
    with pytest.raises(ValueError, match="targets\\[0\\] and targets\\[2\\] repeat"):
        P.plan_tour([[0, 0], [1, 1], [0, 0]])
    with pytest.raises(ValueError, match="route must have at least 2 points"):
        P.place_along_route([[0, 0]], TABLE_CAND, CAM)
    with pytest.raises(ValueError, match="camera fov"):
        P.CameraParams(fov="fisheye")
    with pytest.raises(ValueError, match="camera: unknown parameter 'zoom'"):
        P.place_along_route(route, TABLE_CAND, {"zoom": 2})
    with pytest.raises(ValueError, match="margin = nan must be a finite number"):
        P.candidate_grid((0, 0), (4, 8), 0.5, margin=float("nan"))
    with pytest.raises(ValueError, match="source = 1.5 is not a target index"):
        P.plan_tour([[0, 0], [1, 1], [2, 2]], source=1.5)
    with pytest.raises(ValueError, match="prior_std"):
        P.simulate(route, TABLE_CAND[:3], CAM, prior_std=(-1, 0, 0, 0))
    with pytest.raises(ValueError, match="time_limit = nan"):
        P.place_optimal(route, TABLE_CAND, CAM, time_limit=float("nan"))
    with pytest.raises(ValueError, match="bearing_std = 'x'"):
        P.simulate(route, TABLE_CAND[:3], CAM, bearing_std="x")


# ---------------------------------------------------------------------------
# Tour, SafeNav path, Table I
# ---------------------------------------------------------------------------

def test_tour_is_optimal_on_small_instances():
    rng = np.random.default_rng(30)
    for n in (4, 5, 6, 7, 8):
        for _ in range(3):
            t = rng.uniform((0, 0), (4, 8), (n, 2))
            order = P.plan_tour(t)
            assert order[0] == 0 and order[-1] == n - 1 and sorted(order) == list(range(n))
            best = min(P.tour_length(t[[0, *perm, n - 1]]) for perm in itertools.permutations(range(1, n - 1)))
            assert P.tour_length(t[order]) == pytest.approx(best, rel=1e-12)


def test_place_along_a_safenav_path():
    import safenav

    sc = safenav.default_scenario()
    world = sc.world
    path = world.path_polyline(sc.path_types[1])  # P1 crosses obstacles where no landmark may stand
    cam = P.CameraParams(range=8.0, angle_deg=60.0, clearance=1.0)
    res = P.place_along_path(path, cam, spacing=2.0, world=world)
    rep = res.check()
    assert rep.min_count >= 2 and rep.min_distance > 1.0
    assert not world.obstacle_mask(res.landmarks).any()


def test_place_along_a_planned_safenav_safe_path():
    """The planner's safe path (a PlanResult, not the reference polyline): with the
    default corner coverage the vehicle sees >= 2 landmarks everywhere on it, edges
    and turns, checked exactly and by dense sampling with direct geometry; no
    landmark within p of the path, inside an obstacle or outside the field."""
    import safenav
    from safenav import navigation as nv

    sc = safenav.default_scenario()
    plan = nv.plan_safe_path(sc, "P3", iterations=1500)
    assert plan.success
    cam = P.CameraParams(range=8.0, angle_deg=60.0, clearance=1.0)
    res = P.place_along_path(plan, cam, spacing=2.0, world=sc.world)
    assert res.corners and res.covered and len(res.route) >= 3
    np.testing.assert_allclose(res.route[[0, -1]], np.asarray(plan.path)[[0, -1]])
    rep = res.check(corners=True)
    assert rep.min_count >= 2 and len(rep.start) == 0
    assert dense_counts(res.route, res.landmarks, cam, per_metre=20) >= 2
    d = np.array([min(np.hypot(*(q - (a + np.clip((q - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1) * (b - a))))
                      for a, b in zip(res.route[:-1], res.route[1:])) for q in res.landmarks])
    assert d.min() > cam.clearance
    assert not sc.world.obstacle_mask(res.landmarks).any() and sc.world.field.contains(res.landmarks).all()
    with pytest.raises(ValueError, match="path must have at least 2 points, got 0"):
        P.place_along_path(np.zeros((0, 2)), cam)


def test_table_one_shape_and_order():
    df = P.table_one(seed=0, sizes=[5, 6], optimal=True, time_limit=60)
    assert list(df["targets"]) == [5, 6]
    assert (df["optimal"] <= df["greedy"]).all() and (df["optimal_corners"] <= df["greedy_corners"]).all()
    assert (df["greedy_corners"] >= df["greedy"]).all() and (df["optimal_corners"] >= df["optimal"]).all()
    assert df["covered"].all() and df["proven"].all()
    assert list(df["paper"]) == [21, None] or list(df["paper"])[0] == 21


# ---------------------------------------------------------------------------
# Bearing-only EIF on a placed instance (section III)
# ---------------------------------------------------------------------------

def test_eif_consistent_on_a_placed_instance():
    rng = np.random.default_rng(40)
    route = feasible_route(rng, 6, corners=True)
    res = P.place_along_route(route, TABLE_CAND, CAM, corners=True)
    sim = P.simulate(route, res.landmarks, CAM, seed=1)
    inside = sim.inside_3sigma()
    assert min(inside.values()) >= 0.95, inside
    # ... with bounds that say something (measured: median σ 5 mm, 4 mm rad) and a
    # mean NEES near its 3 degrees of freedom (measured 2.7), so 3σ is not inflated
    assert (np.median(sim.sigmas, axis=0) < [0.02, 0.02, 0.02]).all()
    C = sim.covariance[:, [0, 1, 3]][:, :, [0, 1, 3]]
    nees = np.einsum("ni,ni->n", sim.errors, np.linalg.solve(C, sim.errors[..., None])[..., 0])
    assert 1.5 < nees.mean() < 4.5
    # the robot drove the route and the estimate tracks it
    assert np.hypot(*(sim.truth[-1, :2] - route[-1])) < 0.05
    assert np.abs(sim.errors[:, :2]).max() < 0.2
    assert sim.gap_fraction(2) < 0.02

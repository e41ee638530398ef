"""Property tests of landmark placement against an exact brute-force check
written here from first principles (issue #12, part 1).

The oracle knows nothing of Lemma 2 or the core.  Per edge it lists every
point where what the camera sees can change (a landmark at range R, on a
field-of-view border or straight ahead/behind, two landmarks collinear with
the camera), then at each of those points and the midpoints between them
counts, by direct geometry, the distinct bearings of the landmarks in view.
Corners (the in-place turn) the same over the turned angle.

The rule under test: a placement is ``covered`` exactly when this oracle finds
at least k distinct bearings at every point, for the greedy in every mode and
for the ILP; and ``check_coverage``'s ``min_count`` equals the oracle's minimum.

Generators aim at the degenerate cases: targets on candidate-grid nodes (so
candidates lie on an edge's own line, ahead of and behind the edge), collinear
and back-and-forth routes (revisited points), 180° and circular fields of view,
zero clearance, edges of 1e-10 m.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from safenav import _core
from safenav import placement as P

TOL = 1e-9  # [m] and [rad], the core's rounding slack

FAST = settings(max_examples=60, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
SLOW = settings(max_examples=1500, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


# ---------------------------------------------------------------------------
# The oracle
# ---------------------------------------------------------------------------

def _distinct(bearings) -> int:
    """Distinct directions among ``bearings`` [rad] (equal within TOL, across ±π)."""
    if len(bearings) == 0:
        return 0
    b = np.sort(np.mod(np.asarray(bearings), 2 * math.pi))
    gaps = np.diff(np.concatenate([b, [b[0] + 2 * math.pi]]))
    return max(1, int((gaps > TOL).sum()))


def _seen(cam: P.CameraParams, pos, heading, landmarks) -> np.ndarray:
    """World bearings of the landmarks in view from ``pos`` looking along ``heading``."""
    rel = landmarks - pos
    dist = np.hypot(rel[:, 0], rel[:, 1])
    brg = np.arctan2(rel[:, 1], rel[:, 0])
    ok = (dist > TOL) & (dist <= cam.range + TOL)
    if cam.fov == "sector":
        ok &= np.abs(np.angle(np.exp(1j * (brg - heading)))) <= cam.angle / 2 + TOL
    return brg[ok]


def _probe(events, length):
    """The events inside [0, length] with both ends, and the midpoints between them."""
    pts = np.unique(np.clip(np.concatenate([np.asarray(events, float), [0.0, length]]), 0.0, length))
    return np.concatenate([pts, 0.5 * (pts[1:] + pts[:-1])])


def oracle_min_count(route, landmarks, cam: P.CameraParams, corners: bool) -> int:
    """Fewest distinct bearings in view anywhere on the route (and, with
    ``corners``, anywhere in the in-place turns), by brute force."""
    lm = np.asarray(landmarks, float).reshape(-1, 2)
    worst = math.inf
    half = cam.angle / 2
    for a, b in zip(route[:-1], route[1:]):
        d = float(np.hypot(*(b - a)))
        u = (b - a) / d
        heading = math.atan2(u[1], u[0])
        x = (lm - a) @ u
        y = (lm - a) @ np.array([-u[1], u[0]])
        h = np.sqrt(np.maximum(cam.range ** 2 - y ** 2, 0.0))
        events = [x - h, x + h, x]                                # range R; straight ahead / behind
        if cam.fov == "sector" and half < math.pi / 2:
            events.append(x - np.abs(y) / math.tan(half))         # a border of the field of view
        i, j = np.triu_indices(len(lm), 1)
        dy = y[j] - y[i]
        ok = np.abs(dy) > 0
        events.append(x[i][ok] - y[i][ok] * (x[j][ok] - x[i][ok]) / dy[ok])   # camera on the line ℓi ℓj
        for t in _probe(np.concatenate(events) if len(lm) else [], d):
            worst = min(worst, _distinct(_seen(cam, a + t * u, heading, lm)))
    if corners:
        turns = _core.turn_angles(route)
        for v in range(1, len(route) - 1):
            turn = float(turns[v - 1])
            if abs(turn) <= TOL:
                continue
            th_in = math.atan2(*(route[v] - route[v - 1])[::-1])
            sgn = 1.0 if turn > 0 else -1.0
            brg = np.arctan2(*(lm - route[v]).T[::-1]) if len(lm) else np.zeros(0)
            events = [np.mod(sgn * (brg - th_in) + s * half, 2 * math.pi) for s in (-1, 1)]
            for s in _probe(np.concatenate(events) if len(lm) else [], abs(turn)):
                worst = min(worst, _distinct(_seen(cam, route[v], th_in + sgn * s, lm)))
    return int(worst)


def oracle_covered(route, landmarks, cam, k, corners) -> bool:
    return oracle_min_count(route, landmarks, cam, corners) >= k


def test_oracle_sees_landmarks_on_the_edge_line_as_one_bearing():
    """The oracle itself: two landmarks straight ahead are one bearing, one
    more off the line makes two; a landmark on the route is not in view at
    its own position."""
    cam = P.CameraParams(range=2.0, angle_deg=50.0)
    route = np.array([[0.0, 0.0], [1.0, 0.0]])
    assert oracle_min_count(route, [[1.5, 0.0], [2.0, 0.0]], cam, False) == 1
    assert oracle_min_count(route, [[1.5, 0.0], [2.0, 0.0], [1.8, 0.2]], cam, False) == 2
    assert oracle_min_count(route, [[0.5, 0.0]], P.CameraParams(fov="circular"), False) == 0


# ---------------------------------------------------------------------------
# Generators
# ---------------------------------------------------------------------------

GRID = 0.5
cameras = st.builds(
    P.CameraParams,
    range=st.sampled_from([1.0, 1.5, 2.0]),
    angle_deg=st.sampled_from([50.0, 60.0, 90.0, 120.0, 180.0]),
    clearance=st.sampled_from([0.0, 0.05, 0.3]),
    fov=st.sampled_from(["sector", "sector", "sector", "circular"]),
)
node = st.tuples(st.integers(0, 8), st.integers(0, 8)).map(lambda p: (GRID * p[0], GRID * p[1]))
free = st.tuples(st.floats(0, 4, allow_nan=False), st.floats(0, 4, allow_nan=False))


def _no_repeat(points):
    """Consecutive points apart (edges under 1e-12 m are rejected by design; the
    "tiny" routes below draw 1e-10 m edges on purpose)."""
    return all(math.dist(p, q) > 1e-9 for p, q in zip(points[:-1], points[1:]))


@st.composite
def routes(draw):
    """Routes of 2–5 points: on grid nodes (most), free, collinear on a grid
    line or diagonal, back and forth (revisited points), or with a 1e-10 m edge."""
    kind = draw(st.sampled_from(["nodes", "nodes", "free", "collinear", "revisit", "tiny"]))
    if kind in ("nodes", "free"):
        pts = draw(st.lists(node if kind == "nodes" else free, min_size=2, max_size=5).filter(_no_repeat))
    elif kind == "collinear":
        start = draw(node)
        step = draw(st.sampled_from([(1, 0), (0, 1), (1, 1), (1, -1), (2, 1)]))
        ts = draw(st.lists(st.integers(-4, 4), min_size=2, max_size=4).filter(lambda v: all(np.diff(v))))
        pts = [(start[0] + GRID * t * step[0], start[1] + GRID * t * step[1]) for t in ts]
    elif kind == "revisit":
        a, b = draw(st.lists(node, min_size=2, max_size=2, unique=True))
        pts = [a, b, a] + ([b] if draw(st.booleans()) else [])
    else:
        a = draw(node)
        pts = [a, (a[0] + 1e-10, a[1]), (a[0] + 1e-10, a[1] + 1.0)]
    return np.array(pts, float)


def candidates_for(route, cam):
    return P.candidate_grid(route.min(0), route.max(0), GRID, margin=cam.range)


# ---------------------------------------------------------------------------
# The rule: covered exactly when the exact check says so
# ---------------------------------------------------------------------------

def _assert_certificate(res, cam, k, corners):
    truth = oracle_covered(res.route, res.landmarks, cam, k, corners)
    assert res.covered == truth, (res.method, res.uncovered, res.indices)
    rep = res.check(corners=corners)
    assert (rep.min_count >= k and len(rep.start) == 0) == truth
    if res.count:
        assert _core.distance_to_route(res.route, res.landmarks).min() > cam.clearance


def _greedy_property(route, cam, k, corners, reuse, distinct):
    cand = candidates_for(route, cam)
    res = P.place_along_route(route, cand, cam, k=k, corners=corners, reuse=reuse, distinct_bearings=distinct,
                              allow_uncovered=True)
    _assert_certificate(res, cam, k, corners)
    event(f"greedy covered: {res.covered}")


@FAST
@given(routes(), cameras, st.integers(1, 3), st.booleans(), st.booleans(), st.booleans())
def test_greedy_covered_exactly_when_the_brute_force_says_so(route, cam, k, corners, reuse, distinct):
    _greedy_property(route, cam, k, corners, reuse, distinct)


@pytest.mark.slow
@SLOW
@given(routes(), cameras, st.integers(1, 3), st.booleans(), st.booleans(), st.booleans())
def test_greedy_covered_exactly_when_the_brute_force_says_so_many(route, cam, k, corners, reuse, distinct):
    _greedy_property(route, cam, k, corners, reuse, distinct)


def _ilp_property(route, cam, k, corners):
    cand = candidates_for(route, cam)
    res = P.place_optimal(route, cand, cam, k=k, corners=corners, allow_uncovered=True, time_limit=30)
    _assert_certificate(res, cam, k, corners)
    event(f"ilp covered: {res.covered}")
    greedy = P.place_along_route(route, cand, cam, k=k, corners=corners, allow_uncovered=True)
    if greedy.covered and res.optimal:  # the greedy's set is feasible for the ILP
        assert res.count <= greedy.count


@settings(FAST, max_examples=25)
@given(routes(), cameras, st.integers(1, 3), st.booleans())
def test_ilp_covered_exactly_when_the_brute_force_says_so(route, cam, k, corners):
    _ilp_property(route, cam, k, corners)


@pytest.mark.slow
@settings(SLOW, max_examples=400)
@given(routes(), cameras, st.integers(1, 3), st.booleans())
def test_ilp_covered_exactly_when_the_brute_force_says_so_many(route, cam, k, corners):
    _ilp_property(route, cam, k, corners)


@st.composite
def landmark_sets(draw, route, cam, k):
    """Distinct landmarks on grid nodes near the route (on an edge's line,
    on the route itself, anywhere): a random set, or the greedy's placement
    with one landmark removed or a few added, so that both outcomes and the
    border between them are drawn."""
    cand = candidates_for(route, cam)
    idx = set(draw(st.lists(st.integers(0, len(cand) - 1), max_size=12, unique=True)))
    if draw(st.booleans()):
        placed = P.place_along_route(route, cand, cam, k=k, allow_uncovered=True).indices.tolist()
        if placed and draw(st.booleans()):
            placed.pop(draw(st.integers(0, len(placed) - 1)))
            idx = set()
        idx |= set(placed)
    return cand[sorted(idx)]


def _check_property(data, route, cam, k, corners):
    lm = data.draw(landmark_sets(route, cam, k))
    rep = P.check_coverage(route, lm, cam, k=k, corners=corners)
    want = oracle_min_count(route, lm, cam, corners)
    assert rep.min_count == want
    assert (len(rep.start) == 0) == (want >= k)
    event(f"check covered: {want >= k}")


@FAST
@given(st.data(), routes(), cameras, st.integers(1, 3), st.booleans())
def test_check_coverage_min_count_equals_the_brute_force(data, route, cam, k, corners):
    _check_property(data, route, cam, k, corners)


@pytest.mark.slow
@SLOW
@given(st.data(), routes(), cameras, st.integers(1, 3), st.booleans())
def test_check_coverage_min_count_equals_the_brute_force_many(data, route, cam, k, corners):
    _check_property(data, route, cam, k, corners)


# ---------------------------------------------------------------------------
# Malformed input: one clear ValueError naming the value, from all three
# entry points alike, never another exception, a hang or a silent NaN
# ---------------------------------------------------------------------------

GOOD_ROUTE = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.5]])
GOOD_CAND = P.candidate_grid((0, 0), (2, 1.5), 0.5, margin=2.0)

MALFORMED = {
    # name: (route, candidates, k, the message)
    "nan route": ([[0, 0], [np.nan, 1]], GOOD_CAND, 2, r"route\[\(1, 0\)\] = nan is not finite"),
    "inf candidate": (GOOD_ROUTE, [[0, 1], [np.inf, 1]], 2, r"\[\(1, 0\)\] = inf is not finite"),
    "3 columns": ([[0, 0, 0], [1, 1, 1]], GOOD_CAND, 2, r"route must have shape \(N, 2\), got \(2, 3\)"),
    "flat candidates": (GOOD_ROUTE, [0, 1, 2, 3], 2, r"must have shape \(N, 2\), got \(4,\)"),
    "one point": ([[0, 0]], GOOD_CAND, 2, r"route must have at least 2 points, got 1"),
    "empty route": (np.zeros((0, 2)), GOOD_CAND, 2, r"route must have at least 2 points, got 0"),
    "zero-length edge": ([[0, 0], [1, 1], [1, 1]], GOOD_CAND, 2, r"route\[2\] = \(1, 1\) repeats route\[1\]"),
    "duplicate candidates": (GOOD_ROUTE, [[0, 1], [3, 1], [0, 1]], 2, r"\[0\] and \w+\[2\] coincide at \(0, 1\)"),
    "huge route": ([[0, 0], [1e300, 0]], GOOD_CAND, 2, r"route\[1\] = \(1e\+300, 0\) is farther than 1000000 m"),
    "huge candidate": (GOOD_ROUTE, [[0, 1], [-1e308, 1e308]], 2, r"\[1\] = \(-1e\+308, 1e\+308\) is farther than"),
    "k = 0": (GOOD_ROUTE, GOOD_CAND, 0, r"k must be a positive integer, got 0"),
    "k = 2**31": (GOOD_ROUTE, GOOD_CAND, 2**31, r"k = 2147483648 must be <= 1000"),
    "k = 100000": (GOOD_ROUTE, GOOD_CAND, 100_000, r"k = 100000 must be <= 1000"),
    "k float": (GOOD_ROUTE, GOOD_CAND, 2.0, r"k must be a positive integer, got 2.0"),
    "text route": ("abc", GOOD_CAND, 2, r"route must be numeric"),
}
ENTRY_POINTS = {
    "greedy": lambda r, c, k: P.place_along_route(r, c, k=k, allow_uncovered=True),
    "greedy+corners+reuse": lambda r, c, k: P.place_along_route(r, c, k=k, corners=True, reuse=True,
                                                                allow_uncovered=True),
    "ilp": lambda r, c, k: P.place_optimal(r, c, k=k, corners=True, allow_uncovered=True),
    "check": lambda r, c, k: P.check_coverage(r, c, k=k, corners=True),
}


@pytest.mark.parametrize("entry", sorted(ENTRY_POINTS))
@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_input_gives_one_value_error(case, entry):
    route, cand, k, message = MALFORMED[case]
    with np.errstate(over="ignore", invalid="ignore"):
        with pytest.raises(ValueError, match=message):
            ENTRY_POINTS[entry](route, cand, k)


@st.composite
def scenarios(draw):
    """A valid scenario with one field spoilt, or none: a NaN, an inf, a huge
    or duplicated point, a repeated route point, or a bad k."""
    route = draw(routes())
    cam = draw(cameras)
    cand = candidates_for(route, cam)
    k = draw(st.integers(1, 3))
    spoil = draw(st.sampled_from(["none", "nan", "inf", "huge", "dup candidate", "repeat", "k"]))
    if spoil in ("nan", "inf", "huge"):
        bad = {"nan": np.nan, "inf": -np.inf, "huge": draw(st.sampled_from([1e7, 1e150, 1e308]))}[spoil]
        target = route if draw(st.booleans()) else cand
        i = draw(st.integers(0, len(target) - 1))
        target[i, draw(st.integers(0, 1))] = bad
    elif spoil == "dup candidate":
        cand = np.vstack([cand, cand[draw(st.integers(0, len(cand) - 1))]])
    elif spoil == "repeat":
        i = draw(st.integers(0, len(route) - 1))
        route = np.insert(route, i, route[i], axis=0)
    elif spoil == "k":
        k = draw(st.sampled_from([0, -3, 1001, 2**31, 2**63, 1.5, True, "2", None]))
    return route, cand, cam, k, spoil


def _fuzz(scenario):
    route, cand, cam, k, spoil = scenario
    calls = (lambda: P.place_along_route(route, cand, cam, k=k, corners=True, allow_uncovered=True),
             lambda: P.check_coverage(route, cand, cam, k=k, corners=True))
    for call in calls:
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                out = call()
        except ValueError as exc:
            assert spoil != "none", exc
            assert "\n" not in str(exc)
            event(f"{spoil}: ValueError")
            continue
        assert spoil == "none", f"{spoil} was accepted"
        event("valid: result")
        if hasattr(out, "covered"):
            assert np.isfinite(out.landmarks).all()


@FAST
@given(scenarios())
def test_fuzz_every_call_returns_or_raises_one_value_error(scenario):
    _fuzz(scenario)


@pytest.mark.slow
@SLOW
@given(scenarios())
def test_fuzz_every_call_returns_or_raises_one_value_error_many(scenario):
    _fuzz(scenario)


any_float = st.floats(allow_nan=True, allow_infinity=True)
any_point = st.tuples(any_float, any_float)


@pytest.mark.parametrize("a, b, match", [
    ((np.nan, 0.0), (1.0, 0.0), r"EdgeFrame: a = \(nan, 0\) is not finite"),
    ((0.0, 0.0), (1.0, np.inf), r"EdgeFrame: b = \(1, inf\) is not finite"),
    ((-1e300, 0.0), (1e300, 0.0), r"EdgeFrame: the edge \(-1e\+300, 0\) -> \(1e\+300, 0\) is too long"),
])
def test_edge_frame_names_bad_ends(a, b, match):
    with pytest.raises(ValueError, match=match):
        _core.EdgeFrame(a, b)


def test_edge_frame_names_a_point_it_cannot_map():
    f = _core.EdgeFrame((0.0, 0.0), (1.0, 1.0))
    with pytest.raises(ValueError, match=r"EdgeFrame\.to_local: \(nan, 0\) is not finite or too far"):
        f.to_local((np.nan, 0.0))
    with pytest.raises(ValueError, match=r"EdgeFrame\.to_world: \(1\.5e\+308, 1\.5e\+308\) is not finite or too far"):
        f.to_world((1.5e308, 1.5e308))


@settings(max_examples=300, deadline=None)
@given(any_point, any_point, any_point)
def test_edge_frame_refuses_its_input_or_answers_finite(a, b, p):
    try:
        f = _core.EdgeFrame(a, b)
    except ValueError as e:
        assert str(e).startswith("EdgeFrame: ")
        return
    assert np.isfinite([f.length, f.heading, *f.origin]).all()
    for name in ("to_local", "to_world"):
        try:
            out = getattr(f, name)(p)
        except ValueError as e:
            assert str(e).startswith(f"EdgeFrame.{name}: ")
        else:
            assert np.isfinite(out).all()

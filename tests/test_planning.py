"""RAw-RRT* (SafeNav eqs. 15-19, Algorithm 3) on OMPL: safety, determinism,
risk awareness, cost bookkeeping, a grid-search reference and bad input."""

from __future__ import annotations

import time

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from safenav import RiskZones, metrics
from safenav import planning as P

# A 40 x 20 field: a disc sits above the straight line, so going below it is
# shorter, but the central (safe) path runs above it.
CIRCLES = [(20.0, 11.0, 4.0)]
POLYGONS = [np.array([(8.0, 2.0), (11.0, 2.0), (11.0, 5.0), (8.0, 5.0)])]
CENTRAL = np.array([(2.0, 10.0), (10.0, 17.5), (30.0, 17.5), (38.0, 10.0)])
START, GOAL = (2.0, 10.0), (38.0, 10.0)
FAST = dict(max_iterations=600, range=4.0, resolution=0.1)


def make_problem(**kw):
    m = P.make_map(lower=(0, 0), upper=(40, 20), circles=CIRCLES, polygons=POLYGONS)
    args = dict(map=m, start=START, goal=GOAL, central_path=CENTRAL, zones=RiskZones(half_width=2.0))
    args.update(kw)
    return P.PlanningProblem(**args)


def point_in_polygon(pts, poly):
    x, y = pts[:, 0], pts[:, 1]
    inside = np.zeros(len(pts), bool)
    n = len(poly)
    for i in range(n):
        (xi, yi), (xj, yj) = poly[i], poly[i - 1]
        cond = (yi > y) != (yj > y)
        xc = (xj - xi) * (y - yi) / np.where(yj == yi, 1.0, yj - yi) + xi
        inside ^= cond & (x < xc)
    return inside


def dense(path, step=0.005):
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out.append(a + np.linspace(0, 1, n + 1)[1:, None] * (b - a))
    return np.vstack(out)


def assert_collision_free(path, circles=CIRCLES, polygons=POLYGONS, upper=(40, 20)):
    pts = dense(path)
    assert np.all(pts >= 0) and np.all(pts <= np.asarray(upper))
    for cx, cy, r in circles:
        assert np.min(np.hypot(pts[:, 0] - cx, pts[:, 1] - cy)) > r
    for poly in polygons:
        assert not point_in_polygon(pts, np.asarray(poly)).any()


def risk_integral(path, central, zones, step=0.001):
    """Dense integral of WRS (eq. 18) along the path, with safenav.metrics.wrs."""
    total = 0.0
    for a, b in zip(path[:-1], path[1:]):
        L = np.linalg.norm(b - a)
        n = max(1, int(np.ceil(L / step)))
        pts = a + np.linspace(0, 1, n + 1)[:, None] * (b - a)
        w = metrics.wrs(pts, central, zones)
        total += np.sum(0.5 * (w[1:] + w[:-1])) * (L / n)
    return total


@pytest.fixture(scope="module")
def problem():
    return make_problem()


@pytest.mark.parametrize("beta", [0.0, 1.0])
@pytest.mark.parametrize("smooth", [False, True])
def test_paths_are_collision_free_under_dense_sampling(problem, beta, smooth):
    for seed in (0, 1, 2):
        r = P.plan(problem, beta=beta, seed=seed, smooth=smooth, **FAST)
        assert r.status == P.PlanStatus.EXACT and r.success
        np.testing.assert_allclose(r.path[0], START)
        assert np.linalg.norm(r.path[-1] - np.asarray(GOAL)) <= 1e-6
        assert_collision_free(r.path)
        assert P.path_is_free(problem.map, r.path)


def test_same_seed_same_budget_gives_identical_paths(problem):
    a = P.plan(problem, beta=1.0, seed=7, **FAST)
    P.plan(problem, beta=1.0, seed=8, **FAST)  # another run in between must not matter
    b = P.plan(problem, beta=1.0, seed=7, **FAST)
    assert np.array_equal(a.path, b.path)
    assert a.cost.total == b.cost.total and a.iterations == b.iterations == FAST["max_iterations"]
    np.testing.assert_array_equal(a.cost_history[:, [0, 2]], b.cost_history[:, [0, 2]])
    c = P.plan(problem, beta=1.0, seed=9, **FAST)
    assert not np.array_equal(a.path, c.path)


def test_risk_term_lowers_risk(problem):
    for seed in (0, 1, 2):
        plain = P.plan(problem, beta=0.0, seed=seed, **FAST)
        raw = P.plan(problem, beta=1.0, seed=seed, **FAST)
        assert raw.cost.risk < plain.cost.risk
        assert raw.cost.length >= plain.cost.length - 1e-9
        # plain RRT* goes below the disc, RAw-RRT* above it along the central path
        assert plain.path[:, 1].min() < 7.0 and raw.path[:, 1].max() > 15.0


def test_cost_never_rises_with_budget(problem):
    costs = [P.plan(problem, beta=1.0, seed=3, max_iterations=n, range=4.0).cost.total for n in (150, 300, 600, 1200)]
    assert all(b <= a + 1e-12 for a, b in zip(costs, costs[1:])), costs
    r = P.plan(problem, beta=1.0, seed=3, max_iterations=1200, range=4.0)
    assert np.all(np.diff(r.cost_history[:, 2]) <= 0)
    assert np.all(np.diff(r.cost_history[:, 0]) > 0)


def test_unreachable_goal_reports_no_path_within_budget():
    box = [np.array([(28, 4), (36, 4), (36, 5), (28, 5)]), np.array([(28, 15), (36, 15), (36, 16), (28, 16)]),
           np.array([(28, 4), (29, 4), (29, 16), (28, 16)]), np.array([(35, 4), (36, 4), (36, 16), (35, 16)])]
    m = P.make_map(upper=(40, 20), polygons=box)
    prob = P.PlanningProblem(map=m, start=(2, 10), goal=(32, 10), central_path=CENTRAL)
    t = time.perf_counter()
    r = P.plan(prob, max_iterations=500, range=4.0)
    assert time.perf_counter() - t < 10
    assert r.status == P.PlanStatus.NO_PATH and not r.success
    assert r.path.shape == (0, 2) and r.iterations == 500 and r.first_solution_iteration == -1
    approx = P.plan(prob, max_iterations=500, range=4.0, allow_approximate=True)
    assert approx.status == P.PlanStatus.APPROXIMATE and not approx.success and len(approx.path) >= 2
    assert_collision_free(approx.path, circles=[], polygons=box)
    # a time budget also ends the run
    t = time.perf_counter()
    r = P.plan(prob, max_iterations=10**6, max_time=0.3, range=4.0)  # the most iterations a plan may ask for
    assert r.status == P.PlanStatus.NO_PATH and time.perf_counter() - t < 5


@pytest.mark.parametrize("alpha,beta", [(1.0, 0.0), (1.0, 1.0), (0.5, 3.0)])
def test_reported_cost_matches_numpy_recomputation(problem, alpha, beta):
    r = P.plan(problem, alpha=alpha, beta=beta, seed=4, **FAST)
    length = float(np.sum(np.linalg.norm(np.diff(r.path, axis=0), axis=1)))
    risk = risk_integral(r.path, CENTRAL, problem.zones)
    assert r.cost.length == pytest.approx(length, rel=1e-12)
    # WRS is discontinuous at zone borders: the 0.1 m trapezoid rule agrees with a 1 mm one to < 1 %.
    assert r.cost.risk == pytest.approx(risk, rel=1e-2)
    assert r.cost.total == pytest.approx(alpha * length + beta * risk, rel=1e-2)
    assert r.cost.total == pytest.approx(alpha * r.cost.length + beta * r.cost.risk, rel=1e-12)
    # OMPL's own objective value of the returned solution is the same number.
    assert r.cost_history[-1, 2] == pytest.approx(r.cost.total, rel=1e-9)


def grid_optimum(problem, alpha, beta, h=0.5):
    """Dijkstra on a 16-connected grid with cost alpha*length + beta*integral(WRS)."""
    m = problem.map
    xs = np.arange(0, 40 + 1e-9, h)
    ys = np.arange(0, 20 + 1e-9, h)
    nx, ny = len(xs), len(ys)
    pts = np.array([(x, y) for x in xs for y in ys])
    free = np.array([P.point_is_free(m, p) for p in pts])
    moves = [(1, 0), (0, 1), (1, 1), (1, -1), (2, 1), (1, 2), (2, -1), (1, -2)]
    rows, cols, w = [], [], []
    for i in range(nx):
        for j in range(ny):
            a = i * ny + j
            if not free[a]:
                continue
            for di, dj in moves:
                ii, jj = i + di, j + dj
                if not (0 <= ii < nx and 0 <= jj < ny):
                    continue
                b = ii * ny + jj
                if not free[b] or not P.segment_is_free(m, pts[a], pts[b]):
                    continue
                c = P.path_cost(np.array([pts[a], pts[b]]), problem, alpha=alpha, beta=beta).total
                rows += [a, b]
                cols += [b, a]
                w += [c, c]
    g = csr_matrix((w, (rows, cols)), shape=(nx * ny, nx * ny))
    s = int(round(problem.start[0] / h)) * ny + int(round(problem.start[1] / h))
    t = int(round(problem.goal[0] / h)) * ny + int(round(problem.goal[1] / h))
    return float(dijkstra(g, indices=s)[t])


@pytest.mark.parametrize("beta", [0.0, 1.0])
def test_cost_close_to_grid_optimum(problem, beta):
    ref = grid_optimum(problem, 1.0, beta)
    r = P.plan(problem, beta=beta, seed=0, max_iterations=2000, range=4.0)
    assert r.success
    assert r.cost.total <= 1.3 * ref, (r.cost.total, ref)


def test_smoothing_never_costs_more(problem):
    for beta in (0.0, 1.0):
        raw = P.plan(problem, beta=beta, seed=5, **FAST)
        sm = P.plan(problem, beta=beta, seed=5, smooth=True, **FAST)
        assert sm.cost.total <= raw.cost.total + 1e-9
        assert_collision_free(sm.path)


def test_stay_in_corridor(problem):
    # Corridor wide enough to pass the disc above it.
    prob = make_problem(zones=RiskZones(half_width=3.0))
    r = P.plan(prob, seed=0, stay_in_corridor=True, **FAST)
    assert r.success
    assert metrics.distance_to_path(dense(r.path, 0.01), CENTRAL).max() <= 3.0 + 1e-9


def test_segment_is_free_and_replan(problem):
    m = problem.map
    assert not P.segment_is_free(m, (14, 11), (26, 11))   # through the disc
    assert not P.segment_is_free(m, (7, 1), (12, 6))      # clips the square's corner
    assert P.segment_is_free(m, (2, 18), (38, 18))
    assert not P.segment_is_free(m, (2, 18), (41, 18))    # leaves the field
    assert P.point_ahead(CENTRAL, (10, 17.5), 5.0) == pytest.approx([15.0, 17.5])
    # Obstacle on the central path ahead: the goal slides past it.
    blocked = P.make_map(upper=(40, 20), circles=CIRCLES + [(20.0, 17.5, 1.5)], polygons=POLYGONS)
    prob = make_problem(map=blocked)
    pos = np.array([14.0, 17.5])
    assert not P.segment_is_free(blocked, pos, P.point_ahead(CENTRAL, pos, 6.0))
    r = P.replan(prob, pos, lookahead=6.0, seed=1, **FAST)
    assert r.success
    np.testing.assert_allclose(r.path[0], pos)
    assert metrics.distance_to_path(r.path[-1:], CENTRAL)[0] < 1e-9
    assert r.path[-1, 0] >= 20.0
    assert_collision_free(r.path, circles=CIRCLES + [(20.0, 17.5, 1.5)])
    r2 = P.replan(prob, pos, goal=(30, 17.5), seed=1, **FAST)
    assert r2.success and np.allclose(r2.path[-1], (30, 17.5))


@pytest.mark.parametrize("kwargs,match", [
    (dict(alpha=-1.0), "alpha"),
    (dict(beta=-0.5), "beta"),
    (dict(alpha=0.0, beta=0.0), "alpha and beta"),
    (dict(alpha=float("nan")), "alpha"),
    (dict(max_iterations=0), "max_iterations"),
    (dict(resolution=0.0), "resolution"),
    (dict(goal_bias=1.5), "goal_bias"),
    (dict(range=-1.0), "range"),
    (dict(max_time=-1.0), "max_time"),
])
def test_bad_settings(problem, kwargs, match):
    with pytest.raises(ValueError, match=match):
        P.plan(problem, **kwargs)


def test_bad_problem(problem):
    with pytest.raises(ValueError, match="start"):
        P.plan(make_problem(start=(20, 11)), **FAST)            # inside the disc
    with pytest.raises(ValueError, match="goal"):
        P.plan(make_problem(goal=(50, 10)), **FAST)             # outside the field
    with pytest.raises(ValueError, match="start"):
        P.plan(make_problem(start=(9, 3)), **FAST)              # inside the square
    with pytest.raises(ValueError, match="not finite"):
        P.make_map(circles=[(1, float("nan"), 1)])
    with pytest.raises(ValueError, match="radius"):
        P.make_map(circles=[(1, 1, 0)])
    with pytest.raises(ValueError, match="polygon 0"):
        P.make_map(polygons=[np.zeros((0, 2))])
    with pytest.raises(ValueError, match="polygon 0"):
        P.make_map(polygons=[[(0, 0), (1, 1)]])
    with pytest.raises(ValueError, match="upper"):
        P.make_map(lower=(5, 5), upper=(1, 10))
    with pytest.raises(ValueError, match="corridor"):
        P.plan(make_problem(start=(2, 2)), stay_in_corridor=True, **FAST)
    with pytest.raises(ValueError, match="lookahead"):
        P.replan(problem, (5, 12), lookahead=-1.0)
    with pytest.raises(ValueError, match="exactly one"):
        P.replan(problem, (5, 12))


def test_corridor_bias_finds_cheaper_paths_sooner_on_the_default_scenario():
    """Sampling inside the corridor (our extension; 0 = the paper's uniform RRT*)
    reaches a lower α·length + β·∫WRS at the same budget, stays deterministic
    and collision-free."""
    import safenav

    sc = safenav.default_scenario()
    path = sc.path_polyline("P1")
    prob = P.PlanningProblem(map=P.map_from_world(sc.world), start=path[0], goal=path[-1], central_path=path,
                             zones=sc.risk_zones())
    common = dict(alpha=1.0, beta=1.0, max_iterations=2000, range=10.0, resolution=0.5)
    plain = [P.plan(prob, seed=s, **common).cost.total for s in range(3)]
    biased_runs = [P.plan(prob, seed=s, corridor_bias=0.5, **common) for s in range(3)]
    assert all(r.success for r in biased_runs)
    assert np.median([r.cost.total for r in biased_runs]) < 0.9 * np.median(plain)
    again = P.plan(prob, seed=0, corridor_bias=0.5, **common)
    np.testing.assert_array_equal(again.path, biased_runs[0].path)
    for r in biased_runs:
        assert P.path_is_free(prob.map, r.path)
    with pytest.raises(ValueError, match=r"corridor_bias must be in \[0, 1\], got 1.5"):
        P.plan(prob, corridor_bias=1.5, **common)

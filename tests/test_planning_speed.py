"""RAw-RRT*'s speed-ups: the fast risk evaluation is Corridor's WRS bit for
bit; informed sampling's lower bound is admissible (checked against exact
grid shortest paths with the planner's own edge cost) and never makes a plan
worse within the same fixed-seed budget."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from safenav import Corridor, RiskZones
from safenav import planning as P

CENTRAL = np.array([(2.0, 10.0), (10.0, 16.0), (30.0, 16.0), (38.0, 10.0)])
ZONES = RiskZones(half_width=6.0)


def make_problem(**kw):
    m = P.make_map(lower=(0, 0), upper=(40, 20), circles=[(20.0, 12.0, 3.0)])
    args = dict(map=m, start=CENTRAL[0], goal=CENTRAL[-1], central_path=CENTRAL, zones=ZONES)
    args.update(kw)
    return P.PlanningProblem(**args)


def trapezoid_risk(path, corridor, step):
    """path_cost's risk: the trapezoid rule on ceil(length / step) equal sub-steps per edge."""
    total = 0.0
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(np.ceil(np.hypot(*(b - a)) / step)))
        pts = [a + (j / n) * (b - a) for j in range(n)] + [b]
        w = corridor.wrs(np.array(pts))
        for j in range(n):
            d = pts[j + 1] - pts[j]
            total += 0.5 * (w[j] + w[j + 1]) * np.sqrt(d[0] * d[0] + d[1] * d[1])
    return total


def test_risk_term_equals_corridor_wrs_bit_for_bit():
    rng = np.random.default_rng(3)
    prob = make_problem()
    corridor = Corridor(CENTRAL, ZONES)
    # Points on the path, at its vertices, inside every zone and far outside the buffer.
    path = np.vstack([CENTRAL, rng.uniform((-5, -5), (45, 25), (30, 2)), CENTRAL[1] + (0, 3.0)])
    for step in (0.1, 0.37):
        cost = P.path_cost(path, prob, resolution=step)
        assert cost.risk == trapezoid_risk(path, corridor, step)


def grid_costs(prob, settings, h=1.0):
    """Exact shortest-path costs from start and from goal on a 16-connected
    grid whose edges cost what the planner charges (path_cost)."""
    xs, ys = np.arange(0, 40 + 1e-9, h), np.arange(0, 20 + 1e-9, h)
    ny = len(ys)
    pts = np.array([(x, y) for x in xs for y in ys])
    rows, cols, w = [], [], []
    for a, p in enumerate(pts):
        for di, dj in [(1, 0), (0, 1), (1, 1), (1, -1), (2, 1), (1, 2), (2, -1), (1, -2)]:
            q = p + h * np.array([di, dj])
            if not (0 <= q[0] <= 40 and 0 <= q[1] <= 20) or not P.segment_is_free(prob.map, p, q):
                continue
            b = int(round(q[0] / h)) * ny + int(round(q[1] / h))
            c = P.path_cost(np.array([p, q]), prob, settings).total
            rows += [a, b]
            cols += [b, a]
            w += [c, c]
    g = csr_matrix((w, (rows, cols)), shape=(len(pts), len(pts)))
    index = [int(round(e[0] / h)) * ny + int(round(e[1] / h)) for e in (prob.start, prob.goal)]
    return pts, dijkstra(g, indices=index)


@pytest.mark.parametrize("alpha,beta", [(1.0, 1.0), (1.0, 5.0), (0.5, 2.0), (1.0, 0.0)])
def test_lower_bound_never_exceeds_the_grid_cost_through_a_point(alpha, beta):
    prob = make_problem()
    settings = P.PlannerSettings(alpha=alpha, beta=beta, resolution=0.1)
    pts, (from_start, to_goal) = grid_costs(prob, settings)
    through = from_start + to_goal
    reach = np.isfinite(through)
    bound = P.cost_lower_bound(pts, prob, settings)
    assert np.all(bound[reach] <= through[reach] * (1 + 1e-12)), np.max(bound[reach] - through[reach])
    # Nowhere below the length part alone, and, with the risk term, strictly above it off the path.
    straight = alpha * (np.linalg.norm(pts - prob.start, axis=1) + np.linalg.norm(pts - prob.goal, axis=1))
    assert np.all(bound >= straight - alpha * settings.goal_tolerance - 1e-9)
    if beta > 0:
        far = Corridor(CENTRAL, ZONES).distance(pts) > 3.0
        assert np.all(bound[far] > straight[far] + 1.0)
    # The optimum itself lies on the best path: its bound is below it, and close at the start.
    assert bound[np.argmin(through)] <= np.min(through[reach])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_informed_sampling_is_no_worse_with_the_same_budget(seed):
    prob = make_problem()
    kw = dict(beta=1.0, seed=seed, max_iterations=1500, range=4.0, resolution=0.2)
    plain = P.plan(prob, **kw)
    informed = P.plan(prob, informed_sampling=True, **kw)
    assert plain.success and informed.success
    assert informed.cost.total <= plain.cost.total
    again = P.plan(prob, informed_sampling=True, **kw)
    np.testing.assert_array_equal(informed.path, again.path)  # seeded: same plan every time
    assert P.path_is_free(prob.map, informed.path)


def test_informed_sampling_without_risk_term_and_with_corridor_bias():
    prob = make_problem()
    for extra in (dict(beta=0.0), dict(beta=1.0, corridor_bias=0.5), dict(beta=1.0, hazard_weight=2.0)):
        r = P.plan(prob, informed_sampling=True, seed=7, max_iterations=800, range=4.0, resolution=0.2, **extra)
        assert r.success and P.path_is_free(prob.map, r.path)
        assert r.cost.total >= P.cost_lower_bound(prob.goal[None], prob, beta=extra["beta"])[0]


def test_informed_sampling_needs_alpha():
    with pytest.raises(ValueError, match="informed_sampling needs alpha > 0"):
        P.PlannerSettings(alpha=0.0, beta=1.0, informed_sampling=True)
    with pytest.raises(ValueError, match="not finite"):
        P.cost_lower_bound([[np.nan, 1.0]], make_problem())

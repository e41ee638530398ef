"""Benchmark RAw-RRT* (OMPL RRTstar + alpha*length + beta*integral(WRS)) on the
built-in default scenario (the paper's 200 x 200 m real-imitated world).

For each path type (P1-P3: first to last cluster centroid, the ground-truth
polyline as the central safe path) it prints medians over seeds of:
  * time to the first solution, time to reach 5 % above the grid optimum,
    final cost / grid optimum (grid: 16-connected Dijkstra, 1 m, same cost);
  * plain RRT* (beta = 0) beside RAw-RRT* with length and risk, and
    RAw-RRT* with half of its samples drawn inside the corridor ("RAw+bias",
    corridor_bias = 0.5, our extension);
  * speed ratio against a pure-Python RRT* (PythonRobotics-style) with the
    same iteration budget and the same cost.

Obstacles: the scenario's 25 (its 25 hazards carry risk, not collision, and
enter here only through the corridor risk term).  Run:
    python bench/bench_planning.py [--iterations 30000] [--seeds 3]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

import safenav
from safenav import metrics
from safenav import planning as P

SCENARIO = safenav.default_scenario()
WORLD = SCENARIO.world
FIELD = float(WORLD.field.width)    # 200 m square field
ZONES = SCENARIO.risk_zones()       # half-width 8 m, four 2 m zones per side
RES = 0.5                           # cost-integration step [m]
RANGE = 10.0


def default_problems():
    """The built-in default scenario (SafeNav V-A real-imitated world): one
    problem per path type, from the first to the last cluster centroid, with
    the ground-truth polyline as the central safe path."""
    sc = safenav.default_scenario()
    m = P.map_from_world(sc.world)
    probs = {}
    for pt in sc.path_types:
        path = sc.path_polyline(pt.name)
        probs[pt.name] = P.PlanningProblem(map=m, start=path[0], goal=path[-1], central_path=path, zones=ZONES)
    return sc, probs


def inside_any(m, pts):
    """Points inside an obstacle (boundary included), via the world model."""
    return WORLD.obstacle_mask(pts)


def edge_cost(problem, a, b, alpha, beta, path):
    """Cost of straight edges a[k]-b[k] (trapezoid rule on RES steps, as the planner)."""
    L = np.linalg.norm(b - a, axis=1)
    n = int(np.ceil(L.max() / RES))
    t = np.linspace(0, 1, n + 1)
    pts = a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]
    w = metrics.wrs(pts.reshape(-1, 2), path, ZONES).reshape(len(a), n + 1)
    risk = np.trapezoid(w, t, axis=1) * L
    hit = inside_any(problem.map, pts.reshape(-1, 2)).reshape(len(a), n + 1).any(axis=1)
    return alpha * L + beta * risk, hit


def grid_optimum(problem, alpha, beta, h=1.0):
    xs = np.arange(0, FIELD + 1e-9, h)
    nx = len(xs)
    gx, gy = np.meshgrid(xs, xs, indexing="ij")
    pts = np.c_[gx.ravel(), gy.ravel()]
    idx = np.arange(nx * nx).reshape(nx, nx)
    rows, cols, ws = [], [], []
    for di, dj in [(1, 0), (0, 1), (1, 1), (1, -1), (2, 1), (1, 2), (2, -1), (1, -2)]:
        i0, i1 = max(0, -di), nx - max(0, di)
        j0, j1 = max(0, -dj), nx - max(0, dj)
        a = idx[i0:i1, j0:j1].ravel()
        b = idx[i0 + di:i1 + di, j0 + dj:j1 + dj].ravel()
        c, hit = edge_cost(problem, pts[a], pts[b], alpha, beta, problem.central_path)
        ok = ~hit
        rows += [a[ok], b[ok]]
        cols += [b[ok], a[ok]]
        ws += [c[ok], c[ok]]
    g = csr_matrix((np.concatenate(ws), (np.concatenate(rows), np.concatenate(cols))), shape=(nx * nx,) * 2)
    s = int(round(problem.start[0] / h)) * nx + int(round(problem.start[1] / h))
    t = int(round(problem.goal[0] / h)) * nx + int(round(problem.goal[1] / h))
    # start and goal snap to the nearest grid node (within 0.71 m)
    return float(dijkstra(g, indices=s)[t])


# ------------------------------------------------------------- pure-Python RRT*
def python_rrt_star(problem, alpha, beta, iterations, seed, goal_bias=0.05, expand=RANGE):
    """PythonRobotics-style RRT* with the same cost; nodes in Python lists."""
    rng = np.random.default_rng(seed)
    m, path = problem.map, problem.central_path
    start, goal = np.asarray(problem.start), np.asarray(problem.goal)

    def cost(a, b):
        c, hit = edge_cost(problem, a[None], b[None], alpha, beta, path)
        return float(c[0]), bool(hit[0]) or not P.segment_is_free(m, a, b)

    nodes, parent, cst = [start], [-1], [0.0]
    best = math.inf
    goal_nodes = []
    for it in range(iterations):
        rnd = goal if rng.random() < goal_bias else rng.uniform(0, FIELD, 2)
        arr = np.array(nodes)
        d = np.linalg.norm(arr - rnd, axis=1)
        k = int(np.argmin(d))
        step = rnd - nodes[k]
        dist = np.linalg.norm(step)
        new = rnd if dist <= expand else nodes[k] + step / dist * expand
        if inside_any(m, new[None])[0]:
            continue
        r = min(expand, 50.0 * math.sqrt(math.log(len(nodes) + 1) / (len(nodes) + 1)))
        near = np.flatnonzero(np.linalg.norm(arr - new, axis=1) <= max(r, 1e-9))
        if k not in near:
            near = np.append(near, k)
        best_p, best_c = -1, math.inf
        edge = {}
        for j in near:
            c, hit = cost(nodes[j], new)
            if not hit:
                edge[j] = c
                if cst[j] + c < best_c:
                    best_p, best_c = j, cst[j] + c
        if best_p < 0:
            continue
        nodes.append(new)
        parent.append(best_p)
        cst.append(best_c)
        n_new = len(nodes) - 1
        for j in near:  # rewire (symmetric edge costs)
            if j in edge and best_c + edge[j] < cst[j]:
                parent[j], cst[j] = n_new, best_c + edge[j]
        if np.linalg.norm(new - goal) < 1e-9:
            goal_nodes.append(n_new)
    if goal_nodes:
        best = min(cst[g] for g in goal_nodes)
    return best


def median(x):
    x = [v for v in x if v is not None and np.isfinite(v)]
    return float(np.median(x)) if x else float("nan")


PLANNERS = (  # name, beta, extra settings; RRT* is the peer every ratio is taken against
    ("RRT*", 0.0, {}),
    ("RAw-RRT*", 1.0, {}),
    ("RAw+bias", 1.0, {"corridor_bias": 0.5}),
    ("RAw+informed", 1.0, {"informed_sampling": True}),
    ("RAw+inf+bias", 1.0, {"informed_sampling": True, "corridor_bias": 0.5}),
)


def time_to_5(prob, beta, ref, seeds, iterations, budget, extra):
    """Per seed: (time [s] of the first solution within 5 % of ``ref``, or None;
    first-solution time; final cost / ref; length; risk; planning time)."""
    rows = []
    for s in range(seeds):
        r = P.plan(prob, alpha=1.0, beta=beta, seed=s, max_iterations=iterations, max_time=budget, range=RANGE,
                   resolution=RES, **extra)
        if not r.success:
            rows.append((None, None, None, None, None, r.planning_time))
            continue
        h = r.cost_history
        within = np.flatnonzero(h[:, 2] <= 1.05 * ref)
        rows.append((h[within[0], 1] if len(within) else None, r.first_solution_time, r.cost.total / ref,
                     r.cost.length, r.cost.risk, r.planning_time))
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--iterations", type=int, default=30000)
    ap.add_argument("--budget", type=float, default=2.0, help="wall-clock budget per plan [s]")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--python-iterations", type=int, default=500, help="0 skips the pure-Python comparison")
    args = ap.parse_args()
    _, named = default_problems()
    probs = list(named.values())
    m = probs[0].map
    print(f"default scenario: field 200x200 m, {len(m.circles)} discs + {len(m.polygons)} polygons, paths "
          f"{', '.join(named)}, corridor half-width "
          f"{ZONES.half_width} m, resolution {RES} m, range {RANGE} m, at most {args.iterations} iterations "
          f"or {args.budget} s, {args.seeds} seeds (medians)\n")
    print("t_5%: time to a path within 5 % of the grid optimum (same cost); ratio: to plain RRT*'s t_5%\n")
    hdr = (f"{'path':4} {'planner':12} {'t_5%[s]':>8} {'ratio':>6} {'reached':>7} {'t_first[s]':>10} "
           f"{'cost/grid':>9} {'length':>8} {'risk':>8} {'plan[s]':>8}")
    print(hdr)
    for pi, prob in enumerate(probs, 1):
        refs, peer = {}, None
        for name, beta, extra in PLANNERS:
            ref = refs[beta] = refs[beta] if beta in refs else grid_optimum(prob, 1.0, beta)
            rows = time_to_5(prob, beta, ref, args.seeds, args.iterations, args.budget, extra)
            t5 = [r[0] for r in rows]
            reached = sum(v is not None for v in t5)
            # the median over all seeds; a seed that never reached 5 % counts as +inf
            med = float(np.median([v if v is not None else math.inf for v in t5]))
            peer = med if peer is None else peer
            col = [median([r[k] for r in rows]) for k in range(1, 6)]
            print(f"P{pi:<3} {name:12} {med:8.3f} {med / peer:6.1f} {reached:>4}/{len(t5):<2} {col[0]:10.3f} "
                  f"{col[1]:9.3f} {col[2]:8.1f} {col[3]:8.1f} {col[4]:8.2f}   (grid optimum {ref:.1f})")
    if args.python_iterations <= 0:
        return
    print(f"\nspeed vs pure-Python RRT* ({args.python_iterations} iterations, beta = 1, same cost):")
    ratios = []
    for pi, prob in enumerate(probs, 1):
        t = time.perf_counter()
        c_py = python_rrt_star(prob, 1.0, 1.0, args.python_iterations, seed=0)
        t_py = time.perf_counter() - t
        t = time.perf_counter()
        r = P.plan(prob, beta=1.0, seed=0, max_iterations=args.python_iterations, range=RANGE, resolution=RES)
        t_cpp = time.perf_counter() - t
        ratios.append(t_py / t_cpp)
        print(f"P{pi}: python {t_py:7.2f} s (cost {c_py:8.1f})   OMPL {t_cpp:6.3f} s (cost "
              f"{r.cost.total if r.success else float('nan'):8.1f})   ratio {t_py / t_cpp:6.1f}x")
    print(f"median speed ratio {np.median(ratios):.1f}x")


if __name__ == "__main__":
    main()

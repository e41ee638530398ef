"""Landmark placement for guaranteed observability (the landmark placement paper).

A vehicle with a forward camera (range ``R``, viewing angle ``α``) follows a
route; a bearing-only filter is observable only while at least two landmarks
are in view.  Given candidate landmark locations, place the fewest landmarks
so that every point of the route sees at least ``k`` (the paper: 2), no
landmark is within ``p`` of the route and no two chosen landmarks lie on one
bearing from the camera.

* :func:`place_along_route` — the paper's algorithm (section II): per edge
  the rigid transform to ``(0,0) → (d,0)``, Lemma 2's visibility interval
  ``[t_s, t_d]`` of every candidate (Corollary 1 for a circular field of
  view, typo fixed), the greedy k-interval cover (Algorithm 1, optimal per
  edge by Proposition 1), then the union over edges.  Options: ``corners``
  (cover the in-place turn at every vertex, the paper's future work),
  ``reuse`` (an edge counts landmarks placed for earlier edges).
* :func:`place_optimal` — the global optimum over the whole route: an integer
  program (``scipy.optimize.milp``, HiGHS) with one coverage row per interval
  endpoint, alignment point and gap between them, which is exact because the
  number of landmarks in view is constant between those points.
* :func:`place_through_targets` — a route through targets first (open tour
  from the first to the last target, 2-opt + Or-opt; see :func:`plan_tour`).
* :func:`place_along_path` — the same for a SafeNav safe path (a polyline,
  e.g. :meth:`safenav.World.path_polyline` or a planner's path).
* :func:`simulate` — the paper's section III: a ground robot at 0.2 m/s with
  a heading controller, bearings to the landmarks in view, and the extended
  information filter (:class:`safenav.InformationFilter`).
* :func:`table_one` — the paper's Table I on fresh random instances.

The heavy lifting is in the C++ core (``safenav._core``: ``place_landmarks``,
``edge_visibility``, ``alignments``, ``check_coverage``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from . import _core
from .validation import as_array, as_positive_int, as_seed
from .results import save_figure

__all__ = [
    "CameraParams", "PlacementResult", "SimulationResult", "PAPER_TABLE_ONE",
    "candidate_grid", "plan_tour", "tour_length", "place_along_route", "place_through_targets",
    "place_along_path", "place_optimal", "check_coverage", "simulate", "random_instance",
    "table_one", "corner_gap_demo", "plot_placement", "plot_simulation", "plot_corner_gap", "paper_figures",
]

#: The paper's Table I: (targets, landmarks) for its nine random instances.
PAPER_TABLE_ONE = ((5, 21), (5, 22), (5, 12), (6, 24), (6, 22), (7, 20), (7, 31), (7, 21), (7, 12))
#: Table I setup: a 4 × 8 area, candidates on a 0.5 grid.
PAPER_AREA = (4.0, 8.0)
PAPER_SPACING = 0.5

_EPS = 1e-9          # [m] or [rad], the same rounding slack as the C++ core
_BEARING_TOL = 1e-9  # [rad], bearings closer than this are one bearing


# ---------------------------------------------------------------------------
# Camera and inputs
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class CameraParams:
    """The bearing sensor and the collision-avoidance distance.

    ``range`` is the paper's R [m], ``angle_deg`` its viewing angle α [deg]
    (full angle, in (0°, 180°]), ``clearance`` its p [m] (landmarks must be
    farther than p from the route), ``fov`` ``"sector"`` (Lemma 2) or
    ``"circular"`` (Corollary 1).  Defaults are the paper's section III.
    """

    range: float = 2.0
    angle_deg: float = 50.0
    clearance: float = 0.05
    fov: str = "sector"

    def __post_init__(self):
        for name in ("range", "angle_deg", "clearance"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not math.isfinite(v):
                raise ValueError(f"camera {name} = {v!r} must be a finite number")
        if self.fov not in ("sector", "circular"):
            raise ValueError(f"camera fov = {self.fov!r} must be 'sector' or 'circular'")
        if self.range <= 0:
            raise ValueError(f"camera range R = {self.range} must be > 0")
        if self.clearance < 0:
            raise ValueError(f"camera clearance p = {self.clearance} must be >= 0")
        if self.range <= self.clearance:
            raise ValueError(f"camera range R = {self.range} must exceed the clearance p = {self.clearance}: "
                             "no landmark could be both farther than p and in view")
        if self.fov == "sector" and not (0.0 < self.angle_deg <= 180.0):
            raise ValueError(f"camera angle alpha = {self.angle_deg} deg must be in (0, 180] "
                             "for a sector field of view")

    @property
    def angle(self) -> float:
        """α in radians."""
        return math.radians(self.angle_deg)

    def to_core(self) -> _core.Camera:
        cam = _core.Camera()
        cam.range, cam.angle, cam.clearance = float(self.range), self.angle, float(self.clearance)
        cam.fov = _core.FieldOfView.SECTOR if self.fov == "sector" else _core.FieldOfView.CIRCULAR
        return cam

    def in_view(self, position, heading: float, points) -> np.ndarray:
        """Which ``points`` a camera at ``position`` looking along ``heading`` sees (direct geometry)."""
        rel = np.asarray(points, float).reshape(-1, 2) - np.asarray(position, float)[:2]
        dist = np.hypot(rel[:, 0], rel[:, 1])
        ok = (dist <= self.range) & (dist > 0)
        if self.fov == "sector":
            rel_b = np.angle(np.exp(1j * (np.arctan2(rel[:, 1], rel[:, 0]) - heading)))
            ok &= np.abs(rel_b) <= self.angle / 2
        return ok


def _camera(camera) -> CameraParams:
    if camera is None:
        return CameraParams()
    if isinstance(camera, CameraParams):
        return camera
    if isinstance(camera, dict):
        known = ("range", "angle_deg", "clearance", "fov")
        bad = sorted(set(camera) - set(known))
        if bad:
            raise ValueError(f"camera: unknown parameter {bad[0]!r} (known: {', '.join(known)})")
        return CameraParams(**camera)
    raise ValueError(f"camera must be a CameraParams or a dict, got {camera!r}")


def _route(route) -> np.ndarray:
    r = as_array("route", route, (None, 2))
    if r.shape[0] < 2:
        raise ValueError(f"route must have at least 2 points, got {r.shape[0]}")
    step = np.hypot(*np.diff(r, axis=0).T)
    if (step <= 1e-12).any():
        i = int(np.argmax(step <= 1e-12)) + 1
        raise ValueError(f"route[{i}] = ({r[i, 0]:g}, {r[i, 1]:g}) repeats route[{i - 1}]: an edge of zero length has no direction")
    return r


def _candidates(candidates) -> np.ndarray:
    c = as_array("candidates", candidates, (None, 2))
    if c.shape[0] == 0:
        raise ValueError("candidates must hold at least one candidate location, got 0")
    return c


def _k(k) -> int:
    """k in [1, the core's bound], checked before it reaches the core (a C int)."""
    k = as_positive_int("k", k)
    if k > _core.PLACEMENT_MAX_K:
        raise ValueError(f"k = {k} must be <= {_core.PLACEMENT_MAX_K} (landmarks in view)")
    return k


def candidate_grid(lower, upper, spacing: float = PAPER_SPACING, margin: float = 0.0) -> np.ndarray:
    """Candidate locations on a square grid of ``spacing`` covering the box
    ``[lower − margin, upper + margin]`` (grid lines through ``lower − margin``)."""
    for name, v in (("spacing", spacing), ("margin", margin)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v):
            raise ValueError(f"{name} = {v!r} must be a finite number")
    if spacing <= 0:
        raise ValueError(f"spacing = {spacing!r} must be finite and > 0")
    lo = as_array("lower", lower, (2,)) - margin
    hi = as_array("upper", upper, (2,)) + margin
    if (hi < lo).any():
        raise ValueError(f"upper = {tuple(hi)} must not be below lower = {tuple(lo)}")
    n = np.floor((hi - lo) / spacing + 1e-9).astype(int) + 1
    if n.prod() > 5_000_000:
        raise ValueError(f"candidate grid of {n[0]} x {n[1]} points is too large; raise spacing = {spacing}")
    xs = lo[0] + spacing * np.arange(n[0])
    ys = lo[1] + spacing * np.arange(n[1])
    return np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)


# ---------------------------------------------------------------------------
# Route through targets: open tour with fixed ends, 2-opt + Or-opt
# ---------------------------------------------------------------------------

def tour_length(points) -> float:
    p = np.asarray(points, float)
    return float(np.hypot(*np.diff(p, axis=0).T).sum())


def _two_opt_or_opt(order: list[int], D: np.ndarray) -> list[int]:
    """Local search on an open path with fixed first and last node."""
    n = len(order)
    improved = True
    while improved:
        improved = False
        # 2-opt: reverse order[i..j] (1 <= i < j <= n-2)
        for i in range(1, n - 2):
            for j in range(i + 1, n - 1):
                a, b, c, d = order[i - 1], order[i], order[j], order[j + 1]
                if D[a, c] + D[b, d] < D[a, b] + D[c, d] - 1e-12:
                    order[i:j + 1] = order[i:j + 1][::-1]
                    improved = True
        # Or-opt: move a run of 1-3 inner nodes elsewhere, possibly reversed
        for seg in (1, 2, 3):
            for i in range(1, n - seg):
                j = i + seg  # run = order[i:j], j <= n-1 so the last node stays
                if j > n - 1:
                    break
                run = order[i:j]
                prev, nxt = order[i - 1], order[j]
                gain = D[prev, run[0]] + D[run[-1], nxt] - D[prev, nxt]
                rest = order[:i] + order[j:]
                best = None
                for p in range(len(rest) - 1):
                    u, v = rest[p], rest[p + 1]
                    for r in (run, run[::-1]):
                        cost = D[u, r[0]] + D[r[-1], v] - D[u, v]
                        if cost < gain - 1e-12 and (best is None or cost < best[0]):
                            best = (cost, p, r)
                if best is not None:
                    _, p, r = best
                    order[:] = rest[:p + 1] + list(r) + rest[p + 1:]
                    improved = True
                    break
            if improved:
                break
    return order


def plan_tour(targets, *, source: int = 0, destination: int = -1, restarts: int = 8, seed: int = 0) -> np.ndarray:
    """Order of the targets for the shortest open tour from ``source`` to
    ``destination`` through all of them (the paper uses LKH).

    We use 2-opt + Or-opt local search from a nearest-neighbour start and
    ``restarts`` seeded random starts, keeping the best.  OR-Tools routing is
    not installed here and would be a heavy dependency for tours of a handful
    of targets; for up to 9 targets this finds the exact optimum in our tests
    (checked against enumeration), and for larger tours 2-opt + Or-opt is
    within a few per cent of optimal.  Returns the visiting order (indices).
    """
    t = as_array("targets", targets, (None, 2))
    n = t.shape[0]
    if n < 2:
        raise ValueError(f"targets must hold at least 2 points (a source and a destination), got {n}")
    for name, v in (("source", source), ("destination", destination)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            _bad_index(name, v, n)
    if isinstance(restarts, bool) or not isinstance(restarts, (int, np.integer)) or restarts < 0:
        raise ValueError(f"restarts = {restarts!r} must be an integer >= 0")
    s = int(source) % n if -n <= int(source) < n else _bad_index("source", source, n)
    d = int(destination) % n if -n <= int(destination) < n else _bad_index("destination", destination, n)
    if s == d:
        raise ValueError(f"source = {source} and destination = {destination} are the same target")
    for i in range(n):
        for j in range(i + 1, n):
            if np.array_equal(t[i], t[j]):
                raise ValueError(f"targets[{i}] and targets[{j}] repeat the point ({t[i, 0]:g}, {t[i, 1]:g})")
    D = np.hypot(*(t[:, None, :] - t[None, :, :]).transpose(2, 0, 1))
    inner = [i for i in range(n) if i not in (s, d)]
    if not inner:
        return np.array([s, d])
    starts = []
    left, cur, nn = set(inner), s, []
    while left:
        cur = min(left, key=lambda j: (D[cur, j], j))
        nn.append(cur)
        left.remove(cur)
    starts.append(nn)
    rng = np.random.default_rng(as_seed("seed", seed))
    for _ in range(restarts):
        starts.append(list(rng.permutation(inner)))
    best, best_len = None, math.inf
    for st in starts:
        order = _two_opt_or_opt([s] + [int(i) for i in st] + [d], D)
        length = sum(D[a, b] for a, b in zip(order, order[1:]))
        if length < best_len - 1e-12:
            best, best_len = order, length
    return np.array(best)


def _bad_index(name, value, n):
    raise ValueError(f"{name} = {value!r} is not a target index (0 .. {n - 1})")


# ---------------------------------------------------------------------------
# Placement results
# ---------------------------------------------------------------------------

@dataclass
class PlacementResult:
    """A placement: the chosen candidate indices and where they are."""

    route: np.ndarray                 #: (n, 2) the route
    candidates: np.ndarray            #: (m, 2) all candidate locations
    indices: np.ndarray               #: chosen candidate indices, sorted
    camera: CameraParams
    k: int
    method: str                       #: "greedy", "greedy+corners", "optimal", ...
    corners: bool
    edge_landmarks: list = field(default_factory=list)   #: per edge, its own picks (greedy only)
    uncovered: list = field(default_factory=list)        #: [(where, index, start, end)] stretches with < k
    too_close: np.ndarray = field(default_factory=lambda: np.zeros(0, int))  #: candidates within p (removed)
    seconds: float = 0.0
    optimal: bool | None = None       #: ILP only: proven optimal within the time limit

    @property
    def landmarks(self) -> np.ndarray:
        """(L, 2) positions of the placed landmarks."""
        return self.candidates[self.indices]

    @property
    def count(self) -> int:
        return int(len(self.indices))

    @property
    def covered(self) -> bool:
        return not self.uncovered

    def check(self, *, corners: bool | None = None) -> "_core.CoverageReport":
        """Exact coverage check of this placement (see :func:`check_coverage`)."""
        return check_coverage(self.route, self.landmarks, self.camera, k=self.k,
                              corners=self.corners if corners is None else corners)

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        cam = self.camera
        return {
            "method": self.method, "k": self.k, "corners": self.corners,
            "camera": {"range": cam.range, "angle_deg": cam.angle_deg, "clearance": cam.clearance, "fov": cam.fov},
            "route": self.route.tolist(),
            "route_length": tour_length(self.route),
            "n_candidates": int(len(self.candidates)),
            "n_too_close": int(len(self.too_close)),
            "n_landmarks": self.count,
            "landmark_indices": [int(i) for i in self.indices],
            "landmarks": self.landmarks.tolist(),
            "edge_landmarks": [[int(i) for i in e] for e in self.edge_landmarks],
            "covered": self.covered,
            "uncovered": [{"where": w, "index": int(i), "start": float(a), "end": float(b)}
                          for w, i, a, b in self.uncovered],
            "optimal": self.optimal,
            "seconds": self.seconds,
        }


def _describe_uncovered(route, uncovered, k) -> str:
    lines = []
    for where, i, a, b in uncovered[:5]:
        if where == "edge":
            p, q = route[i], route[i + 1]
            what = f"at the point t = {a:.4g} m (landmarks align there)" if a == b else f"from t = {a:.4g} to {b:.4g} m"
            lines.append(f"edge {i} from ({p[0]:.4g}, {p[1]:.4g}) to ({q[0]:.4g}, {q[1]:.4g}) {what}")
        else:
            lines.append(f"the turn at route[{i}] = ({route[i][0]:.4g}, {route[i][1]:.4g}) between "
                         f"{math.degrees(a):.3g} and {math.degrees(b):.3g} deg into the turn")
    more = f" (and {len(uncovered) - 5} more)" if len(uncovered) > 5 else ""
    return (f"cannot keep {k} landmarks in view on " + "; ".join(lines) + more +
            ": too few candidates there; add candidates (denser grid or a wider candidate area), "
            "or pass allow_uncovered=True to get the best-effort placement")


def place_along_route(route, candidates, camera: CameraParams | dict | None = None, *, k: int = 2,
                      corners: bool = False, reuse: bool = False, distinct_bearings: bool = True,
                      allow_uncovered: bool = False) -> PlacementResult:
    """The paper's placement on a given route (section II): per edge the
    greedy k-interval cover (Algorithm 1, generalised to k ≥ 1), then the
    union over the edges (section II-B).

    ``distinct_bearings=False`` runs Algorithm 1 verbatim.  With the default
    ``True`` (condition (2) of the LPP, non-coincidence): of the candidates
    on an edge's own line, which all share one bearing, only the one reaching
    farthest is offered; and wherever the exact count of an edge's picks
    falls below k (two picks aligned at a point), the candidate with a fresh
    bearing there that reaches farthest is added.  ``corners`` also covers
    the in-place turn at each vertex; ``reuse`` lets an edge count landmarks
    placed for earlier edges (our improvement; the paper's union does not).

    The certificate (:attr:`PlacementResult.covered`,
    :attr:`PlacementResult.uncovered`) is :func:`check_coverage` of the final
    landmarks, in every mode: covered exactly when the exact check finds at
    least k distinct bearings everywhere.  Raises ``ValueError`` naming the
    first uncovered stretch unless ``allow_uncovered``.
    """
    cam = _camera(camera)
    r, c, k = _route(route), _candidates(candidates), _k(k)
    opt = _core.PlacementOptions()
    opt.k, opt.corners, opt.reuse, opt.distinct_bearings = k, bool(corners), bool(reuse), bool(distinct_bearings)
    t0 = time.perf_counter()
    p = _core.place_landmarks(r, c, cam.to_core(), opt)
    sec = time.perf_counter() - t0
    unc = [("edge", i, a, b) for i, e in enumerate(p.edges) for a, b in e.uncovered]
    unc += [("corner", cp.vertex, a, b) for cp in p.corners for a, b in cp.uncovered]
    if unc and not allow_uncovered:
        raise ValueError(_describe_uncovered(r, unc, k))
    method = "greedy" + ("+reuse" if reuse else "") + ("+corners" if corners else "")
    if not distinct_bearings:
        method += " (Algorithm 1 verbatim)"
    return PlacementResult(route=r, candidates=c, indices=np.array(p.landmarks, dtype=int), camera=cam, k=k,
                           method=method, corners=bool(corners), edge_landmarks=[list(e.landmarks) for e in p.edges],
                           uncovered=unc, too_close=np.array(p.too_close, dtype=int), seconds=sec)


def check_coverage(route, landmarks, camera: CameraParams | dict | None = None, *, k: int = 2,
                   corners: bool = False) -> "_core.CoverageReport":
    """Exact check: at every interval endpoint, alignment point, on-line
    landmark and the midpoint between consecutive ones, count the distinct
    bearings in view (DESIGN: check coverage at interval endpoints, not at
    sample points; the count is constant in between).  Landmarks must be
    pairwise distinct.  The report has ``min_count``,
    ``min_distance`` (closest landmark to the route) and the deficient
    stretches (``kind`` 0 edge / 1 corner, ``index``, ``start``, ``end``)."""
    cam = _camera(camera)
    lm = as_array("landmarks", landmarks, (None, 2))
    return _core.check_coverage(_route(route), lm, cam.to_core(), _k(k), bool(corners))


# ---------------------------------------------------------------------------
# Global optimum: integer program over interval endpoints (HiGHS)
# ---------------------------------------------------------------------------

def _bearing_groups(bearings: np.ndarray) -> list[np.ndarray]:
    """Indices of ``bearings`` [rad, in (−π, π]] grouped where consecutive
    sorted values differ by <= the bearing tolerance, across ±π too (as the
    core's distinct-bearing count)."""
    if bearings.size == 0:
        return []
    order = np.argsort(bearings, kind="stable")
    groups = np.split(order, np.flatnonzero(np.diff(bearings[order]) > _BEARING_TOL) + 1)
    if len(groups) > 1 and bearings[order[0]] + 2 * math.pi - bearings[order[-1]] <= _BEARING_TOL:
        groups = [np.concatenate([groups[-1], groups[0]])] + groups[1:-1]
    return groups


def place_optimal(route, candidates, camera: CameraParams | dict | None = None, *, k: int = 2,
                  corners: bool = False, distinct_bearings: bool = True, time_limit: float = 120.0,
                  allow_uncovered: bool = False) -> PlacementResult:
    """The fewest landmarks for the whole route at once: an integer program
    solved with ``scipy.optimize.milp`` (HiGHS).

    Variables: ``x_ℓ ∈ {0, 1}`` per candidate with a non-empty Lemma 2
    interval on some edge (or turn); minimise ``Σ x_ℓ``.  One row per point of
    each edge where coverage can change — every interval endpoint, every
    alignment point of two candidates, and the midpoint of every gap between
    consecutive such points — requires ``≥ k`` distinct bearings in view.
    Coverage is constant between those points, so the program is exact (the
    route is not sampled).  Candidates on one bearing at a point form a group
    ``g`` counted once through ``z_g ≤ Σ_{ℓ∈g} x_ℓ``, ``0 ≤ z_g ≤ 1`` (those
    on the edge's own line share bearing 0 or π wherever they are in view).
    With ``corners`` the same is done over the turned angle at each vertex.
    ``distinct_bearings=False`` drops the groups; the certificate
    (:attr:`PlacementResult.uncovered`) is the exact check of the chosen
    landmarks either way, as for the greedy.
    """
    from scipy.optimize import Bounds, LinearConstraint, milp
    from scipy.sparse import coo_matrix

    cam = _camera(camera)
    r, c, k = _route(route), _candidates(candidates), _k(k)
    if isinstance(time_limit, bool) or not isinstance(time_limit, (int, float, np.integer, np.floating)) \
            or not (math.isfinite(time_limit) and time_limit > 0):
        raise ValueError(f"time_limit = {time_limit!r} must be a finite number of seconds > 0")
    core_cam = cam.to_core()
    t0 = time.perf_counter()
    vis = _core.edge_visibility(r, c, core_cam)
    too_close = np.flatnonzero(_core.distance_to_route(r, c) <= cam.clearance)
    col_of: dict[int, int] = {}
    z_groups: dict[tuple, int] = {}
    rows: list[tuple[list[int], int]] = []   # (columns, required)
    seen_rows: set = set()
    unc: list = []

    def col(i: int) -> int:
        return col_of.setdefault(int(i), len(col_of))

    def add_row(cands_groups: list[np.ndarray], where, idx, a, b):
        cols = []
        for g in cands_groups:
            members = [col(i) for i in g]  # every candidate gets its own x, grouped or not
            if len(g) == 1:
                cols.append(("x", members[0]))
            else:
                key = tuple(sorted(int(i) for i in g))
                cols.append(("z", z_groups.setdefault(key, len(z_groups))))
        need = k
        if len(cols) < k:
            unc.append((where, idx, a, b))
            need = len(cols)
        if need == 0:
            return
        key = (tuple(sorted(cols)), need)
        if key not in seen_rows:
            seen_rows.add(key)
            rows.append((cols, need))

    al = _core.alignments(r, c, core_cam) if distinct_bearings else None
    for e in range(len(r) - 1):
        d = float(np.hypot(*(r[e + 1] - r[e])))
        m = vis.edge == e
        a, b, x, y, ci = vis.start[m], vis.end[m], vis.x[m], vis.y[m], vis.candidate[m]
        pts = np.concatenate([a, b, [0.0, d]] + ([al.t[al.edge == e]] if al is not None else []))
        pts = np.unique(np.clip(pts, 0.0, d))
        probe = np.concatenate([pts, 0.5 * (pts[:-1] + pts[1:])])
        inview = (a[None, :] - _EPS <= probe[:, None]) & (probe[:, None] <= b[None, :] + _EPS)
        for pi, t in enumerate(probe):
            idx = np.flatnonzero(inview[pi])
            if distinct_bearings and idx.size > 1:
                brg = np.arctan2(y[idx], x[idx] - t)
                groups = [ci[idx[g]] for g in _bearing_groups(brg)]
            else:
                groups = [np.array([ci[i]]) for i in idx]
            lo = t if pi < len(pts) else pts[pi - len(pts)]
            hi = t if pi < len(pts) else pts[pi - len(pts) + 1]
            add_row(groups, "edge", e, lo, hi)
    if corners:
        cv = _core.corner_visibility(r, c, core_cam)
        turns = _core.turn_angles(r)
        for v in range(1, len(r) - 1):
            L = abs(float(turns[v - 1]))
            if L <= _EPS:
                continue
            m = cv.edge == v
            a, b, ci = cv.start[m], cv.end[m], cv.candidate[m]
            brg = np.arctan2(cv.y[m], cv.x[m])
            rays = _bearing_groups(brg) if distinct_bearings else [np.array([i]) for i in range(len(ci))]
            pts = np.unique(np.clip(np.concatenate([a, b, [0.0, L]]), 0.0, L))
            probe = np.concatenate([pts, 0.5 * (pts[:-1] + pts[1:])])
            for pi, s in enumerate(probe):
                groups = [ci[g] for g in rays if ((a[g] - _EPS <= s) & (s <= b[g] + _EPS)).any()]
                lo = s if pi < len(pts) else pts[pi - len(pts)]
                hi = s if pi < len(pts) else pts[pi - len(pts) + 1]
                add_row(groups, "corner", v, lo, hi)
    unc = _merge_uncovered(unc)
    if unc and not allow_uncovered:
        raise ValueError(_describe_uncovered(r, unc, k))
    nx, nz = len(col_of), len(z_groups)
    cand_of_col = np.empty(nx, dtype=int)
    for cand, j in col_of.items():
        cand_of_col[j] = cand
    method = "optimal" + ("+corners" if corners else "")
    if nx == 0:
        return PlacementResult(route=r, candidates=c, indices=np.zeros(0, int), camera=cam, k=k, method=method,
                               corners=bool(corners), uncovered=_exact_uncovered(r, c[:0], cam, k, corners),
                               too_close=too_close, seconds=time.perf_counter() - t0, optimal=True)
    ri, cj, vals, lb = [], [], [], []
    for row, (cols, need) in enumerate(rows):
        for kind, j in cols:
            ri.append(row)
            cj.append(j if kind == "x" else nx + j)
            vals.append(1.0)
        lb.append(need)
    nrow = len(rows)
    for key, j in z_groups.items():   # z_g - sum_{l in g} x_l <= 0
        ri.append(nrow)
        cj.append(nx + j)
        vals.append(1.0)
        for cand in key:
            ri.append(nrow)
            cj.append(col_of[cand])
            vals.append(-1.0)
        nrow += 1
    A = coo_matrix((vals, (ri, cj)), shape=(nrow, nx + nz)).tocsr()
    lo = np.concatenate([lb, np.full(nz, -np.inf)])
    hi = np.concatenate([np.full(len(rows), np.inf), np.zeros(nz)])
    cost = np.concatenate([np.ones(nx), np.zeros(nz)])
    integrality = np.concatenate([np.ones(nx), np.zeros(nz)])
    res = milp(cost, constraints=LinearConstraint(A, lo, hi), integrality=integrality, bounds=Bounds(0, 1),
               options={"time_limit": float(time_limit), "presolve": True})
    if res.x is None:
        raise ValueError(f"the placement integer program found no solution ({res.message})")
    chosen = np.sort(cand_of_col[res.x[:nx] > 0.5])
    return PlacementResult(route=r, candidates=c, indices=chosen, camera=cam, k=k, method=method,
                           corners=bool(corners), uncovered=_exact_uncovered(r, c[chosen], cam, k, corners),
                           too_close=too_close, seconds=time.perf_counter() - t0, optimal=bool(res.status == 0))


def _exact_uncovered(route, landmarks, cam: CameraParams, k: int, corners: bool) -> list:
    """The certificate: the stretches the exact check finds with fewer than k
    distinct bearings, as ``[(where, index, start, end)]``."""
    rep = _core.check_coverage(route, landmarks, cam.to_core(), k, corners)
    return [("edge" if kind == 0 else "corner", int(i), float(a), float(b))
            for kind, i, a, b in zip(rep.kind, rep.index, rep.start, rep.end)]


def _merge_uncovered(unc):
    out = []
    for w, i, a, b in sorted(unc, key=lambda u: (u[0], u[1], u[2], u[3])):
        if out and out[-1][0] == w and out[-1][1] == i and a <= out[-1][3] + _EPS:
            out[-1] = (w, i, out[-1][2], max(out[-1][3], b))
        else:
            out.append((w, i, a, b))
    return out


# ---------------------------------------------------------------------------
# Through targets, along a SafeNav path
# ---------------------------------------------------------------------------

def place_through_targets(targets, candidates, camera: CameraParams | dict | None = None, *, k: int = 2,
                          corners: bool = False, method: str = "greedy", source: int = 0, destination: int = -1,
                          route=None, seed: int = 0, **kwargs) -> PlacementResult:
    """Route through ``targets`` (open tour ``source`` → ``destination``,
    :func:`plan_tour`), or the explicit ``route`` if given, then placement by
    ``method``: ``"greedy"`` (the paper), ``"reuse"`` (greedy reusing earlier
    edges' landmarks) or ``"optimal"`` (ILP)."""
    if route is None:
        t = as_array("targets", targets, (None, 2))
        route = t[plan_tour(t, source=source, destination=destination, seed=seed)]
    if method == "greedy":
        return place_along_route(route, candidates, camera, k=k, corners=corners, **kwargs)
    if method == "reuse":
        return place_along_route(route, candidates, camera, k=k, corners=corners, reuse=True, **kwargs)
    if method == "optimal":
        return place_optimal(route, candidates, camera, k=k, corners=corners, **kwargs)
    raise ValueError(f"method = {method!r} must be 'greedy', 'reuse' or 'optimal'")


def place_along_path(path, camera: CameraParams | dict | None = None, *, candidates=None, spacing: float = 0.5,
                     world=None, k: int = 2, corners: bool = True, method: str = "reuse",
                     allow_uncovered: bool = False) -> PlacementResult:
    """Landmarks along a SafeNav safe path (a polyline, e.g. from
    :meth:`safenav.World.path_polyline`, or a :func:`safenav.planning.plan`
    result) so
    that a vehicle on it always has ``k`` landmarks in view.

    Without ``candidates`` a grid of ``spacing`` within R of the path is used;
    with a ``world`` candidates inside obstacles or outside the field are
    dropped.  Consecutive repeated path points are merged.
    """
    cam = _camera(camera)
    if hasattr(path, "path") and not isinstance(path, np.ndarray):  # a planner's PlanResult
        if not getattr(path, "success", True):
            raise ValueError("the plan has no path (planning did not succeed)")
        path = path.path
    p = as_array("path", path, (None, 2))
    if p.shape[0] < 2:
        raise ValueError(f"path must have at least 2 points, got {p.shape[0]}")
    keep = np.concatenate([[True], np.hypot(*np.diff(p, axis=0).T) > 1e-12])
    p = _route(p[keep])
    if candidates is None:
        c = candidate_grid(p.min(axis=0), p.max(axis=0), spacing, margin=cam.range)
        c = c[_core.distance_to_route(p, c) <= cam.range]
    else:
        c = _candidates(candidates)
    if world is not None:
        c = c[~world.obstacle_mask(c) & world.field.contains(c)]
    if len(c) == 0:
        raise ValueError("no candidate locations left around the path (all inside obstacles or outside the field)")
    return place_through_targets(None, c, cam, k=k, corners=corners, method=method, route=p,
                                 allow_uncovered=allow_uncovered)


# ---------------------------------------------------------------------------
# Table I
# ---------------------------------------------------------------------------

def random_instance(n_targets: int, rng: np.random.Generator, area=PAPER_AREA) -> np.ndarray:
    """Targets drawn uniformly in the ``area`` (the paper: a 4 × 8 grid)."""
    return rng.uniform((0.0, 0.0), area, size=(as_positive_int("n_targets", n_targets), 2))


def table_one(seed: int = 0, *, camera: CameraParams | None = None, k: int = 2, margin: float | None = None,
              optimal: bool = True, time_limit: float = 120.0, sizes: Sequence[int] | None = None):
    """The paper's Table I on fresh random instances.

    Nine instances with 5, 5, 5, 6, 6, 7, 7, 7, 7 targets uniform in 4 × 8,
    candidates on a 0.5 grid over the area widened by ``margin`` (default R:
    the paper does not say how far its grid reached, and inside the area
    alone many instances cannot be covered near the edge ends), field of view
    50°, R = 2 m, p = 0.05 m, the route an open tour from the first to the
    last target.  Columns: ``greedy_paper`` (Algorithm 1 verbatim, union over
    edges), ``greedy`` (plus non-coincidence), ``greedy_reuse``,
    ``greedy_corners``, ``optimal`` and ``optimal_corners`` (ILP) and the
    paper's count.  The instances are random, so compare distributions, not
    rows.
    """
    import pandas as pd

    cam = camera or CameraParams()
    margin = cam.range if margin is None else float(margin)
    rng = np.random.default_rng(as_seed("seed", seed))
    cand = candidate_grid((0.0, 0.0), PAPER_AREA, PAPER_SPACING, margin=margin)
    sizes = [n for n, _ in PAPER_TABLE_ONE] if sizes is None else list(sizes)
    rows = []
    for i, n in enumerate(sizes):
        targets = random_instance(n, rng)
        route = targets[plan_tour(targets, seed=i)]
        row = {"instance": i + 1, "targets": n, "route_length": tour_length(route)}
        kw = dict(k=k, allow_uncovered=True)
        g0 = place_along_route(route, cand, cam, distinct_bearings=False, **kw)
        g = place_along_route(route, cand, cam, **kw)
        gr = place_along_route(route, cand, cam, reuse=True, **kw)
        gc = place_along_route(route, cand, cam, corners=True, **kw)
        row.update(greedy_paper=g0.count, greedy=g.count, greedy_reuse=gr.count, greedy_corners=gc.count,
                   greedy_ms=1e3 * g.seconds, covered=g.covered and gc.covered)
        if optimal:
            o = place_optimal(route, cand, cam, time_limit=time_limit, **kw)
            oc = place_optimal(route, cand, cam, corners=True, time_limit=time_limit, **kw)
            row.update(optimal=o.count, optimal_corners=oc.count, optimal_s=o.seconds, optimal_corners_s=oc.seconds,
                       proven=bool(o.optimal and oc.optimal))
        row["paper"] = PAPER_TABLE_ONE[i][1] if i < len(PAPER_TABLE_ONE) and PAPER_TABLE_ONE[i][0] == n else None
        rows.append(row)
    return pd.DataFrame(rows)


# ---------------------------------------------------------------------------
# Simulation (section III): ground robot, bearings, extended information filter
# ---------------------------------------------------------------------------

@dataclass
class SimulationResult:
    """True and estimated trajectories of :func:`simulate`."""

    t: np.ndarray            #: (N+1,) time [s]
    truth: np.ndarray        #: (N+1, 4) true (x, y, v, θ)
    estimate: np.ndarray     #: (N+1, 4) EIF estimate
    covariance: np.ndarray   #: (N+1, 4, 4)
    n_in_view: np.ndarray    #: (N+1,) landmarks in view after each step (0 at t=0)
    turning: np.ndarray      #: (N+1,) True while the robot turns in place
    landmarks: np.ndarray    #: (L, 2)
    route: np.ndarray

    @property
    def errors(self) -> np.ndarray:
        """(N+1, 3) estimate − truth in x, y and heading (wrapped)."""
        e = self.estimate[:, [0, 1, 3]] - self.truth[:, [0, 1, 3]]
        e[:, 2] = np.angle(np.exp(1j * e[:, 2]))
        return e

    @property
    def sigmas(self) -> np.ndarray:
        """(N+1, 3) standard deviations of x, y and heading."""
        return np.sqrt(self.covariance[:, [0, 1, 3], [0, 1, 3]])

    def inside_3sigma(self) -> dict:
        """Fraction of the time each error is within its ±3σ bound."""
        inside = np.abs(self.errors) <= 3 * self.sigmas
        return {name: float(inside[:, i].mean()) for i, name in enumerate(("x", "y", "heading"))}

    def gap_fraction(self, k: int = 2) -> float:
        """Fraction of the time steps with fewer than ``k`` landmarks in view."""
        return float((self.n_in_view[1:] < k).mean())


def simulate(route, landmarks, camera: CameraParams | dict | None = None, *, speed: float = 0.2, dt: float = 0.1,
             bearing_std: float = 0.01, heading_gain: float = 2.0, seed: int = 0,
             prior_std=(0.05, 0.05, 0.01, 0.03), max_steps: int = 200_000) -> SimulationResult:
    """Section III: a ground robot drives the route at ``speed`` (0.2 m/s) with
    a heading controller and an extended information filter estimates its
    position and heading from bearings to the landmarks in view.

    The robot follows the BMM (:class:`safenav.Bmm`) with small process noise.
    Its controller (run on the true state, so that the robot follows the
    route) turns in place at every waypoint until it faces the next one, then
    drives at ``speed`` with heading change ``heading_gain · e · Δt`` for the
    heading error ``e``.  Each step a bearing ``wrap(atan2(ℓ − p) − θ) + v``,
    ``v ~ N(0, bearing_std²)``, is measured to every landmark within R and
    ±α/2 of the true pose.  The EIF (``filter_trajectory(filter="eif")``,
    one C++ call) gets the same controls and the bearings.
    """
    from .filters import filter_trajectory
    from .motion import Bmm, BmmParams

    cam = _camera(camera)
    r = _route(route)
    lm = as_array("landmarks", landmarks, (None, 2))
    if lm.shape[0] == 0:
        raise ValueError("landmarks must hold at least one landmark, got 0")
    for name, v in (("speed", speed), ("dt", dt), ("bearing_std", bearing_std), ("heading_gain", heading_gain)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) \
                or not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} = {v!r} must be finite and > 0")
    try:
        prior = np.asarray(prior_std, dtype=float).ravel() if np.ndim(prior_std) == 1 else np.zeros(0)
    except (TypeError, ValueError):
        prior = np.zeros(0)
    if prior.shape != (4,) or not (np.isfinite(prior).all() and (prior > 0).all()):
        raise ValueError(f"prior_std = {prior_std!r} must be 4 finite values > 0 (x, y, v, theta)")
    as_positive_int("max_steps", max_steps)
    params = BmmParams()
    params.dt = float(dt)
    params.max_speed = max(1.0, 2 * speed)
    params.max_heading_rate = 1.5
    params.speed_noise, params.heading_noise, params.position_noise = 0.002, 0.002, 0.001
    bmm = Bmm(params)
    rng = np.random.default_rng(as_seed("seed", seed))
    sig_eps = np.array([params.position_noise, params.position_noise, params.speed_noise, params.heading_noise])
    heading0 = math.atan2(*(r[1] - r[0])[::-1])
    x = np.array([r[0, 0], r[0, 1], 0.0, heading0])
    states, controls, turning = [x], [], [False]
    wp = 1
    lim = params.max_heading_rate * dt
    while wp < len(r) and len(controls) < max_steps:
        to = r[wp] - x[:2]
        dist = math.hypot(*to)
        if dist <= 0.75 * speed * dt:  # arrived (within one step)
            wp += 1
            continue
        err = math.atan2(to[1], to[0]) - x[3]
        err = math.atan2(math.sin(err), math.cos(err))
        turn = abs(err) > max(lim, 0.02)
        if turn:
            u = (0.0, err)
        else:
            u = (min(speed, dist / dt), heading_gain * err * dt if dist > speed * dt else err)
        x = bmm.transition(x, u, rng.standard_normal(4) * sig_eps)
        states.append(x)
        controls.append(u)
        turning.append(turn)
    truth = np.array(states)
    u = np.array(controls, dtype=float)
    n = len(u)
    # bearings to landmarks in view of the true pose
    rel = lm[None, :, :] - truth[1:, None, :2]
    dist = np.hypot(rel[..., 0], rel[..., 1])
    brg = np.angle(np.exp(1j * (np.arctan2(rel[..., 1], rel[..., 0]) - truth[1:, 3, None])))
    seen = (dist <= cam.range) & (dist > 0)
    if cam.fov == "sector":
        seen &= np.abs(brg) <= cam.angle / 2
    z = np.where(seen, np.angle(np.exp(1j * (brg + bearing_std * rng.standard_normal(brg.shape)))), np.nan)
    P0 = np.diag(np.square(prior_std))
    x0 = truth[0] + rng.standard_normal(4) * np.asarray(prior_std)
    res = filter_trajectory(u, x0, P0, params=params, filter="eif", bearings=z, bearing_std=bearing_std,
                            landmarks=lm)
    return SimulationResult(t=np.arange(n + 1) * dt, truth=truth, estimate=res.states, covariance=res.covariances,
                            n_in_view=np.concatenate([[0], seen.sum(axis=1)]), turning=np.array(turning),
                            landmarks=lm, route=r)


def corner_gap_demo(seed: int = 3, n_targets: int = 6, *, camera: CameraParams | None = None, sim_seed: int = 0):
    """Corner coverage closes the gap: the same random instance placed
    without and with ``corners``, each driven by :func:`simulate`.  Returns a
    dict of the two placements and simulations and, for each, the fraction of
    the turning time with fewer than 2 landmarks in view."""
    cam = camera or CameraParams()
    rng = np.random.default_rng(seed)
    targets = random_instance(n_targets, rng)
    route = targets[plan_tour(targets)]
    cand = candidate_grid((0, 0), PAPER_AREA, PAPER_SPACING, margin=cam.range)
    out = {}
    for corners in (False, True):
        pl = place_along_route(route, cand, cam, corners=corners)
        sim = simulate(route, pl.landmarks, cam, seed=sim_seed)
        turning = sim.turning[1:]
        blind = float((sim.n_in_view[1:][turning] < 2).mean()) if turning.any() else 0.0
        out["corners" if corners else "plain"] = {"placement": pl, "simulation": sim, "turn_gap": blind,
                                                  "gap": sim.gap_fraction(2), "inside_3sigma": sim.inside_3sigma()}
    return out


# ---------------------------------------------------------------------------
# Figures (matplotlib, Agg)
# ---------------------------------------------------------------------------

def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_placement(result: PlacementResult, path, *, simulation: SimulationResult | None = None,
                   title: str | None = None) -> Path:
    """Route, candidates, placed landmarks (numbered) and, if given, the true
    and estimated paths (the paper's Figs. 6–7).  Writes a PNG; returns its path."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5.2, 7.0))
    c, lm, r = result.candidates, result.landmarks, result.route
    ax.plot(c[:, 0], c[:, 1], ".", ms=1.5, color="0.8", label="candidates")
    ax.plot(r[:, 0], r[:, 1], "-", color="tab:blue", lw=1.2, label="route")
    ax.plot(r[:, 0], r[:, 1], "o", color="tab:blue", ms=6, label="targets (waypoints)")
    for i, p in enumerate(r):
        ax.annotate(str(i + 1), p, textcoords="offset points", xytext=(4, 4), fontsize=8, color="tab:blue")
    ax.plot(lm[:, 0], lm[:, 1], "^", color="tab:red", ms=6, label=f"landmarks ({result.count})")
    for i, p in enumerate(lm):
        ax.annotate(str(i + 1), p, textcoords="offset points", xytext=(3, -8), fontsize=6, color="tab:red")
    if simulation is not None:
        ax.plot(simulation.truth[:, 0], simulation.truth[:, 1], "k-", lw=1.0, label="true path")
        ax.plot(simulation.estimate[:, 0], simulation.estimate[:, 1], "--", color="tab:green", lw=1.0,
                label="EIF estimate")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="best", fontsize=7)
    cam = result.camera
    ax.set_title(title or f"{result.method}: {result.count} landmarks, k = {result.k}\n"
                 f"R = {cam.range} m, alpha = {cam.angle_deg} deg, p = {cam.clearance} m", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path, dpi=130)


def plot_simulation(sim: SimulationResult, path, *, title: str | None = None) -> Path:
    """X, Y and heading errors with ±3σ bounds over time (the paper's Figs. 8–9),
    with the number of landmarks in view.  Writes a PNG; returns its path."""
    plt = _pyplot()
    fig, axes = plt.subplots(4, 1, figsize=(7.5, 8.0), sharex=True)
    err, sig = sim.errors, sim.sigmas
    inside = sim.inside_3sigma()
    for i, (name, unit) in enumerate((("x", "m"), ("y", "m"), ("heading", "rad"))):
        ax = axes[i]
        ax.plot(sim.t, err[:, i], color="tab:blue", lw=0.9, label=f"error {name}")
        ax.plot(sim.t, 3 * sig[:, i], "r--", lw=0.8, label="+3σ")
        ax.plot(sim.t, -3 * sig[:, i], "r--", lw=0.8, label="-3σ")
        ax.set_ylabel(f"{name} error [{unit}]")
        ax.set_title(f"{100 * inside[name]:.1f}% of the time within ±3σ", fontsize=8, loc="right")
        if i == 0:
            ax.legend(loc="upper left", fontsize=7, ncol=3)
    axes[3].step(sim.t, sim.n_in_view, where="post", color="0.3", lw=0.8)
    axes[3].axhline(2, color="tab:red", lw=0.6, ls=":")
    axes[3].fill_between(sim.t, 0, sim.n_in_view.max() + 1, where=sim.turning, color="tab:orange", alpha=0.2,
                         step="post", label="turning in place")
    axes[3].set_ylabel("in view")
    axes[3].set_xlabel("time [s]")
    axes[3].legend(loc="upper right", fontsize=7)
    fig.suptitle(title or "Bearing-only EIF on the placed landmarks", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path, dpi=130)


def plot_corner_gap(demo: dict, path) -> Path:
    """Landmarks in view and heading 3σ over time without and with corner
    coverage (:func:`corner_gap_demo`).  Writes a PNG; returns its path."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(10, 5.2), sharex="col")
    for j, key in enumerate(("plain", "corners")):
        d = demo[key]
        sim, pl = d["simulation"], d["placement"]
        ax = axes[0, j]
        ax.step(sim.t, sim.n_in_view, where="post", color="0.25", lw=0.8)
        ax.axhline(2, color="tab:red", ls=":", lw=0.8)
        ax.fill_between(sim.t, 0, sim.n_in_view.max() + 1, where=sim.turning, step="post", color="tab:orange",
                        alpha=0.25, label="turning in place")
        ax.set_ylabel("landmarks in view")
        ax.set_title(f"{'with' if key == 'corners' else 'without'} corner coverage: {pl.count} landmarks; "
                     f"< 2 in view {100 * d['turn_gap']:.0f}% of turning time", fontsize=8)
        ax.legend(loc="upper right", fontsize=7)
        ax = axes[1, j]
        ax.plot(sim.t, 3 * sim.sigmas[:, 2], color="tab:purple", lw=0.9, label="3σ heading")
        ax.plot(sim.t, np.abs(sim.errors[:, 2]), color="tab:blue", lw=0.7, label="|heading error|")
        ax.set_ylabel("rad")
        ax.set_xlabel("time [s]")
        ax.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    return save_figure(fig, path, dpi=120)


def paper_figures(folder="docs/figures", *, seed: int = 0) -> dict:
    """Regenerate the figures of docs/placement.md: the paper's Figs. 6–9
    (6 and 7 targets: route, landmarks, true and EIF paths; X/Y/heading errors
    with ±3σ), the corner-coverage demonstration, and Table I's counts.
    Returns the numbers quoted in the docs."""
    folder = Path(folder)
    cam = CameraParams()
    cand = candidate_grid((0, 0), PAPER_AREA, PAPER_SPACING, margin=cam.range)
    rng = np.random.default_rng(seed)
    numbers = {}
    for n in (6, 7):
        while True:  # first feasible instance of this size
            targets = random_instance(n, rng)
            route = targets[plan_tour(targets)]
            pl = place_along_route(route, cand, cam, allow_uncovered=True)
            if pl.covered:
                break
        sim = simulate(route, pl.landmarks, cam, seed=seed)
        plot_placement(pl, folder / f"placement_route{n}.png", simulation=sim,
                       title=f"{n} targets, {pl.count} landmarks (greedy, k = 2)")
        plot_simulation(sim, folder / f"placement_errors{n}.png",
                        title=f"{n} targets, {pl.count} landmarks: EIF errors with ±3σ")
        numbers[f"targets{n}"] = {"landmarks": pl.count, "duration_s": float(sim.t[-1]),
                                  "inside_3sigma": sim.inside_3sigma(), "below_2_in_view": sim.gap_fraction(2)}
    demo = corner_gap_demo(seed=3, n_targets=6)
    plot_corner_gap(demo, folder / "placement_corners.png")
    numbers["corners"] = {k: {"landmarks": v["placement"].count, "turn_gap": v["turn_gap"], "gap": v["gap"],
                              "inside_3sigma": v["inside_3sigma"]} for k, v in demo.items()}
    df = table_one(seed=seed)
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 3.4))
    idx = np.arange(len(df))
    cols = (("paper", "paper (its own instances)", "0.6"), ("greedy_paper", "greedy (Alg. 1)", "tab:blue"),
            ("optimal", "ILP optimum", "tab:green"), ("greedy_corners", "greedy + corners", "tab:orange"),
            ("optimal_corners", "ILP + corners", "tab:red"))
    w = 0.16
    for j, (c, label, color) in enumerate(cols):
        ax.bar(idx + (j - 2) * w, df[c].astype(float), w, label=label, color=color)
    ax.set_xticks(idx, [f"#{i}\n{t} targets" for i, t in zip(df.instance, df.targets)], fontsize=7)
    ax.set_ylabel("landmarks")
    ax.set_title(f"Table I: nine random instances (seed {seed}) beside the paper's counts", fontsize=9)
    ax.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    save_figure(fig, folder / "placement_table1.png", dpi=120)
    numbers["table_one"] = df
    return numbers

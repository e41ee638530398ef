"""The placement algorithms of the landmark placement paper [Placement §II]:
the greedy per-edge cover [Placement Alg. 1], the global integer program, the
exact coverage check, and placement through targets or along a SafeNav path.
See :mod:`safenav.placement` for the overview."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from .. import _core
from ..validation import as_array, as_positive_int
from ..motion import wrap_angle
from .cover_program import EPS as _EPS, CoverProgram
from .tour import plan_tour, tour_length

#: [Placement Table I] setup ([Placement §III-A]): a 4 × 8 area, candidates on a 0.5 grid.
PAPER_AREA = (4.0, 8.0)
PAPER_SPACING = 0.5



# ---------------------------------------------------------------------------
# Camera and inputs
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class CameraParams:
    """The bearing sensor and the collision-avoidance distance.

    ``range`` is the paper's R [m], ``angle_deg`` its viewing angle α [deg]
    (full angle, in (0°, 180°]), ``clearance`` its p [m] (landmarks must be
    farther than p from the route), ``fov`` ``"sector"`` ([Placement Lemma 2]) or
    ``"circular"`` ([Placement Cor. 1]).  Defaults are [Placement §III-A]'s.
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
            rel_b = wrap_angle(np.arctan2(rel[:, 1], rel[:, 0]) - heading)
            ok &= np.abs(rel_b) <= self.angle / 2
        return ok


def camera_params(camera) -> CameraParams:
    """``camera`` as :class:`CameraParams`: None gives the paper's defaults, a dict its fields."""
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


def check_route(route) -> np.ndarray:
    """``route`` as an (n, 2) array of n >= 2 points, with no edge of zero length."""
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


def occluders(obstacles) -> "_core.Occluders | None":
    """``obstacles`` as the core's :class:`~safenav._core.Occluders`, or None
    for none (the paper: nothing hides a landmark).

    Accepts None, a :class:`safenav.World` (its circle and polygon
    obstacles, not grown; hazards do not hide), a
    :class:`~safenav._core.PlanningMap`, a :class:`~safenav._core.Occluders`,
    or a dict ``{"circles": [[x, y, radius], ...], "polygons": [[[x, y],
    ...], ...]}``.  An empty set gives None, so results are bit for bit
    those without occlusion.  Raises ``ValueError`` naming a bad obstacle.
    """
    if obstacles is None:
        return None
    if isinstance(obstacles, _core.Occluders):
        occ = obstacles
    elif isinstance(obstacles, _core.PlanningMap):
        occ = _core.Occluders.from_map(obstacles)
    elif hasattr(obstacles, "obstacle_arrays"):          # a safenav World
        circles, polygons = obstacles.obstacle_arrays()
        occ = _core.Occluders(circles, polygons)
    elif isinstance(obstacles, dict):
        bad = sorted(set(obstacles) - {"circles", "polygons"})
        if bad:
            raise ValueError(f"obstacles: unknown key {bad[0]!r} (known: circles, polygons)")
        circ = obstacles.get("circles", [])
        circles = as_array("obstacles.circles", circ, (None, 3)) if len(circ) else np.zeros((0, 3))
        polys = obstacles.get("polygons", [])
        if not isinstance(polys, (list, tuple)):
            raise ValueError(f"obstacles.polygons must be a list of vertex lists, got {polys!r}")
        polygons = [as_array(f"obstacles.polygons[{i}]", p, (None, 2)) for i, p in enumerate(polys)]
        occ = _core.Occluders(circles, polygons)
    else:
        raise ValueError(f"obstacles = {obstacles!r} must be None, a World, a PlanningMap, an Occluders "
                         "or a dict with 'circles' and 'polygons'")
    return None if occ.empty() else occ


def _occ_kw(obstacles) -> dict:
    occ = occluders(obstacles)
    return {} if occ is None else {"occluders": occ}


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
    obstacles: object = None          #: the occluders (``_core.Occluders``) or None: nothing hides a landmark

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
                              corners=self.corners if corners is None else corners, obstacles=self.obstacles)

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
            "occlusion": self.obstacles is not None,
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
                      allow_uncovered: bool = False, obstacles=None) -> PlacementResult:
    """The paper's placement on a given route [Placement §II]: per edge the
    greedy k-interval cover [Placement Alg. 1] (generalised to k ≥ 1), then
    the union over the edges [Placement §II-B].

    ``distinct_bearings=False`` runs Algorithm 1 verbatim.  With the default
    ``True`` ([Placement LPP cond. 2], non-coincidence): of the candidates
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

    ``obstacles`` (see :func:`occluders`; ours, not the paper's): a
    candidate an obstacle hides from part of an edge does not cover that
    part.  Each candidate then covers the pieces of its [Placement Lemma 2]
    interval left by the shadows, and the greedy works with pieces (taking a
    piece places the landmark, and its other pieces count too).  The greedy
    remains a valid cover but is no longer optimal per edge: [Placement
    Prop. 1] assumes one interval per landmark.  The certificate counts a
    landmark only where it is not hidden.
    """
    cam = camera_params(camera)
    r, c, k = check_route(route), _candidates(candidates), _k(k)
    occ = _occ_kw(obstacles)
    opt = _core.PlacementOptions()
    opt.k, opt.corners, opt.reuse, opt.distinct_bearings = k, bool(corners), bool(reuse), bool(distinct_bearings)
    t0 = time.perf_counter()
    p = _core.place_landmarks(r, c, cam.to_core(), opt, **occ)
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
                           uncovered=unc, too_close=np.array(p.too_close, dtype=int), seconds=sec,
                           obstacles=occ.get("occluders"))


def check_coverage(route, landmarks, camera: CameraParams | dict | None = None, *, k: int = 2,
                   corners: bool = False, obstacles=None) -> "_core.CoverageReport":
    """Exact check: at every interval endpoint, alignment point, on-line
    landmark and the midpoint between consecutive ones, count the distinct
    bearings in view (DESIGN: check coverage at interval endpoints, not at
    sample points; the count is constant in between).  Landmarks must be
    pairwise distinct.  The report has ``min_count``,
    ``min_distance`` (closest landmark to the route) and the deficient
    stretches (``kind`` 0 edge / 1 corner, ``index``, ``start``, ``end``).

    With ``obstacles`` (:func:`occluders`) a landmark counts only where no
    obstacle hides it (the ends of its pieces are checked too); its pieces
    are shrunk by ~1e-9 m next to each shadow, so the check never counts a
    hidden landmark."""
    cam = camera_params(camera)
    lm = as_array("landmarks", landmarks, (None, 2))
    r, k = check_route(route), _k(k)
    return _core.check_coverage(r, lm, cam.to_core(), k, bool(corners), **_occ_kw(obstacles))


# ---------------------------------------------------------------------------
# Global optimum: integer program over interval endpoints (HiGHS)
# ---------------------------------------------------------------------------

def place_optimal(route, candidates, camera: CameraParams | dict | None = None, *, k: int = 2,
                  corners: bool = False, distinct_bearings: bool = True, time_limit: float = 120.0,
                  allow_uncovered: bool = False, obstacles=None) -> PlacementResult:
    """The fewest landmarks for the whole route at once: an integer program
    solved with ``scipy.optimize.milp`` (HiGHS).

    Variables: ``x_ℓ ∈ {0, 1}`` per candidate with a non-empty
    [Placement Lemma 2] interval on some edge (or turn); minimise ``Σ x_ℓ``.
    One row per point of each edge where coverage can change — every interval endpoint, every
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

    With ``obstacles`` (:func:`occluders`) the tables have one row per
    piece of a candidate's interval left by the shadows; a probe counts a
    candidate at most once, and piece ends are rows too, so the program
    stays exact (up to the pieces' ~1e-9 m shrink next to a shadow).
    """
    cam = camera_params(camera)
    r, c, k = check_route(route), _candidates(candidates), _k(k)
    if isinstance(time_limit, bool) or not isinstance(time_limit, (int, float, np.integer, np.floating)) \
            or not (math.isfinite(time_limit) and time_limit > 0):
        raise ValueError(f"time_limit = {time_limit!r} must be a finite number of seconds > 0")
    core_cam = cam.to_core()
    occ = _occ_kw(obstacles)
    t0 = time.perf_counter()
    too_close = np.flatnonzero(_core.distance_to_route(r, c) <= cam.clearance)
    program = CoverProgram(k, distinct_bearings)
    vis = _core.edge_visibility(r, c, core_cam, **occ)
    al = _core.alignments(r, c, core_cam, **occ) if distinct_bearings else None
    for e in range(len(r) - 1):
        program.add_edge(e, float(np.hypot(*(r[e + 1] - r[e]))), vis, vis.edge == e,
                         al.t[al.edge == e] if al is not None else None, bool(occ))
    if corners:
        cv = _core.corner_visibility(r, c, core_cam, **occ)
        turns = _core.turn_angles(r)
        for v in range(1, len(r) - 1):
            if abs(float(turns[v - 1])) > _EPS:
                program.add_corner(v, abs(float(turns[v - 1])), cv, cv.edge == v)
    unc = _merge_uncovered(program.uncovered)
    if unc and not allow_uncovered:
        raise ValueError(_describe_uncovered(r, unc, k))
    chosen, optimal = (np.zeros(0, int), True) if not program.col_of else program.solve(time_limit)
    return PlacementResult(route=r, candidates=c, indices=chosen, camera=cam, k=k,
                           method="optimal" + ("+corners" if corners else ""), corners=bool(corners),
                           uncovered=_exact_uncovered(r, c[chosen], cam, k, corners, occ),
                           too_close=too_close, seconds=time.perf_counter() - t0, optimal=optimal,
                           obstacles=occ.get("occluders"))


def _exact_uncovered(route, landmarks, cam: CameraParams, k: int, corners: bool, occ: dict | None = None) -> list:
    """The certificate: the stretches the exact check finds with fewer than k
    distinct bearings, as ``[(where, index, start, end)]``."""
    rep = _core.check_coverage(route, landmarks, cam.to_core(), k, corners, **(occ or {}))
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
                     allow_uncovered: bool = False, occlusion: bool = False) -> PlacementResult:
    """Landmarks along a SafeNav safe path (a polyline, e.g. from
    :meth:`safenav.World.path_polyline`, or a :func:`safenav.planning.plan`
    result) so
    that a vehicle on it always has ``k`` landmarks in view.

    Without ``candidates`` a grid of ``spacing`` within R of the path is used;
    with a ``world`` candidates inside obstacles or outside the field are
    dropped.  Consecutive repeated path points are merged.  ``occlusion``
    (needs ``world``): the world's obstacles hide landmarks (see
    :func:`place_along_route`).  Off by default here, so that results stay
    those of the paper's model; :func:`safenav.experiments.placed_scenario`
    and ``safenav place`` turn it on.
    """
    cam = camera_params(camera)
    if hasattr(path, "path") and not isinstance(path, np.ndarray):  # a planner's PlanResult
        if not getattr(path, "success", True):
            raise ValueError("the plan has no path (planning did not succeed)")
        path = path.path
    p = as_array("path", path, (None, 2))
    if p.shape[0] < 2:
        raise ValueError(f"path must have at least 2 points, got {p.shape[0]}")
    keep = np.concatenate([[True], np.hypot(*np.diff(p, axis=0).T) > 1e-12])
    p = check_route(p[keep])
    if candidates is None:
        c = candidate_grid(p.min(axis=0), p.max(axis=0), spacing, margin=cam.range)
        c = c[_core.distance_to_route(p, c) <= cam.range]
    else:
        c = _candidates(candidates)
    if world is not None:
        c = c[~world.obstacle_mask(c) & world.field.contains(c)]
    if len(c) == 0:
        raise ValueError("no candidate locations left around the path (all inside obstacles or outside the field)")
    if occlusion and world is None:
        raise ValueError("occlusion = True needs a world (its obstacles hide landmarks)")
    obstacles = world if occlusion else None
    return place_through_targets(None, c, cam, k=k, corners=corners, method=method, route=p,
                                 allow_uncovered=allow_uncovered, obstacles=obstacles)



"""The battlefield world of SafeNav [SafeNav-ext §V-A3(ii), Fig. 1].

[SafeNav-ext §V-A3(ii)] is [SafeNav-conf §V-A.2(ii)]; the conference has no
figure of the field (its Fig. 1 is the framework).

A rectangular :class:`Field` holding

* obstacles — :class:`Circle` or :class:`Polygon` shapes the vehicle may not enter;
* hazards — a shape with a risk level (:class:`Hazard`); passable, but risky;
* landmarks — :class:`Landmark` with an id, a 2D or 3D position, a class and
  the cluster it belongs to.  Clusters are the paper's trilateration sets; a
  ground-truth path is the polyline through the centroids of a sequence of
  clusters (:class:`PathType`, :meth:`World.path_polyline`).

Every type is a frozen dataclass that validates itself on construction.  An
error is a :class:`ScenarioError` (a ``ValueError``) whose message starts
with the field's path relative to the object, then the bad value, e.g.
``obstacles[3].radius = -2.0: must be in (0, 100000]``; :mod:`safenav.scenario` prefixes
the path of the enclosing object (``world.obstacles[3].radius``).

Collision queries are the core's (``safenav/world.hpp``, ``ObstacleChecker`` on
CGAL's exact predicates): a world builds the core's map of itself on first use.
A point on an obstacle's boundary is inside it; the ``margin`` argument grows
every obstacle by exactly that distance.  Segment tests are exact (no
sampling), so a segment that grazes a corner is caught.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Iterable, Sequence, Union

import numpy as np

from . import _core
from .validation import (FIELD_SIZE, MAX_COORDINATE, MAX_HAZARDS, MAX_LANDMARKS, MAX_OBSTACLES,  # noqa: F401
                         MAX_PATH_CLUSTERS, MAX_RADIUS, MAX_VERTICES, ScenarioError, as_array, at, cut, fail, integer,
                         items, real, table, text, vector)

__all__ = [
    "ScenarioError", "Field", "Circle", "Polygon", "Shape", "Hazard", "Landmark",
    "PathType", "World",
]


class _CoreQueries:
    """Collision queries answered by the core's :class:`~safenav._core.ObstacleChecker`.

    The checker of ``core_map()`` is built on first use and cached on the
    (frozen) object; pickling leaves it out.
    """

    @cached_property
    def _checker(self) -> _core.ObstacleChecker:
        return _core.ObstacleChecker(self.core_map())

    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k != "_checker"}


def _points(points) -> np.ndarray:
    return np.asarray(points, dtype=float).reshape(-1, 2)


# --------------------------------------------------------------------------- shapes

@dataclass(frozen=True)
class Field:
    """The rectangular field ``[x_min, x_max] × [y_min, y_max]`` in metres."""

    x_min: float = 0.0
    y_min: float = 0.0
    x_max: float = 200.0
    y_max: float = 200.0

    def __post_init__(self):
        for n in ("x_min", "y_min", "x_max", "y_max"):
            object.__setattr__(self, n, real(n, getattr(self, n), lo=-MAX_COORDINATE, hi=MAX_COORDINATE))
        lo, hi = FIELD_SIZE
        for n, size in (("x_max", self.width), ("y_max", self.height)):
            if not lo <= size <= hi:
                low = n.replace("max", "min")
                fail(n, getattr(self, n), f"makes the field's {'width' if n == 'x_max' else 'height'} {size:g} m "
                     f"({n} - {low}, {low} = {getattr(self, low):g}); it must be in [{lo:g}, {hi:g}] m")

    @property
    def width(self) -> float:
        return self.x_max - self.x_min

    @property
    def height(self) -> float:
        return self.y_max - self.y_min

    @property
    def bounds(self) -> np.ndarray:
        """``[[x_min, y_min], [x_max, y_max]]`` (for a planner's state space)."""
        return np.array([[self.x_min, self.y_min], [self.x_max, self.y_max]])

    def contains(self, points) -> np.ndarray:
        """Which of the ``(N, 2)`` points lie in the field (boundary included)."""
        p = np.asarray(points, dtype=float).reshape(-1, 2)
        return ((p[:, 0] >= self.x_min) & (p[:, 0] <= self.x_max)
                & (p[:, 1] >= self.y_min) & (p[:, 1] <= self.y_max))

    def describe(self) -> str:
        return f"[{self.x_min:g}, {self.x_max:g}] x [{self.y_min:g}, {self.y_max:g}]"


@dataclass(frozen=True)
class Circle(_CoreQueries):
    """A disc: ``center`` (x, y) and ``radius`` > 0, in metres."""

    center: tuple[float, float]
    radius: float

    kind = "circle"

    def __post_init__(self):
        object.__setattr__(self, "center", vector("center", self.center, (2,)))
        object.__setattr__(self, "radius", real("radius", self.radius, lo=0.0, lo_open=True, hi=MAX_RADIUS))

    def bounding_circle(self) -> tuple[np.ndarray, float]:
        return np.array(self.center), self.radius

    def contains(self, points, margin: float = 0.0) -> np.ndarray:
        """Which of the ``(N, 2)`` points lie in the disc grown by ``margin`` (boundary inside)."""
        return self._checker.obstacles_at(_points(points), margin)[:, 0]

    def segment_hits(self, a, b, margin: float = 0.0) -> bool:
        """Whether the segment ``ab`` touches the disc grown by ``margin``."""
        return bool(self._checker.obstacles_hit(_points(a), _points(b), margin)[0, 0])

    def core_map(self) -> _core.PlanningMap:
        return _core.PlanningMap(circles=[_core.CircleObstacle(self.center, self.radius)])

    def _outside_field(self, fld: Field) -> str | None:
        (x, y), r = self.center, self.radius
        if not fld.contains([(x, y)])[0]:
            return f"center = {self.center!r}: lies outside the field {fld.describe()}"
        if x - r < fld.x_min or x + r > fld.x_max or y - r < fld.y_min or y + r > fld.y_max:
            return (f"radius = {r!r}: the circle at {self.center!r} extends outside the field "
                    f"{fld.describe()}")
        return None

    def to_dict(self) -> dict:
        return {"type": "circle", "center": list(self.center), "radius": self.radius}


@dataclass(frozen=True)
class Polygon(_CoreQueries):
    """A simple polygon given by its ``vertices`` ((x, y) pairs, at least 3, either orientation)."""

    vertices: tuple[tuple[float, float], ...]

    kind = "polygon"

    def __post_init__(self):
        verts = items("vertices", self.vertices, MAX_VERTICES)
        if len(verts) < 3:
            fail("vertices", self.vertices, f"a polygon needs at least 3 vertices, got {len(verts)}")
        verts = tuple(vector(f"vertices[{i}]", v, (2,)) for i, v in enumerate(verts))
        object.__setattr__(self, "vertices", verts)
        v = np.array(verts)
        if not _core.is_simple_polygon(v):      # CGAL's O(n log n) sweep, exact predicates
            if np.linalg.matrix_rank(v - v[0]) < 2:
                fail("vertices", verts, "the polygon has zero area: its vertices lie on one line")
            fail("vertices", verts, "the polygon is not simple: two edges cross or touch, or a vertex repeats")
        area = 0.5 * abs(np.dot(v[:, 0], np.roll(v[:, 1], -1)) - np.dot(v[:, 1], np.roll(v[:, 0], -1)))
        if not area > 1e-12:
            fail("vertices", verts, "the polygon has zero area")

    def array(self) -> np.ndarray:
        """The vertices as an ``(M, 2)`` array."""
        return np.array(self.vertices)

    def bounding_circle(self) -> tuple[np.ndarray, float]:
        v = self.array()
        c = v.mean(axis=0)
        return c, float(np.max(np.hypot(*(v - c).T)))

    def contains(self, points, margin: float = 0.0) -> np.ndarray:
        """Which of the ``(N, 2)`` points lie in the polygon grown by ``margin`` (boundary inside)."""
        return self._checker.obstacles_at(_points(points), margin)[:, 0]

    def segment_hits(self, a, b, margin: float = 0.0) -> bool:
        """Whether the segment ``ab`` touches the polygon grown by ``margin`` (exact, CGAL)."""
        return bool(self._checker.obstacles_hit(_points(a), _points(b), margin)[0, 0])

    def core_map(self) -> _core.PlanningMap:
        return _core.PlanningMap(polygons=[self.array()])

    def _outside_field(self, fld: Field) -> str | None:
        inside = fld.contains(self.array())
        if not inside.all():
            k = int(np.argmin(inside))
            return f"vertices[{k}] = {self.vertices[k]!r}: lies outside the field {fld.describe()}"
        return None

    def to_dict(self) -> dict:
        return {"type": "polygon", "vertices": [list(v) for v in self.vertices]}


Shape = Union[Circle, Polygon]


@dataclass(frozen=True)
class Hazard:
    """A hazard zone: a :data:`Shape` with a ``risk`` level in (0, 1] (1 = most dangerous).

    The paper gives hazards no numeric scale; the risk level is ours.
    """

    shape: Shape
    risk: float = 1.0

    def __post_init__(self):
        if not isinstance(self.shape, (Circle, Polygon)):
            fail("shape", self.shape, "must be a Circle or a Polygon")
        object.__setattr__(self, "risk", real("risk", self.risk, lo=0.0, lo_open=True, hi=1.0))

    def to_dict(self) -> dict:
        return {**self.shape.to_dict(), "risk": self.risk}


@dataclass(frozen=True)
class Landmark:
    """A landmark: ``id``, ``position`` (x, y) or (x, y, z) in metres, ``class_name``, ``cluster`` id.

    ``class_name`` is the detector's class (``class`` in scenario files); the
    cluster is the trilateration set the landmark belongs to.
    """

    id: int
    position: tuple[float, ...]
    class_name: str = "landmark"
    cluster: int = 0

    def __post_init__(self):
        object.__setattr__(self, "id", integer("id", self.id, 0, field=True))
        object.__setattr__(self, "position", vector("position", self.position, (2, 3)))
        object.__setattr__(self, "class_name", text("class", self.class_name))
        object.__setattr__(self, "cluster", integer("cluster", self.cluster, 0, field=True))

    @property
    def xy(self) -> np.ndarray:
        return np.array(self.position[:2])

    @property
    def height(self) -> float:
        """z, or 0 for a 2D landmark."""
        return self.position[2] if len(self.position) == 3 else 0.0

    def to_dict(self) -> dict:
        return {"id": self.id, "position": list(self.position), "class": self.class_name,
                "cluster": self.cluster}


@dataclass(frozen=True)
class PathType:
    """A path cluster: a ``name`` and the ``clusters`` it visits, start first, destination last.

    The ground truth is the polyline through the clusters' centroids
    (:meth:`World.path_polyline`); the paper's P1 is clusters 6 → … → 3.
    """

    name: str
    clusters: tuple[int, ...]

    def __post_init__(self):
        text("name", self.name)
        ids = items("clusters", self.clusters, MAX_PATH_CLUSTERS)
        if len(ids) < 2:
            fail("clusters", self.clusters, "a path needs a start and a destination cluster")
        ids = tuple(integer(f"clusters[{i}]", c, 0, field=True) for i, c in enumerate(ids))
        for i in range(1, len(ids)):
            if ids[i] == ids[i - 1]:
                fail(f"clusters[{i}]", ids[i], "repeats the previous cluster")
        object.__setattr__(self, "clusters", ids)

    @property
    def start(self) -> int:
        return self.clusters[0]

    @property
    def destination(self) -> int:
        return self.clusters[-1]

    def to_dict(self) -> dict:
        return {"name": self.name, "start": self.start, "clusters": list(self.clusters),
                "destination": self.destination}


# --------------------------------------------------------------------------- world

@dataclass(frozen=True)
class World(_CoreQueries):
    """The field with its obstacles, hazards and landmarks (SafeNav Fig. 1).

    Validation: every obstacle and hazard lies wholly inside the field, every
    landmark's (x, y) lies in the field, and landmark ids are unique.
    """

    field: Field = field(default_factory=Field)
    obstacles: tuple[Shape, ...] = ()
    hazards: tuple[Hazard, ...] = ()
    landmarks: tuple[Landmark, ...] = ()

    def __post_init__(self):
        if not isinstance(self.field, Field):
            fail("field", self.field, "must be a Field")
        for name, kinds, limit in (("obstacles", (Circle, Polygon), MAX_OBSTACLES), ("hazards", (Hazard,), MAX_HAZARDS),
                                   ("landmarks", (Landmark,), MAX_LANDMARKS)):
            entries = items(name, getattr(self, name), limit)
            for i, it in enumerate(entries):
                if not isinstance(it, kinds):
                    fail(f"{name}[{i}]", it, f"must be a {' or '.join(k.__name__ for k in kinds)}")
            object.__setattr__(self, name, entries)
        for i, ob in enumerate(self.obstacles):
            msg = ob._outside_field(self.field)
            if msg:
                raise ScenarioError(f"obstacles[{i}].{msg}")
        for i, hz in enumerate(self.hazards):
            msg = hz.shape._outside_field(self.field)
            if msg:
                raise ScenarioError(f"hazards[{i}].{msg}")
        seen: dict[int, int] = {}
        for i, lm in enumerate(self.landmarks):
            if not self.field.contains([lm.position[:2]])[0]:
                fail(f"landmarks[{i}].position", lm.position, f"lies outside the field {self.field.describe()}")
            if lm.id in seen:
                fail(f"landmarks[{i}].id", lm.id, f"duplicates landmarks[{seen[lm.id]}].id")
            seen[lm.id] = i

    # ---- obstacles, ready for a planner
    def circle_array(self) -> np.ndarray:
        """Circular obstacles as a ``(K, 3)`` array of ``(x, y, radius)``."""
        rows = [(*o.center, o.radius) for o in self.obstacles if isinstance(o, Circle)]
        return np.array(rows, dtype=float).reshape(-1, 3)

    def polygon_arrays(self) -> list[np.ndarray]:
        """Polygonal obstacles as a list of ``(M, 2)`` vertex arrays."""
        return [o.array() for o in self.obstacles if isinstance(o, Polygon)]

    def obstacle_arrays(self) -> tuple[np.ndarray, list[np.ndarray]]:
        """``(circles (K, 3), polygons [(M, 2), ...])`` — the obstacles in planner form."""
        return self.circle_array(), self.polygon_arrays()

    def hazard_arrays(self) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
        """``(circles (K, 4) as x, y, radius, risk; polygons [(M, 2)]; polygon risks (P,))``."""
        circ = [(*h.shape.center, h.shape.radius, h.risk) for h in self.hazards if isinstance(h.shape, Circle)]
        polys = [h for h in self.hazards if isinstance(h.shape, Polygon)]
        return (np.array(circ, dtype=float).reshape(-1, 4), [h.shape.array() for h in polys],
                np.array([h.risk for h in polys], dtype=float))

    # ---- collision queries: the core's ObstacleChecker answers them all
    def core_map(self, clearance: float = 0.0) -> _core.PlanningMap:
        """This world as the core's map: the field, the obstacles (circles, then polygons), the hazards,
        and ``clearance`` [m], the distance to keep from every obstacle."""
        circles, polygons = self.obstacle_arrays()
        zone = _core.HazardZone
        hazards = [zone.from_circle(h.shape.center, h.shape.radius, h.risk) if isinstance(h.shape, Circle)
                   else zone.from_polygon(h.shape.array(), h.risk) for h in self.hazards]
        return _core.PlanningMap(lower=self.field.bounds[0], upper=self.field.bounds[1],
                                 circles=[_core.CircleObstacle(c[:2], c[2]) for c in circles], polygons=polygons,
                                 clearance=clearance, hazards=hazards)

    @cached_property
    def _core_order(self) -> np.ndarray:
        """Column k of a core answer is obstacle ``_core_order[k]`` (the core lists circles first)."""
        kinds = [isinstance(o, Circle) for o in self.obstacles]
        return np.array([i for i, c in enumerate(kinds) if c] + [i for i, c in enumerate(kinds) if not c], dtype=int)

    def _in_world_order(self, hits: np.ndarray) -> np.ndarray:
        out = np.empty_like(hits)
        out[:, self._core_order] = hits
        return out

    def obstacles_containing(self, points, margin: float = 0.0) -> np.ndarray:
        """``(N, M)`` bool: point i lies in obstacle j grown by ``margin`` (boundary inside)."""
        return self._in_world_order(self._checker.obstacles_at(_points(points), margin))

    def obstacles_hit_by_segments(self, a, b, margin: float = 0.0) -> np.ndarray:
        """``(N, M)`` bool: the segment ``a[i] b[i]`` touches obstacle j grown by ``margin``.

        Exact (CGAL's predicates for polygon containment and edge crossings; no
        sampling), so a segment that grazes a corner is caught.
        """
        return self._in_world_order(self._checker.obstacles_hit(_points(a), _points(b), margin))

    def obstacle_mask(self, points, margin: float = 0.0) -> np.ndarray:
        """Which of the ``(N, 2)`` points lie in an obstacle grown by ``margin`` (boundary inside)."""
        return self._checker.obstacles_at(_points(points), margin).any(axis=1)

    def first_obstacle_at(self, points, margin: float = 0.0) -> np.ndarray:
        """Per ``(N, 2)`` point: the index of the first obstacle grown by ``margin`` that contains it, or −1."""
        hit = self.obstacles_containing(points, margin)
        first = np.c_[hit, np.ones(len(hit), dtype=bool)].argmax(axis=1)     # a last column that always hits
        return np.where(first < hit.shape[1], first, -1)

    def point_in_obstacle(self, point, margin: float = 0.0) -> bool:
        """Whether the (x, y) ``point`` lies in some obstacle grown by ``margin``."""
        return bool(self.obstacle_mask(np.asarray(point, dtype=float)[:2], margin)[0])

    def obstacles_at(self, point, margin: float = 0.0) -> list[int]:
        """Indices of the obstacles containing ``point``."""
        return np.flatnonzero(self.obstacles_containing(np.asarray(point, dtype=float)[:2], margin)[0]).tolist()

    def segment_hits_obstacle(self, a, b, margin: float = 0.0) -> bool:
        """Whether the segment ``ab`` touches an obstacle grown by ``margin`` (exact, see
        :meth:`obstacles_hit_by_segments`)."""
        a, b = np.asarray(a, dtype=float)[:2], np.asarray(b, dtype=float)[:2]
        return bool(self._checker.obstacles_hit(_points(a), _points(b), margin).any())

    def obstacles_hit_by(self, polyline, margin: float = 0.0) -> list[int]:
        """Indices of the obstacles that the ``(N, 2)`` polyline touches."""
        pts = _points(polyline)
        return np.flatnonzero(self.obstacles_hit_by_segments(pts[:-1], pts[1:], margin).any(axis=0)).tolist()

    def polyline_hits_obstacle(self, polyline, margin: float = 0.0) -> bool:
        pts = _points(polyline)
        return bool(self._checker.obstacles_hit(pts[:-1], pts[1:], margin).any())

    def hazard_risk(self, points) -> np.ndarray:
        """The highest hazard risk at each ``(N, 2)`` point (0 outside every hazard; boundary inside)."""
        return self._checker.hazard_risk(_points(points))

    # ---- occlusion: the core's one line-of-sight query
    def line_of_sight(self, a, b) -> bool:
        """Whether ``b`` is seen from ``a`` (both ``(x, y)``): the segment ``ab`` meets no obstacle.

        The obstacles themselves, not grown by any margin, and exact
        (``ObstacleChecker::line_of_sight``, CGAL's exact predicates): touching an
        obstacle's boundary blocks, but an obstacle containing ``a`` or ``b``
        (boundary included) does not, so a landmark on a boulder is seen from
        outside it.  Obstacles hide anything behind them (heights are not
        modelled); hazards hide nothing.  Symmetric: ``line_of_sight(b, a)``
        gives the same answer, exactly, at any finite coordinates; landmark
        placement's sight test is the same predicate.  ``ValueError`` names a
        non-finite or misshapen ``a`` or ``b``.
        """
        return bool(self._checker.line_of_sight(as_array("a", a, (2,)), as_array("b", b, (2,))))

    def visible_from(self, p, points) -> np.ndarray:
        """``(N,)`` bool: :meth:`line_of_sight` from ``p`` to each of the ``(N, 2)`` ``points``."""
        return self._checker.visible_from(as_array("p", p, (2,)), as_array("points", points, (None, 2)))

    # ---- landmarks and clusters
    def landmark_array(self) -> np.ndarray:
        """Landmark positions as ``(L, 3)`` (z = 0 for 2D landmarks)."""
        return np.array([(*lm.position[:2], lm.height) for lm in self.landmarks], dtype=float).reshape(-1, 3)

    @property
    def cluster_ids(self) -> tuple[int, ...]:
        return tuple(sorted({lm.cluster for lm in self.landmarks}))

    def clusters(self) -> dict[int, tuple[Landmark, ...]]:
        """Landmarks grouped by cluster id (ids ascending)."""
        out: dict[int, list[Landmark]] = {c: [] for c in self.cluster_ids}
        for lm in self.landmarks:
            out[lm.cluster].append(lm)
        return {c: tuple(v) for c, v in out.items()}

    def cluster_landmarks(self, cluster: int) -> tuple[Landmark, ...]:
        lms = tuple(lm for lm in self.landmarks if lm.cluster == cluster)
        if not lms:
            raise ScenarioError(f"cluster = {cut(cluster)}: no landmark belongs to it (known: {cut(list(self.cluster_ids))})")
        return lms

    def cluster_centroid(self, cluster: int) -> np.ndarray:
        """The (x, y) mean of the cluster's landmarks."""
        return np.mean([lm.xy for lm in self.cluster_landmarks(cluster)], axis=0)

    def cluster_centroids(self) -> dict[int, np.ndarray]:
        return {c: np.mean([lm.xy for lm in lms], axis=0) for c, lms in self.clusters().items()}

    def landmarks_in_range(self, point, max_range: float, cluster: int | None = None) -> tuple[Landmark, ...]:
        """Landmarks within ``max_range`` of the ground point ``point`` (3D distance; z counts)."""
        p = np.asarray(point, dtype=float)[:2]
        cand = self.landmarks if cluster is None else self.cluster_landmarks(cluster)
        return tuple(lm for lm in cand if math.hypot(*(lm.xy - p), lm.height) <= max_range)

    def path_polyline(self, path_type: PathType | Iterable[int]) -> np.ndarray:
        """The ground-truth ``(n, 2)`` polyline through the centroids of the path's clusters."""
        ids = path_type.clusters if isinstance(path_type, PathType) else tuple(path_type)
        return np.array([self.cluster_centroid(c) for c in ids])

    # ---- serialisation
    def to_dict(self) -> dict:
        return {
            "field": {"x_min": self.field.x_min, "y_min": self.field.y_min,
                      "x_max": self.field.x_max, "y_max": self.field.y_max},
            "obstacles": [o.to_dict() for o in self.obstacles],
            "hazards": [h.to_dict() for h in self.hazards],
            "landmarks": [lm.to_dict() for lm in self.landmarks],
        }

    @classmethod
    def from_dict(cls, data) -> "World":
        """Build from a ``to_dict``-shaped mapping; errors name the field path (``obstacles[3].radius``)."""
        d = table("", data, required=(), optional=("field", "obstacles", "hazards", "landmarks"))
        with at("field"):
            f = table("", d.get("field", {}), required=(), optional=("x_min", "y_min", "x_max", "y_max"))
            fld = Field(**f)
        obstacles = []
        for i, o in enumerate(items("obstacles", d.get("obstacles", []), MAX_OBSTACLES)):
            with at(f"obstacles[{i}]"):
                obstacles.append(_shape_from_dict(o, extra=()))
        hazards = []
        for i, h in enumerate(items("hazards", d.get("hazards", []), MAX_HAZARDS)):
            with at(f"hazards[{i}]"):
                shape = _shape_from_dict(h, extra=("risk",))
                hazards.append(Hazard(shape, h.get("risk", 1.0)))
        landmarks = []
        for i, lm in enumerate(items("landmarks", d.get("landmarks", []), MAX_LANDMARKS)):
            with at(f"landmarks[{i}]"):
                t = table("", lm, required=("id", "position"), optional=("class", "cluster"))
                landmarks.append(Landmark(t["id"], t["position"], t.get("class", "landmark"), t.get("cluster", 0)))
        return cls(fld, tuple(obstacles), tuple(hazards), tuple(landmarks))


def _shape_from_dict(d, extra: Sequence[str]) -> Shape:
    t = table("", d, required=("type",), optional=("center", "radius", "vertices", *extra))
    kind = t["type"]
    if kind == "circle":
        table("", t, required=("type", "center", "radius"), optional=extra)
        return Circle(t["center"], t["radius"])
    if kind == "polygon":
        table("", t, required=("type", "vertices"), optional=extra)
        return Polygon(t["vertices"])
    fail("type", kind, 'must be "circle" or "polygon"')

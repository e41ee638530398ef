"""The battlefield world of SafeNav (section V-A(3)(ii), Fig. 1).

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

Geometry conventions: a point on an obstacle's boundary is inside it; the
``margin`` argument inflates every obstacle by that distance.  Segment tests
are exact (no sampling), so a segment that grazes a corner is caught.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Sequence, Union

import numpy as np
from matplotlib.path import Path as _MplPath

from . import _core
from ._checks import INT32_MAX, cut

__all__ = [
    "ScenarioError", "Field", "Circle", "Polygon", "Shape", "Hazard", "Landmark",
    "PathType", "World",
]


class ScenarioError(ValueError):
    """A world or scenario field is invalid; the message names the field and its value."""


# --------------------------------------------------------------------------- validation helpers

def _join(prefix: str, msg: str) -> str:
    if not prefix:
        return msg
    if msg.startswith("["):
        return prefix + msg
    if msg.startswith(("=", ":")):
        return f"{prefix} {msg}" if msg.startswith("=") else prefix + msg
    return f"{prefix}.{msg}"


class _at:
    """Context manager: re-raise a ``ValueError`` with ``prefix`` prepended to its field path."""

    def __init__(self, prefix: str):
        self.prefix = prefix

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None and issubclass(exc_type, ValueError):
            raise ScenarioError(_join(self.prefix, str(exc))) from None
        return False


def _fail(name: str, value, problem: str):
    raise ScenarioError(f"{name} = {cut(value)}: {problem}")


# --------------------------------------------------------------------------- limits
# Every coordinate and collection is bounded (docs/scenario.md gives the reasons),
# so that no file, however large its numbers or lists, hangs validation or planning.

MAX_COORDINATE = 1e6         #: |x|, |y|, |z| of every point [m]
FIELD_SIZE = (1.0, 1e5)      #: the field's width and height [m]
MAX_RADIUS = 1e5             #: of a circle [m]
MAX_OBSTACLES = 1000
MAX_HAZARDS = 1000
MAX_LANDMARKS = 10_000
MAX_VERTICES = 1000          #: of one polygon
MAX_PATH_CLUSTERS = 100      #: clusters on one path type
MAX_NAME = 200               #: characters of a name or a landmark class


def _interval(lo: float, hi: float, lo_open: bool = False) -> str:
    return f"{'(' if lo_open else '['}{lo:g}, {hi:g}]"


@dataclass(frozen=True)
class Range:
    """The valid values of a scalar parameter: ``[lo, hi]`` (``(lo, hi]`` if ``lo_open``); ``integer`` for counts."""

    lo: float
    hi: float
    lo_open: bool = False
    integer: bool = False

    def check(self, name: str, value):
        if self.integer:
            return _integer(name, value, lo=int(self.lo), hi=int(self.hi))
        return _real(name, value, lo=self.lo, lo_open=self.lo_open, hi=self.hi)

    def __str__(self) -> str:
        return f"[{int(self.lo)}, {int(self.hi)}]" if self.integer else _interval(self.lo, self.hi, self.lo_open)


def _real(name: str, value, *, lo: float, hi: float, lo_open: bool = False) -> float:
    """``value`` as a finite float (ints accepted, bools and strings not) in ``[lo, hi]`` (``(lo, hi]``)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        _fail(name, value, "must be a number")
    try:
        v = float(value)
    except OverflowError:                       # an integer too large for a float
        v = math.inf if value > 0 else -math.inf
    if not math.isfinite(v):
        _fail(name, value, "must be finite")
    if not (lo < v <= hi if lo_open else lo <= v <= hi):
        _fail(name, value, f"must be in {_interval(lo, hi, lo_open)}")
    return v


def _integer(name: str, value, *, lo: int = 0, hi: int = INT32_MAX) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        _fail(name, value, "must be an integer")
    v = int(value)
    if not lo <= v <= hi:
        _fail(name, value, f"must be in [{lo}, {hi}]")
    return v


def _text(name: str, value, max_len: int = MAX_NAME) -> str:
    if not isinstance(value, str) or not value.strip():
        _fail(name, value, "must be a non-empty string")
    if len(value) > max_len:
        _fail(name, value, f"has {len(value)} characters, at most {max_len} allowed")
    return value


def _vector(name: str, value, sizes: tuple[int, ...], bound: float = MAX_COORDINATE) -> tuple[float, ...]:
    """A list of ``sizes`` numbers, each in [-bound, bound]."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
        _fail(name, value, f"must be a list of {' or '.join(map(str, sizes))} numbers")
    if len(value) not in sizes:
        _fail(name, value, f"must have {' or '.join(map(str, sizes))} entries, got {len(value)}")
    return tuple(_real(f"{name}[{i}]", v, lo=-bound, hi=bound) for i, v in enumerate(value))


def _items(name: str, value, max_len: int) -> tuple:
    """``value`` as a tuple: a list of at most ``max_len`` entries."""
    if isinstance(value, (str, bytes, dict)) or not isinstance(value, (Sequence, np.ndarray)):
        _fail(name, value, "must be a list")
    if len(value) > max_len:
        _fail(name, value, f"has {len(value)} entries, at most {max_len} allowed")
    return tuple(value)


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
            object.__setattr__(self, n, _real(n, getattr(self, n), lo=-MAX_COORDINATE, hi=MAX_COORDINATE))
        lo, hi = FIELD_SIZE
        for n, size in (("x_max", self.width), ("y_max", self.height)):
            if not lo <= size <= hi:
                low = n.replace("max", "min")
                _fail(n, getattr(self, n), f"makes the field's {'width' if n == 'x_max' else 'height'} {size:g} m "
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
class Circle:
    """A disc: ``center`` (x, y) and ``radius`` > 0, in metres."""

    center: tuple[float, float]
    radius: float

    kind = "circle"

    def __post_init__(self):
        object.__setattr__(self, "center", _vector("center", self.center, (2,)))
        object.__setattr__(self, "radius", _real("radius", self.radius, lo=0.0, lo_open=True, hi=MAX_RADIUS))

    def bounding_circle(self) -> tuple[np.ndarray, float]:
        return np.array(self.center), self.radius

    def contains(self, points, margin: float = 0.0) -> np.ndarray:
        p = np.asarray(points, dtype=float).reshape(-1, 2)
        return np.hypot(p[:, 0] - self.center[0], p[:, 1] - self.center[1]) <= self.radius + margin

    def segment_hits(self, a, b, margin: float = 0.0) -> bool:
        return bool(_point_segment_distance(np.array([self.center]), np.asarray(a, float),
                                            np.asarray(b, float))[0] <= self.radius + margin)

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
class Polygon:
    """A simple polygon given by its ``vertices`` ((x, y) pairs, at least 3, either orientation)."""

    vertices: tuple[tuple[float, float], ...]

    kind = "polygon"

    def __post_init__(self):
        verts = _items("vertices", self.vertices, MAX_VERTICES)
        if len(verts) < 3:
            _fail("vertices", self.vertices, f"a polygon needs at least 3 vertices, got {len(verts)}")
        verts = tuple(_vector(f"vertices[{i}]", v, (2,)) for i, v in enumerate(verts))
        object.__setattr__(self, "vertices", verts)
        v = np.array(verts)
        if not _core.is_simple_polygon(v):      # CGAL's O(n log n) sweep, exact predicates
            if np.linalg.matrix_rank(v - v[0]) < 2:
                _fail("vertices", verts, "the polygon has zero area: its vertices lie on one line")
            _fail("vertices", verts, "the polygon is not simple: two edges cross or touch, or a vertex repeats")
        area = 0.5 * abs(np.dot(v[:, 0], np.roll(v[:, 1], -1)) - np.dot(v[:, 1], np.roll(v[:, 0], -1)))
        if not area > 1e-12:
            _fail("vertices", verts, "the polygon has zero area")
        object.__setattr__(self, "_path", _MplPath(np.vstack([v, v[:1]]), closed=True))

    def array(self) -> np.ndarray:
        """The vertices as an ``(M, 2)`` array."""
        return np.array(self.vertices)

    def bounding_circle(self) -> tuple[np.ndarray, float]:
        v = self.array()
        c = v.mean(axis=0)
        return c, float(np.max(np.hypot(*(v - c).T)))

    def _edges(self) -> tuple[np.ndarray, np.ndarray]:
        v = self.array()
        return v, np.roll(v, -1, axis=0)

    def contains(self, points, margin: float = 0.0) -> np.ndarray:
        p = np.asarray(points, dtype=float).reshape(-1, 2)
        inside = self._path.contains_points(p)
        d = _point_segment_distance(p, *self._edges()).min(axis=1)
        return inside | (d <= margin + 1e-9)

    def segment_hits(self, a, b, margin: float = 0.0) -> bool:
        a, b = np.asarray(a, float), np.asarray(b, float)
        if self._path.contains_point(a):
            return True
        p0, p1 = self._edges()
        return bool(np.min(_segments_distance(a, b, p0, p1)) <= margin + 1e-9)

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
            _fail("shape", self.shape, "must be a Circle or a Polygon")
        object.__setattr__(self, "risk", _real("risk", self.risk, lo=0.0, lo_open=True, hi=1.0))

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
        object.__setattr__(self, "id", _integer("id", self.id))
        object.__setattr__(self, "position", _vector("position", self.position, (2, 3)))
        object.__setattr__(self, "class_name", _text("class", self.class_name))
        object.__setattr__(self, "cluster", _integer("cluster", self.cluster))

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
        _text("name", self.name)
        ids = _items("clusters", self.clusters, MAX_PATH_CLUSTERS)
        if len(ids) < 2:
            _fail("clusters", self.clusters, "a path needs a start and a destination cluster")
        ids = tuple(_integer(f"clusters[{i}]", c) for i, c in enumerate(ids))
        for i in range(1, len(ids)):
            if ids[i] == ids[i - 1]:
                _fail(f"clusters[{i}]", ids[i], "repeats the previous cluster")
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


# --------------------------------------------------------------------------- geometry kernels

def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each of the ``(N, 2)`` points to the segment ``ab``: shape ``(N,)``;
    or, for ``(M, 2)`` end points ``a``, ``b``, to each segment ``a[k] b[k]``: shape ``(N, M)``."""
    p = np.asarray(p, dtype=float)[:, None, :]
    a2, b2 = np.atleast_2d(a)[None], np.atleast_2d(b)[None]
    ab = b2 - a2
    den = np.sum(ab * ab, axis=-1)
    t = np.clip(np.sum((p - a2) * ab, axis=-1) / np.where(den == 0.0, 1.0, den), 0.0, 1.0)
    q = a2 + t[..., None] * ab
    d = np.hypot(p[..., 0] - q[..., 0], p[..., 1] - q[..., 1])
    return d[:, 0] if np.ndim(a) == 1 else d


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _segments_distance(a: np.ndarray, b: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Distance between segment ``ab`` and each segment ``p[k] q[k]`` (0 where they meet)."""
    p, q = np.atleast_2d(p), np.atleast_2d(q)
    d1, d2 = _cross(b - a, p - a), _cross(b - a, q - a)
    d3, d4 = _cross(q - p, a - p), _cross(q - p, b - p)
    proper = (d1 * d2 < 0) & (d3 * d4 < 0)
    ends = np.minimum.reduce([
        _point_segment_distance(p, a, b), _point_segment_distance(q, a, b),
        _point_segment_distance(a[None], p, q)[0], _point_segment_distance(b[None], p, q)[0],
    ])
    return np.where(proper, 0.0, ends)


# --------------------------------------------------------------------------- world

@dataclass(frozen=True)
class World:
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
            _fail("field", self.field, "must be a Field")
        for name, kinds, limit in (("obstacles", (Circle, Polygon), MAX_OBSTACLES), ("hazards", (Hazard,), MAX_HAZARDS),
                                   ("landmarks", (Landmark,), MAX_LANDMARKS)):
            items = _items(name, getattr(self, name), limit)
            for i, it in enumerate(items):
                if not isinstance(it, kinds):
                    _fail(f"{name}[{i}]", it, f"must be a {' or '.join(k.__name__ for k in kinds)}")
            object.__setattr__(self, name, items)
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
                _fail(f"landmarks[{i}].position", lm.position, f"lies outside the field {self.field.describe()}")
            if lm.id in seen:
                _fail(f"landmarks[{i}].id", lm.id, f"duplicates landmarks[{seen[lm.id]}].id")
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

    # ---- collision queries
    def obstacle_mask(self, points, margin: float = 0.0) -> np.ndarray:
        """Which of the ``(N, 2)`` points lie in an obstacle inflated by ``margin`` (boundary inside)."""
        p = np.asarray(points, dtype=float).reshape(-1, 2)
        hit = np.zeros(len(p), dtype=bool)
        for ob in self.obstacles:
            hit |= ob.contains(p, margin)
        return hit

    def first_obstacle_at(self, points, margin: float = 0.0) -> np.ndarray:
        """Per ``(N, 2)`` point: the index of the first obstacle inflated by ``margin`` that contains it, or −1."""
        p = np.asarray(points, dtype=float).reshape(-1, 2)
        first = np.full(len(p), -1)
        for i in reversed(range(len(self.obstacles))):
            first[self.obstacles[i].contains(p, margin)] = i
        return first

    def point_in_obstacle(self, point, margin: float = 0.0) -> bool:
        """Whether the (x, y) ``point`` lies in some obstacle inflated by ``margin``."""
        return bool(self.obstacle_mask(np.asarray(point, dtype=float)[:2], margin)[0])

    def obstacles_at(self, point, margin: float = 0.0) -> list[int]:
        """Indices of the obstacles containing ``point``."""
        p = np.asarray(point, dtype=float)[:2]
        return [i for i, ob in enumerate(self.obstacles) if ob.contains(p, margin)[0]]

    def segment_hits_obstacle(self, a, b, margin: float = 0.0) -> bool:
        """Whether the segment ``ab`` touches an obstacle inflated by ``margin``.

        Exact: circles by point–segment distance, polygons by containment of
        ``a`` plus segment–edge distance, so no sampling step can miss a corner.
        """
        a, b = np.asarray(a, float)[:2], np.asarray(b, float)[:2]
        return any(ob.segment_hits(a, b, margin) for ob in self.obstacles)

    def obstacles_hit_by(self, polyline, margin: float = 0.0) -> list[int]:
        """Indices of the obstacles that the ``(N, 2)`` polyline touches."""
        pts = np.asarray(polyline, dtype=float).reshape(-1, 2)
        return [i for i, ob in enumerate(self.obstacles)
                if any(ob.segment_hits(pts[k], pts[k + 1], margin) for k in range(len(pts) - 1))]

    def polyline_hits_obstacle(self, polyline, margin: float = 0.0) -> bool:
        pts = np.asarray(polyline, dtype=float).reshape(-1, 2)
        return any(self.segment_hits_obstacle(pts[k], pts[k + 1], margin) for k in range(len(pts) - 1))

    def hazard_risk(self, points) -> np.ndarray:
        """The highest hazard risk at each ``(N, 2)`` point (0 outside every hazard)."""
        p = np.asarray(points, dtype=float).reshape(-1, 2)
        risk = np.zeros(len(p))
        for hz in self.hazards:
            risk = np.where(hz.shape.contains(p), np.maximum(risk, hz.risk), risk)
        return risk

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
        d = _table("", data, required=(), optional=("field", "obstacles", "hazards", "landmarks"))
        with _at("field"):
            f = _table("", d.get("field", {}), required=(), optional=("x_min", "y_min", "x_max", "y_max"))
            fld = Field(**f)
        obstacles = []
        for i, o in enumerate(_items("obstacles", d.get("obstacles", []), MAX_OBSTACLES)):
            with _at(f"obstacles[{i}]"):
                obstacles.append(_shape_from_dict(o, extra=()))
        hazards = []
        for i, h in enumerate(_items("hazards", d.get("hazards", []), MAX_HAZARDS)):
            with _at(f"hazards[{i}]"):
                shape = _shape_from_dict(h, extra=("risk",))
                hazards.append(Hazard(shape, h.get("risk", 1.0)))
        landmarks = []
        for i, lm in enumerate(_items("landmarks", d.get("landmarks", []), MAX_LANDMARKS)):
            with _at(f"landmarks[{i}]"):
                t = _table("", lm, required=("id", "position"), optional=("class", "cluster"))
                landmarks.append(Landmark(t["id"], t["position"], t.get("class", "landmark"), t.get("cluster", 0)))
        return cls(fld, tuple(obstacles), tuple(hazards), tuple(landmarks))


def _table(name: str, value, *, required: Sequence[str], optional: Sequence[str]) -> dict:
    """Check that ``value`` is a mapping with exactly the allowed keys."""
    if not isinstance(value, dict):
        raise ScenarioError(_join(name, f"= {cut(value)}: must be a table"))
    allowed = set(required) | set(optional)
    for k in value:
        if k not in allowed:
            where = _join(name, str(k) if len(str(k)) <= 40 else str(k)[:37] + "...")
            raise ScenarioError(f"{where} = {cut(value[k])}: unknown key (allowed: {', '.join(sorted(allowed))})")
    for k in required:
        if k not in value:
            raise ScenarioError(f"{_join(name, k)}: missing (required: {', '.join(required)})")
    return value


def _shape_from_dict(d, extra: Sequence[str]) -> Shape:
    t = _table("", d, required=("type",), optional=("center", "radius", "vertices", *extra))
    kind = t["type"]
    if kind == "circle":
        _table("", t, required=("type", "center", "radius"), optional=extra)
        return Circle(t["center"], t["radius"])
    if kind == "polygon":
        _table("", t, required=("type", "vertices"), optional=extra)
        return Polygon(t["vertices"])
    _fail("type", kind, 'must be "circle" or "polygon"')

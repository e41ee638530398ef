"""Safe-path corridor geometry ([SafeNav-ext §V-A3(iii)], [SafeNav Algs. 1–2]).

Citations follow docs/paper_map.md; [SafeNav-ext §V-A3(iii)] is
[SafeNav-conf §V-A.2(iii)].

* :class:`Corridor` — the *safe buffer*: a corridor of half-width ``W = d_max``
  around the central polyline, cut into ``n`` equal-width zones per side with
  weights ``w_j`` (2, 4, 6, 8).  Deviation ``d`` is the distance to the nearest
  point of the central path (eq. 17); WRS is eq. 18 and AWRS
  [SafeNav-ext eq. 20], both evaluated by the same C++ function as
  :func:`safenav.metrics.wrs`.
  Arc length ``s`` runs from 0 at the first vertex to ``L`` at the last.
* :class:`PathSegments` — the path cut into segments for SafeNav-CHull
  (Algorithm 1: convex hull of each segment, point-in-hull test against the
  current and next hull) and SafeNav-Centroid (Algorithm 2: each segment cut
  into sub-segments whose centroids attract the vehicle).

How segments and hulls are defined (the paper leaves it open):

* The path is cut at arc lengths ``0 = s_0 < … < s_K = L`` into ``K`` pieces
  of equal arc length: ``K = count``, or ``K = ceil(L / length)`` so that no
  piece is longer than ``length``.
* ``points(k)`` is the central polyline of segment ``k`` (its cut points plus
  the original vertices in between), densified so no step exceeds ``spacing``.
* ``hull(k)`` is the CGAL convex hull of the *buffer* around that polyline:
  every polyline vertex contributes a regular ``disc_sides``-gon circumscribed
  about the disc of radius ``W``.  The hull therefore contains the whole safe
  buffer of the segment, and exceeds the buffer's own hull by at most
  ``W·(1/cos(π/disc_sides) − 1)`` (1.9 % of W with 16 sides).
* Sub-segment ``j`` of segment ``k`` is the ``j``-th of ``sub_segments`` equal
  arc-length pieces; its centroid is the length-weighted centroid
  ``∫ p ds / ℓ`` of its polyline (independent of sampling; the midpoint of a
  straight piece).

Hulls and point location are CGAL's (``convex_hull_2``, ``bounded_side_2``
with the exact-predicates kernel); points on a hull's boundary count as inside.
"""

from __future__ import annotations

import numpy as np

from . import _core
from .validation import as_array, as_positive_int
from .metrics import RiskZones

PathProjection = _core.PathProjection
CentroidTarget = _core.CentroidTarget

__all__ = ["Corridor", "PathSegments", "PathProjection", "CentroidTarget", "convex_hull", "points_in_polygon"]


def _pts(name, p):
    return as_array(name, p, (None, 2))


def _pt(name, p):
    return as_array(name, p, (2,))


def convex_hull(points) -> np.ndarray:
    """Convex hull of ``points`` (N, 2) by CGAL: extreme points, counter-clockwise.

    The vertices are a subset of the input rows; collinear boundary points are
    dropped.  This is the ConvexHull step of Algorithm 1."""
    return _core.convex_hull(_pts("points", points))


def points_in_polygon(points, polygon) -> np.ndarray:
    """Boolean mask: each point inside or on the boundary of the simple ``polygon``.

    The PointInHull test of [SafeNav-ext Alg. 1 l. 13] (= conf l. 10), by CGAL's ``bounded_side_2``."""
    return _core.points_in_polygon(_pts("points", points), _pts("polygon", polygon))


class Corridor:
    """The safe buffer of [SafeNav-ext §V-A3(iii)] around a central polyline.

    Parameters
    ----------
    path : (M, 2) array
        The central (safe) path.  Consecutive duplicate vertices are dropped;
        at least two distinct vertices are needed.
    zones : RiskZones, optional
        Half-width ``d_max`` and zone weights ``w_j`` (eq. 18); defaults to
        ``W = 2 m`` and weights 2, 4, 6, 8.
    half_width : float, optional
        Shortcut for ``RiskZones(half_width=..., weights=zones.weights)``.
    """

    def __init__(self, path, zones: RiskZones | None = None, *, half_width: float | None = None):
        z = zones or RiskZones()
        if half_width is not None:
            z = RiskZones(half_width=float(half_width), weights=list(z.weights))
        self._c = _core.Corridor(_pts("path", path), z)

    # -- properties ---------------------------------------------------------
    @property
    def path(self) -> np.ndarray:
        """The central polyline (duplicates removed)."""
        return np.array(self._c.path)

    @property
    def zones(self) -> RiskZones:
        return self._c.zones

    @property
    def half_width(self) -> float:
        """W = d_max, the buffer's half-width."""
        return self._c.half_width

    @property
    def zone_count(self) -> int:
        return self._c.zone_count

    @property
    def length(self) -> float:
        """Arc length L of the central path."""
        return self._c.length

    @property
    def vertex_arc_lengths(self) -> np.ndarray:
        return np.array(self._c.vertex_arc_lengths)

    # -- single point -------------------------------------------------------
    def project(self, point) -> PathProjection:
        """Nearest path point of ``point``: arc length s, deviation d (eq. 17), side (+1 left, −1 right)."""
        return self._c.project(_pt("point", point))

    def point_at(self, s: float) -> np.ndarray:
        """Point of the central path at arc length ``s`` (clamped to [0, L]).

        With ``project`` this gives "a point ahead on the safe path":
        ``point_at(project(p).arc_length + lookahead)``."""
        return self._c.point_at(float(s))

    def tangent_at(self, s: float) -> np.ndarray:
        """Unit direction of the path at arc length ``s`` (clamped to [0, L])."""
        return self._c.tangent_at(float(s))

    # -- batch --------------------------------------------------------------
    def distance(self, points) -> np.ndarray:
        """Deviation d_i from the nearest point of the central path (eq. 17)."""
        return self._c.distance(_pts("points", points))

    def arc_length(self, points) -> np.ndarray:
        """Arc length s of each point's projection onto the path."""
        return self._c.arc_length(_pts("points", points))

    def signed_offset(self, points) -> np.ndarray:
        """Deviation with sign: positive left of the path direction, negative right."""
        return self._c.signed_offset(_pts("points", points))

    def side(self, points) -> np.ndarray:
        """+1 left of the path, −1 right, 0 on it (CGAL orientation of the nearest edge)."""
        return self._c.side(_pts("points", points))

    def zone(self, points) -> np.ndarray:
        """Zone index 0 … n−1 (zone j covers ``[j·W/n, (j+1)·W/n)``), or n when d ≥ W."""
        return self._c.zone(_pts("points", points))

    def contains(self, points) -> np.ndarray:
        """Boolean mask: inside the safe buffer (d ≤ W, boundary included)."""
        return self._c.contains(_pts("points", points))

    def wrs(self, points) -> np.ndarray:
        """Weighted risk score of each point (eq. 18), as :func:`safenav.metrics.wrs`."""
        return self._c.wrs(_pts("points", points))

    def awrs(self, points) -> float:
        """Average weighted risk score over a trajectory [SafeNav-ext eq. 20]."""
        return self._c.awrs(_pts("points", points))

    def points_at(self, s) -> np.ndarray:
        """Points of the path at arc lengths ``s`` (each clamped to [0, L])."""
        return self._c.points_at(as_array("s", np.atleast_1d(s), (None,)))

    def segments(self, *, count: int | None = None, length: float | None = None, spacing: float = 0.5,
                 sub_segments: int = 4, disc_sides: int = 16) -> "PathSegments":
        """Cut the path into segments for Algorithms 1 and 2 (see the module docstring).

        Give ``count`` (number of equal arc-length segments) or ``length``
        (maximum segment arc length, default 10 m), not both."""
        if count is not None and length is not None:
            raise ValueError(f"give count or length, not both (count={count!r}, length={length!r})")
        if count is not None:
            opts = _core.SegmentOptions(count=as_positive_int("count", count), spacing=float(spacing),
                                        sub_segments=as_positive_int("sub_segments", sub_segments),
                                        disc_sides=as_positive_int("disc_sides", disc_sides))
        else:
            opts = _core.SegmentOptions(count=0, length=float(10.0 if length is None else length),
                                        spacing=float(spacing),
                                        sub_segments=as_positive_int("sub_segments", sub_segments),
                                        disc_sides=as_positive_int("disc_sides", disc_sides))
        return PathSegments(self._c.segments(opts), self)

    def __repr__(self) -> str:
        return f"Corridor(length={self.length:.3f}, half_width={self.half_width}, vertices={len(self._c.path)})"


class PathSegments:
    """Segments of a safe path with their convex hulls and sub-segment centroids.

    Made by :meth:`Corridor.segments`.  ``len(segments)`` is K."""

    def __init__(self, core, corridor: Corridor):
        self._s = core
        self.corridor = corridor

    def __len__(self) -> int:
        return self._s.size

    @property
    def core(self) -> _core.PathSegments:
        """The core's segments, for the core's navigation functions."""
        return self._s

    @property
    def breaks(self) -> np.ndarray:
        """Cut arc lengths s_0 = 0 < … < s_K = L."""
        return np.array(self._s.breaks)

    def _k(self, k) -> int:
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
            raise ValueError(f"segment index must be an integer, got {k!r}")
        return int(k)

    def segment_at(self, s: float) -> int:
        """Segment holding arc length ``s`` (a cut belongs to the later segment)."""
        return self._s.segment_at(float(s))

    def points(self, k: int) -> np.ndarray:
        """Densified central polyline of segment ``k`` (the segment's trajectory points p_i)."""
        return self._s.points(self._k(k))

    def hull_input(self, k: int) -> np.ndarray:
        """The points hull ``k`` is built from: a circumscribed polygon of each buffer disc."""
        return self._s.hull_input(self._k(k))

    def hull(self, k: int) -> np.ndarray:
        """Convex hull of segment ``k`` [SafeNav-ext Alg. 1 l. 8] (= conf l. 5), counter-clockwise."""
        return np.array(self._s.hull(self._k(k)))

    def hulls(self) -> list[np.ndarray]:
        return [self.hull(k) for k in range(len(self))]

    def hull_contains(self, k: int, points) -> np.ndarray:
        """PointInHull [SafeNav-ext Alg. 1 l. 13] (= conf l. 10) for many points: inside or on hull ``k``."""
        return self._s.hull_contains(self._k(k), _pts("points", points))

    def in_current_or_next(self, k: int, point) -> bool:
        """[SafeNav-ext Alg. 1 l. 13] (= conf l. 10): the point is inside hull ``k`` or hull ``k+1``
        (when it exists)."""
        return self._s.in_current_or_next(self._k(k), _pt("point", point))

    def segments_containing(self, point) -> list[int]:
        """All segments whose hull contains ``point``, ascending."""
        return self._s.segments_containing(_pt("point", point))

    def locate(self, points) -> np.ndarray:
        """For each point the first segment whose hull contains it, or −1."""
        return self._s.locate(_pts("points", points))

    @property
    def centroids(self) -> np.ndarray:
        """All sub-segment centroids [SafeNav-ext Alg. 2 l. 5] (= conf l. 2), ``K·m`` rows, row = k·m + j."""
        return np.array(self._s.centroids)

    @property
    def centroid_arc_lengths(self) -> np.ndarray:
        """Mid arc length of each sub-segment (rows as :attr:`centroids`)."""
        return np.array(self._s.centroid_arc_lengths)

    def segment_centroids(self, k: int) -> np.ndarray:
        """The ``m`` sub-segment centroids of segment ``k`` (Algorithm 2)."""
        return self._s.segment_centroids(self._k(k))

    def nearest_centroid_ahead(self, point) -> CentroidTarget:
        """Algorithm 2's target: the nearest centroid whose sub-segment lies ahead.

        Ahead means a mid arc length larger than the arc length of ``point``'s
        projection on the path.  When none is ahead, the last centroid is
        returned with ``ahead = False``."""
        return self._s.nearest_centroid_ahead(_pt("point", point))

    def __repr__(self) -> str:
        return f"PathSegments(count={len(self)}, sub_segments={self._s.options.sub_segments})"

"""Shapes for :mod:`safenav.foxglove`: Foxglove scene primitives and point
clouds (``foxglove.SceneUpdate`` parts, ``foxglove.PointCloud``) built from
the world's shapes, paths and covariances.

Everything is in the ``map`` frame (:data:`FRAME`), metres, z up; the vehicle
moves in the z = 0 plane.  Only display geometry lives here: ear-clipping a
simple polygon into triangles, the k-σ ellipse of a 2×2 covariance, sampled
outlines, colours.  No model of the vehicle or the sensors is computed.
"""

from __future__ import annotations

import math

import numpy as np

#: The one fixed frame of every message.
FRAME = "map"
#: Height [m] an obstacle is drawn with (display only: the core's obstacles are 2D and hide any landmark).
OBSTACLE_HEIGHT = 2.0
#: Points per ellipse and per circle outline.
ELLIPSE_POINTS = 48

#: RGBA colours (0..1) of the view's kinds of things.
COLORS = {
    "obstacle": (0.35, 0.35, 0.38, 1.0),
    "obstacle_edge": (0.05, 0.05, 0.05, 1.0),
    "field": (0.1, 0.1, 0.1, 1.0),
    "landmark": (0.12, 0.47, 0.71, 1.0),
    "landmark_seen": (0.1, 0.75, 1.0, 1.0),
    "safe_path": (0.17, 0.63, 0.17, 1.0),
    "corridor": (0.17, 0.63, 0.17, 0.8),
    "zone": (0.17, 0.63, 0.17, 0.35),
    "truth": (0.0, 0.0, 0.0, 1.0),
    "estimate": (0.84, 0.15, 0.16, 1.0),
    "followed": (0.58, 0.4, 0.74, 0.8),
    "ellipse": (0.84, 0.15, 0.16, 0.9),
    "fix": (1.0, 0.5, 0.05, 1.0),
    "command": (0.09, 0.75, 0.81, 1.0),
    "predicted": (0.09, 0.75, 0.81, 0.6),
    "rejected": (0.9, 0.1, 0.1, 1.0),
}


# --------------------------------------------------------------------------- geometry

def yaw_quaternion(theta: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation by ``theta`` [rad] about z; the identity for a NaN heading."""
    if not math.isfinite(theta):
        return 0.0, 0.0, 0.0, 1.0
    return 0.0, 0.0, math.sin(theta / 2.0), math.cos(theta / 2.0)


def signed_area(poly) -> float:
    """Shoelace area of a polygon's (N, 2) vertices: > 0 counter-clockwise."""
    p = np.asarray(poly, dtype=float)
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _cross(o, a, b) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def triangulate(poly) -> np.ndarray:
    """Triangles (M, 3) of vertex indices covering a simple polygon (ear
    clipping; M = N − 2, each counter-clockwise).  Raises ValueError for
    fewer than 3 vertices or a polygon with no ear (self-intersecting)."""
    p = np.asarray(poly, dtype=float)
    n = len(p)
    if n < 3:
        raise ValueError(f"polygon with {n} vertices: needs at least 3")
    idx = list(range(n)) if signed_area(p) > 0 else list(range(n))[::-1]
    out = []
    while len(idx) > 3:
        for k in range(len(idx)):
            a, b, c = idx[k - 1], idx[k], idx[(k + 1) % len(idx)]
            if _cross(p[a], p[b], p[c]) <= 0:
                continue        # reflex or flat: not an ear
            if any(_cross(p[a], p[b], p[q]) >= 0 and _cross(p[b], p[c], p[q]) >= 0 and _cross(p[c], p[a], p[q]) >= 0
                   for q in idx if q not in (a, b, c)):
                continue        # another vertex inside the candidate ear
            out.append((a, b, c))
            del idx[k]
            break
        else:
            raise ValueError(f"polygon {p.tolist()}: no ear left to clip (is it self-intersecting?)")
    out.append(tuple(idx))
    return np.asarray(out, dtype=int)


def ellipse(center, cov, k: float = 3.0, n: int = ELLIPSE_POINTS) -> np.ndarray:
    """(n, 2) points of the k-σ ellipse {p : (p − c)ᵀ P⁻¹ (p − c) = k²} of a
    2×2 position covariance P (symmetric; its negative eigenvalues from
    round-off are taken as 0)."""
    P = np.asarray(cov, dtype=float).reshape(2, 2)
    w, V = np.linalg.eigh(0.5 * (P + P.T))
    a = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    unit = np.c_[np.cos(a), np.sin(a)]
    return np.asarray(center, dtype=float)[:2] + k * (unit * np.sqrt(np.maximum(w, 0.0))) @ V.T


def circle(center, radius: float, n: int = ELLIPSE_POINTS) -> np.ndarray:
    """(n, 2) points of a circle."""
    return ellipse(center, np.eye(2) * float(radius) ** 2, k=1.0, n=n)


def outline(points, spacing: float, *, closed: bool = True) -> np.ndarray:
    """Points every ``spacing`` metres (at most) along a polyline, its vertices included."""
    p = np.asarray(points, dtype=float)
    if closed:
        p = np.vstack([p, p[:1]])
    out = [p[:1]]
    for a, b in zip(p[:-1], p[1:]):
        m = max(1, int(math.ceil(np.linalg.norm(b - a) / spacing)))
        out.append(a + np.outer(np.arange(1, m + 1) / m, b - a))
    pts = np.vstack(out)
    return pts[:-1] if closed else pts


def risk_color(risk: float, max_risk: float) -> tuple[float, float, float, float]:
    """A hazard's colour: yellow (low risk) to red (the world's highest), more opaque when riskier."""
    f = min(max(risk / max_risk, 0.0), 1.0) if max_risk > 0 else 1.0
    return 1.0, 0.85 * (1.0 - f) + 0.1 * f, 0.0, 0.3 + 0.35 * f


# --------------------------------------------------------------------------- Foxglove parts

def set_time(stamp, t_ns: int) -> None:
    """Set a ``google.protobuf.Timestamp`` from nanoseconds."""
    stamp.FromNanoseconds(int(t_ns))


def set_color(c, rgba) -> None:
    c.r, c.g, c.b, c.a = (float(v) for v in rgba)


def set_pose(pose, x: float, y: float, theta: float = 0.0, z: float = 0.0) -> None:
    """A ``foxglove.Pose`` at (x, y, z) with heading ``theta``."""
    pose.position.x, pose.position.y, pose.position.z = float(x), float(y), float(z)
    q = yaw_quaternion(float(theta))
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = q


def entity(update, entity_id: str, t_ns: int, *, metadata: dict | None = None):
    """A new ``foxglove.SceneEntity`` of ``update`` (frame :data:`FRAME`, no
    lifetime: it stays until an entity of the same id replaces it)."""
    e = update.entities.add()
    e.id = entity_id
    e.frame_id = FRAME
    set_time(e.timestamp, t_ns)
    for k, v in (metadata or {}).items():
        kv = e.metadata.add()
        kv.key, kv.value = str(k), str(v)
    return e


def add_line(e, points, rgba, *, thickness: float = 0.15, loop: bool = False, z: float = 0.0,
             segments: bool = False) -> None:
    """A line strip (``loop``: closed; ``segments``: a line list of point pairs) in entity ``e``."""
    from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive

    ln = e.lines.add()
    ln.type = LinePrimitive.LINE_LIST if segments else LinePrimitive.LINE_LOOP if loop else LinePrimitive.LINE_STRIP
    ln.pose.orientation.w = 1.0
    ln.thickness = float(thickness)
    ln.scale_invariant = False
    for x, y, *rest in np.asarray(points, dtype=float):
        q = ln.points.add()
        q.x, q.y, q.z = x, y, rest[0] if rest else z
    set_color(ln.color, rgba)


def add_prism(e, poly, height: float, rgba) -> None:
    """A polygon extruded from z = 0 to ``height``: walls and top cap as one
    triangle list (a flat polygon when ``height`` is 0)."""
    p = np.asarray(poly, dtype=float)
    if signed_area(p) < 0:
        p = p[::-1]
    tris = e.triangles.add()
    tris.pose.orientation.w = 1.0
    set_color(tris.color, rgba)

    def put(x, y, z):
        q = tris.points.add()
        q.x, q.y, q.z = float(x), float(y), float(z)

    for a, b, c in triangulate(p):
        for v in (a, b, c):
            put(p[v, 0], p[v, 1], height)
    if height > 0:
        for a, b in zip(p, np.roll(p, -1, axis=0)):
            for (x, y), z in ((a, 0), (b, 0), (b, height), (a, 0), (b, height), (a, height)):
                put(x, y, z)


def add_cylinder(e, center, radius: float, height: float, rgba) -> None:
    """An upright cylinder standing on z = 0."""
    c = e.cylinders.add()
    set_pose(c.pose, center[0], center[1], 0.0, z=height / 2.0)
    c.size.x = c.size.y = 2.0 * float(radius)
    c.size.z = float(height)
    c.bottom_scale = c.top_scale = 1.0
    set_color(c.color, rgba)


def add_sphere(e, xy, diameter: float, rgba, z: float = 0.0) -> None:
    s = e.spheres.add()
    set_pose(s.pose, xy[0], xy[1], 0.0, z=z)
    s.size.x = s.size.y = s.size.z = float(diameter)
    set_color(s.color, rgba)


def add_arrow(e, xy, theta: float, length: float, rgba) -> None:
    """An arrow from ``xy`` pointing along ``theta``, ``length`` long (shaft plus head)."""
    a = e.arrows.add()
    set_pose(a.pose, xy[0], xy[1], theta)
    head = min(0.4, 0.4 * max(length, 1e-3))
    a.shaft_length = max(float(length) - head, 1e-3)
    a.shaft_diameter = 0.08
    a.head_length = head
    a.head_diameter = 0.25
    set_color(a.color, rgba)


def add_text(e, xy, text: str, rgba, *, z: float = 0.5, size: float = 12.0) -> None:
    t = e.texts.add()
    set_pose(t.pose, xy[0], xy[1], 0.0, z=z)
    t.billboard = True
    t.font_size = float(size)
    t.scale_invariant = True
    t.text = text
    set_color(t.color, rgba)


def point_cloud(t_ns: int, points, rgba, *, ids=None):
    """A ``foxglove.PointCloud`` in :data:`FRAME`: fields x, y, z (float32),
    red, green, blue, alpha (uint8; one colour per point or one for all) and,
    with ``ids``, ``id`` (float32, e.g. a landmark's id)."""
    from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField as F
    from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud

    p = np.asarray(points, dtype=float).reshape(-1, 2 if np.asarray(points).shape[-1] == 2 else 3)
    dtype = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1"),
             ("alpha", "u1")] + ([("id", "<f4")] if ids is not None else [])
    rec = np.zeros(len(p), dtype=dtype)
    rec["x"], rec["y"] = p[:, 0], p[:, 1]
    if p.shape[1] == 3:
        rec["z"] = p[:, 2]
    rgba8 = np.rint(np.broadcast_to(np.asarray(rgba, dtype=float), (len(p), 4)) * 255).astype(np.uint8)
    for k, name in enumerate(("red", "green", "blue", "alpha")):
        rec[name] = rgba8[:, k]
    if ids is not None:
        rec["id"] = np.asarray(ids, dtype=float)
    msg = PointCloud()
    set_time(msg.timestamp, t_ns)
    msg.frame_id = FRAME
    msg.pose.orientation.w = 1.0
    msg.point_stride = rec.dtype.itemsize
    kinds = {"<f4": F.FLOAT32, "u1": F.UINT8}
    for name, kind in dtype:
        msg.fields.add(name=name, offset=rec.dtype.fields[name][1], type=kinds[kind])
    msg.data = rec.tobytes()
    return msg

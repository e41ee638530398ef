"""A view of a run for Foxglove and Rerun: an MCAP file of Foxglove's schemas.

``safenav run``, ``demo``, ``plan`` and ``replay`` write one with
``--view FILE.mcap`` (:func:`add_view_argument`); ``docs/view.md`` lists the
topics.  The file is written with the ``mcap`` package; every message is one
of Foxglove's schemas (``foxglove.SceneUpdate``, ``foxglove.PoseInFrame``,
``foxglove.FrameTransforms``, ``foxglove.PointCloud``, ``foxglove.PosesInFrame``,
``foxglove.Log``), protobuf-encoded, with each schema's ``FileDescriptorSet``
taken from the installed ``foxglove-schemas-protobuf`` package and stored in
the file (nothing is downloaded).  Protobuf rather than JSON: Rerun converts
Foxglove's *protobuf* messages into its own types (poses, transforms, point
clouds, text logs) and keeps JSON-encoded ones as raw bytes.

Conventions: one fixed frame, ``map`` (:data:`~safenav.foxglove_scene.FRAME`),
metres, z up; a message's log time, publish time and ``timestamp`` are the
simulation time in nanoseconds (step k of a trial at k·Δt; a replay's own log
times); static content (world, plans, whole tracks) is stamped at the start.

The view only reads what a run produced: the recorded trials (trial 0 of each
cell, the trace that Figs. 4–5 draw; :func:`safenav.experiments.figures.recorded_trials`)
or a replay's result.  It runs no simulation and changes no result.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from . import _core
from . import foxglove_scene as fs
from .foxglove_trial import write_replay, write_trial
from .results import atomic_write

__all__ = ["View", "write_view", "add_view_argument", "write_world", "write_field", "write_obstacles",
           "write_hazards", "write_outlines", "write_landmarks", "write_plan", "write_trial", "write_replay",
           "navigation_view", "plan_view", "replay_view", "schema_data", "SUFFIX", "PROFILE"]

#: The suffix of a view file.
SUFFIX = ".mcap"
#: MCAP profile of the file: none (its channels are protobuf-encoded).
PROFILE = ""
def schema_data(message_type) -> bytes:
    """The serialized ``FileDescriptorSet`` of a protobuf message type: its
    file and every file it imports, dependencies first (what Foxglove and
    Rerun decode a ``protobuf`` channel with)."""
    from google.protobuf.descriptor_pb2 import FileDescriptorSet

    fds, seen = FileDescriptorSet(), set()

    def add(f):
        if f.name in seen:
            return
        seen.add(f.name)
        for d in f.dependencies:
            add(d)
        f.CopyToProto(fds.file.add())

    add(message_type.DESCRIPTOR.file)
    return fds.SerializeToString()


class View:
    """An MCAP file being written to an open binary handle: one channel per
    topic, one schema per message type.  Messages are kept until
    :meth:`finish`, which writes them in time order (ties in the order they
    were given), so that the file's chunks follow the time line whatever order
    the content was produced in.  ``counts`` holds the messages per topic."""

    def __init__(self, fh, *, metadata: dict | None = None):
        from mcap.writer import CompressionType, Writer

        from . import __version__

        self._writer = Writer(fh, compression=CompressionType.ZSTD)
        self._writer.start(profile=PROFILE, library=f"safenav {__version__} (mcap)")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, str]] = {}
        self.counts: dict[str, int] = {}
        self._pending: list[tuple[int, int, int, int, bytes]] = []
        if metadata:
            self._writer.add_metadata("safenav", {str(k): str(v) for k, v in metadata.items()})

    def write(self, topic: str, message, t_ns: int) -> None:
        """Write ``message`` (a Foxglove protobuf message) on ``topic`` at time ``t_ns``."""
        name = message.DESCRIPTOR.full_name
        if topic not in self._channels:
            if name not in self._schemas:
                self._schemas[name] = self._writer.register_schema(name=name, encoding="protobuf",
                                                                   data=schema_data(type(message)))
            cid = self._writer.register_channel(topic=topic, message_encoding="protobuf",
                                                schema_id=self._schemas[name])
            self._channels[topic] = (cid, name)
        cid, have = self._channels[topic]
        if have != name:
            raise ValueError(f"topic {topic!r} carries {have}, not {name}")
        t = int(t_ns)
        if t < 0:
            raise ValueError(f"message time {t} ns on {topic!r}: must be >= 0")
        seq = self.counts.get(topic, 0)
        self._pending.append((t, len(self._pending), cid, seq, message.SerializeToString()))
        self.counts[topic] = seq + 1

    def finish(self) -> None:
        """Write the messages in time order and close the file's summary."""
        for t, _, cid, seq, data in sorted(self._pending, key=lambda m: (m[0], m[1])):
            self._writer.add_message(cid, log_time=t, publish_time=t, data=data, sequence=seq)
        self._pending.clear()
        self._writer.finish()


def write_view(path, fill, *, metadata: dict | None = None) -> Path:
    """Write the view ``path`` (``.mcap``) with ``fill(view)`` through
    :func:`safenav.results.atomic_write` (a unique temporary name beside it,
    renamed when complete).  Returns ``path``."""
    path = Path(path)
    if path.suffix.lower() != SUFFIX:
        raise ValueError(f"view {str(path)!r}: the file name must end in {SUFFIX}")

    def write(fh):
        view = View(fh, metadata=metadata)
        fill(view)
        view.finish()

    return atomic_write(path, write)


def _view_path(text: str) -> str:
    if Path(text).suffix.lower() != SUFFIX:
        raise argparse.ArgumentTypeError(f"must be a file name ending in {SUFFIX}, got {text!r}")
    return text


def add_view_argument(parser) -> None:
    """``--view FILE.mcap``: also write the run as an MCAP file for Foxglove or Rerun (docs/view.md)."""
    parser.add_argument("--view", type=_view_path, default=None, metavar="FILE.mcap",
                        help="also write a view of the run for Foxglove or Rerun: an MCAP file of Foxglove's "
                             "schemas (docs/view.md); the results are the same with or without it")


# --------------------------------------------------------------------------- content: the world

def write_field(view: View, world, t_ns: int = 0) -> None:
    """The field's border on ``/world/field``."""
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    b = np.asarray(world.field.bounds, dtype=float)
    u = SceneUpdate()
    e = fs.entity(u, "field", t_ns)
    fs.add_line(e, [(b[0, 0], b[0, 1]), (b[1, 0], b[0, 1]), (b[1, 0], b[1, 1]), (b[0, 0], b[1, 1])],
                fs.COLORS["field"], thickness=0.3, loop=True)
    view.write("/world/field", u, t_ns)


def write_obstacles(view: View, world, t_ns: int = 0) -> list:
    """One entity per obstacle on ``/world/obstacles``: a cylinder for a
    circle, an extruded polygon with its outline, both
    :data:`~safenav.foxglove_scene.OBSTACLE_HEIGHT` tall.  Returns the outlines
    (points, colour) for :func:`write_outlines`."""
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    from .world import Circle

    u, rings = SceneUpdate(), []
    for i, o in enumerate(world.obstacles):
        e = fs.entity(u, f"obstacle/{i}", t_ns, metadata={"index": i, "shape": type(o).__name__.lower()})
        if isinstance(o, Circle):
            fs.add_cylinder(e, o.center, o.radius, fs.OBSTACLE_HEIGHT, fs.COLORS["obstacle"])
            ring = fs.circle(o.center, o.radius)
        else:
            ring = o.array()
            fs.add_prism(e, ring, fs.OBSTACLE_HEIGHT, fs.COLORS["obstacle"])
            fs.add_line(e, ring, fs.COLORS["obstacle_edge"], thickness=0.1, loop=True, z=fs.OBSTACLE_HEIGHT)
        rings.append((fs.outline(ring, 0.5), fs.COLORS["obstacle"]))
    view.write("/world/obstacles", u, t_ns)
    return rings


def write_hazards(view: View, world, t_ns: int = 0) -> list:
    """One flat entity per hazard on ``/world/hazards``, coloured by its risk
    (:func:`~safenav.foxglove_scene.risk_color`; metadata ``risk``).  Returns
    the outlines (points, colour) for :func:`write_outlines`."""
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    from .world import Circle

    u, rings = SceneUpdate(), []
    top = max((h.risk for h in world.hazards), default=1.0)
    for i, h in enumerate(world.hazards):
        rgba = fs.risk_color(h.risk, top)
        e = fs.entity(u, f"hazard/{i}", t_ns, metadata={"index": i, "risk": h.risk})
        if isinstance(h.shape, Circle):
            fs.add_cylinder(e, h.shape.center, h.shape.radius, 0.02, rgba)
            ring = fs.circle(h.shape.center, h.shape.radius)
        else:
            ring = h.shape.array()
            fs.add_prism(e, ring, 0.0, rgba)
        fs.add_line(e, ring, (*rgba[:3], 1.0), thickness=0.08, loop=True, z=0.03)
        rings.append((fs.outline(ring, 0.5), (*rgba[:3], 1.0)))
    view.write("/world/hazards", u, t_ns)
    return rings


def write_outlines(view: View, rings: list, t_ns: int = 0) -> None:
    """Outlines as one point cloud on ``/world/outlines`` (Rerun draws point clouds, not scene entities)."""
    pts = np.vstack([r for r, _ in rings]) if rings else np.zeros((0, 2))
    colors = np.vstack([np.tile(c, (len(r), 1)) for r, c in rings]) if rings else np.zeros((0, 4))
    view.write("/world/outlines", fs.point_cloud(t_ns, pts, colors), t_ns)


def write_landmarks(view: View, world, t_ns: int = 0) -> None:
    """The landmarks as a point cloud on ``/world/landmarks`` (field ``id``: each one's id)."""
    lm = world.landmark_array()
    view.write("/world/landmarks", fs.point_cloud(t_ns, lm[:, :2], fs.COLORS["landmark"],
                                                  ids=[m.id for m in world.landmarks]), t_ns)


def write_world(view: View, world, t_ns: int = 0) -> None:
    """A ``safenav.World``: its field, obstacles, hazards, their outlines, and its landmarks."""
    write_field(view, world, t_ns)
    rings = write_obstacles(view, world, t_ns) + write_hazards(view, world, t_ns)
    write_outlines(view, rings, t_ns)
    write_landmarks(view, world, t_ns)


# --------------------------------------------------------------------------- content: a plan

def corridor_edges(path, zones) -> list[tuple[float, np.ndarray]]:
    """(offset, (n, 2) points) of the safe buffer's edges (±half-width) and
    zone borders around ``path`` (the core's ``Corridor``; the same lines as
    the figures draw, :func:`safenav.experiments.figures.corridor_lines`)."""
    from .experiments.figures import corridor_lines

    return corridor_lines(_core.Corridor(np.asarray(path, dtype=float), zones))


def write_plan(view: View, name: str, path, zones, t_ns: int = 0) -> None:
    """Path type ``name``'s safe path (RAw-RRT*), its corridor (edges bold,
    risk-zone borders thin), start and goal: a scene update, the waypoints as
    ``foxglove.PosesInFrame`` (heading along the path) and a point cloud of the lines."""
    from foxglove_schemas_protobuf.PosesInFrame_pb2 import PosesInFrame
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    p = np.asarray(path, dtype=float)
    edges = corridor_edges(p, zones)
    half = max(abs(o) for o, _ in edges) if edges else 0.0
    u = SceneUpdate()
    e = fs.entity(u, f"{name}/safe_path", t_ns, metadata={"waypoints": len(p)})
    fs.add_line(e, p, fs.COLORS["safe_path"], thickness=0.3, z=0.05)
    fs.add_sphere(e, p[0], 1.2, fs.COLORS["safe_path"])
    fs.add_sphere(e, p[-1], 1.2, fs.COLORS["estimate"])
    fs.add_text(e, p[0], f"{name} start", fs.COLORS["safe_path"], z=1.5)
    e = fs.entity(u, f"{name}/corridor", t_ns, metadata={"half_width_m": half})
    for off, pts in edges:
        edge = abs(off) == half
        fs.add_line(e, pts, fs.COLORS["corridor" if edge else "zone"], thickness=0.2 if edge else 0.06, z=0.04)
    view.write(f"/plan/{name}", u, t_ns)

    poses = PosesInFrame()
    fs.set_time(poses.timestamp, t_ns)
    poses.frame_id = fs.FRAME
    d = np.diff(p, axis=0)
    heading = np.arctan2(d[:, 1], d[:, 0])
    heading = np.append(heading, heading[-1:]) if len(heading) else np.zeros(len(p))
    for (x, y), th in zip(p, heading):
        fs.set_pose(poses.poses.add(), x, y, th)
    view.write(f"/plan/{name}/waypoints", poses, t_ns)
    lines = [fs.outline(p, 0.5, closed=False)] + [fs.outline(pts, 1.0, closed=False) for _, pts in edges]
    colors = [fs.COLORS["safe_path"]] + [fs.COLORS["corridor"]] * len(edges)
    view.write(f"/plan/{name}/points", fs.point_cloud(t_ns, np.vstack(lines), np.vstack(
        [np.tile(c, (len(pts), 1)) for pts, c in zip(lines, colors)])), t_ns)


# --------------------------------------------------------------------------- the commands' views

def _metadata(**kw) -> dict:
    from . import __version__

    return {"safenav": __version__, "frame": fs.FRAME, "time": "simulation time [ns]", **kw}


def navigation_view(path, scenario, safe: dict, recorded: dict, *, command: str = "run", seed=None) -> Path | None:
    """``safenav run``/``demo --view``: the world, each path type's safe path
    and corridor, and each recorded trial (``recorded`` maps
    ``(method, path type)`` to ``(navigator, trial result)``).  Does nothing
    when ``path`` is None."""
    if path is None:
        return None

    def fill(view):
        write_world(view, scenario.world)
        for name, p in safe.items():
            write_plan(view, name, p, scenario.risk_zones())
        for (method, name), (navigator, trial) in recorded.items():
            write_trial(view, f"{method}/{name}", navigator, trial, scenario.world)

    return write_view(path, fill, metadata=_metadata(command=command, scenario=scenario.name, seed=seed,
                                                     trials=", ".join(f"{m}/{n}" for m, n in recorded)))


def plan_view(path, scenario, trials: dict) -> Path | None:
    """``safenav plan --view``: the world, each planned path type and its
    recorded check trial (``trials`` maps a path type to ``(navigator, trial result)``)."""
    if path is None:
        return None

    def fill(view):
        write_world(view, scenario.world)
        for name, (navigator, trial) in trials.items():
            write_plan(view, name, np.asarray(navigator.problem.path), navigator.problem.zones)
            write_trial(view, f"check/{name}", navigator, trial, scenario.world)

    return write_view(path, fill, metadata=_metadata(command="plan", scenario=scenario.name))


def replay_view(path, log, result, *, source: str = "") -> Path | None:
    """``safenav replay --view``: the log's landmarks and truth, and the
    replay's estimates with their covariance ellipses, observations and input statuses."""
    if path is None:
        return None
    return write_view(path, lambda view: write_replay(view, log, result),
                      metadata=_metadata(command="replay", log=source))

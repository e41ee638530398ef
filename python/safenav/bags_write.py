"""Logs and trajectories out: ROS 2 bags (MCAP), ROS 1 bags and TUM files.

* :func:`write_bag` writes a :class:`~safenav.logs.Log` as a bag of the
  standard messages that :func:`safenav.bags.read_bag` reads back (its module
  doc has the topics and conventions), plus ``landmarks.csv`` (the map,
  ``id,x,y``) in the bag's folder.  Every motion row becomes one
  ``nav_msgs/Odometry`` message carrying both readings of the row: the pose
  integrated from the rows (:func:`integrate_odometry`) and the twist (speed,
  and yaw rate = Δθ / Δt), after one first message that starts the
  increments.  Read back in the matching mode (pose increments for
  ``odometry`` rows, ``--odom-twist`` for ``motion`` rows) a log gives the
  same rows up to the rounding of stamps to nanoseconds and of float32
  fields (``sensor_msgs/Range``'s range and variance).
* :func:`write_trajectories` writes a replay's estimate, and the truth where
  there is one, as TUM files (``trajectory.tum``, ``truth.tum``: ``t x y z qx
  qy qz qw``, evo's ``read_tum_trajectory_file`` reads them) and as
  ``nav_msgs/Odometry`` with covariance in ``trajectory.mcap`` (topics
  ``/estimate`` and ``/ground_truth``).

Files are written with :func:`safenav.results.atomic_write` (``rosbags``
writes into a temporary folder; each of its files is then copied in
atomically), so they are recorded in a run folder's manifest.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from .logs import Log
from .results import TEMP_PREFIX, atomic_write, write_text

__all__ = ["write_bag", "write_trajectories", "integrate_odometry", "STORAGES"]

#: write_bag's storages: rosbag2 with MCAP or sqlite3 storage (a folder), or a ROS 1 .bag file.
STORAGES = ("mcap", "sqlite3", "ros1")
_ODOM, _RANGE = "nav_msgs/msg/Odometry", "sensor_msgs/msg/Range"
_POSE_COV = "geometry_msgs/msg/PoseWithCovarianceStamped"


def integrate_odometry(distance, heading_change, pose0=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Poses (n + 1, 3) = (x, y, θ) from ``pose0`` and n increments:
    θₖ = θₖ₋₁ + Δθₖ, (xₖ, yₖ) = (xₖ₋₁, yₖ₋₁) + dₖ (cos, sin)(θₖ₋₁ + Δθₖ/2)
    (the mid-interval heading; :func:`safenav.bags.read_bag` inverts it)."""
    d = np.asarray(distance, dtype=float)
    dh = np.asarray(heading_change, dtype=float)
    h = pose0[2] + np.concatenate([[0.0], np.cumsum(dh)])
    mid = h[:-1] + dh / 2.0
    x = pose0[0] + np.concatenate([[0.0], np.cumsum(d * np.cos(mid))])
    y = pose0[1] + np.concatenate([[0.0], np.cumsum(d * np.sin(mid))])
    return np.column_stack([x, y, h])


class _Messages:
    """Builds standard messages in one typestore and collects them, serialised, per topic."""

    def __init__(self, ros1: bool):
        from rosbags.typesys import Stores, get_typestore

        self.ros1 = ros1
        self.ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_JAZZY)
        self.T = self.ts.types
        self.serialize = self.ts.serialize_ros1 if ros1 else self.ts.serialize_cdr
        self.out: list[tuple[int, str, str, bytes]] = []    # (record ns, topic, type, data)

    def header(self, ns: int, frame: str):
        sec, nsec = divmod(int(ns), 1_000_000_000)
        stamp = self.T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
        if self.ros1:
            return self.T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)
        return self.T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def pose(self, x: float, y: float, yaw: float):
        T = self.T
        q = (0.0, 0.0, 0.0, 0.0) if np.isnan(yaw) else (0.0, 0.0, float(np.sin(yaw / 2)), float(np.cos(yaw / 2)))
        point = T["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0)
        quaternion = T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])
        return T["geometry_msgs/msg/Pose"](position=point, orientation=quaternion)

    def odometry(self, ns, x, y, yaw, v=0.0, w=0.0, pose_cov=None, twist_cov=None):
        T = self.T
        vec = T["geometry_msgs/msg/Vector3"]
        twist = T["geometry_msgs/msg/Twist"](linear=vec(x=float(v), y=0.0, z=0.0),
                                             angular=vec(x=0.0, y=0.0, z=float(w)))
        return T[_ODOM](header=self.header(ns, "map"), child_frame_id="base_link",
                        pose=T["geometry_msgs/msg/PoseWithCovariance"](
                            pose=self.pose(x, y, yaw), covariance=np.zeros(36) if pose_cov is None else pose_cov),
                        twist=T["geometry_msgs/msg/TwistWithCovariance"](
                            twist=twist, covariance=np.zeros(36) if twist_cov is None else twist_cov))

    def pose_cov(self, ns, frame, x, y, yaw, cov):
        T = self.T
        return T[_POSE_COV](header=self.header(ns, frame),
                            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(x, y, yaw), covariance=cov))

    def range(self, ns, lid, r, std):
        fields = dict(header=self.header(ns, f"landmark_{int(lid)}"), radiation_type=1, field_of_view=0.0,
                      min_range=0.0, max_range=float("inf"), range=float(r))
        if not self.ros1:
            fields["variance"] = float(std) ** 2
        return self.T[_RANGE](**fields)

    def add(self, topic: str, ns: int, msg, record: int | None = None) -> None:
        """Collect ``msg`` with record time ``record`` [ns] (default: its stamp ``ns``)."""
        ns = int(ns) if record is None else int(record)
        self.out.append((max(ns, 0), topic, msg.__msgtype__, self.serialize(msg, msg.__msgtype__)))

    def write(self, path: Path, storage: str) -> None:
        """Write the collected messages, in record-time order (stable), to a new bag at ``path``."""
        order = sorted(range(len(self.out)), key=lambda i: self.out[i][0])
        if storage == "ros1":
            from rosbags.rosbag1 import Writer as Writer1

            writer = Writer1(path)
        else:
            from rosbags.rosbag2 import StoragePlugin, Writer

            plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
            writer = Writer(path, version=Writer.VERSION_LATEST, storage_plugin=plugin)
        with writer:
            conns = {}
            for _, topic, msgtype, _ in self.out:
                if topic not in conns:
                    conns[topic] = writer.add_connection(topic, msgtype, typestore=self.ts)
            for i in order:
                ns, topic, _, data = self.out[i]
                writer.write(conns[topic], ns, data)


def _ns(t) -> np.ndarray:
    """Times [s] as integer nanoseconds (a stamp's resolution)."""
    return np.round(np.asarray(t, dtype=float) * 1e9).astype(np.int64)


def _add_motion(m: _Messages, ev: pd.DataFrame, topic: str) -> None:
    """The motion rows as Odometry messages: a first message, then one per row (module doc)."""
    rows = ev[ev["kind"].isin(("odometry", "motion"))]
    if not len(rows):
        raise ValueError("the log has no odometry or motion rows: a bag needs its odometry topic")
    ns = _ns(rows["t"])
    gap = int(ns[1] - ns[0]) if len(ns) > 1 and ns[1] > ns[0] else 100_000_000
    ns = np.concatenate([[ns[0] - gap], ns])
    if (np.diff(ns) <= 0).any():
        i = int(np.flatnonzero(np.diff(ns) <= 0)[0])
        raise ValueError(f"two motion rows at t = {rows['t'].iloc[i]!r} s: an odometry topic's stamps must increase")
    dt = np.diff(ns / 1e9)        # as read_bag computes it from the stamps
    motion = (rows["kind"] == "motion").to_numpy()
    speed = np.where(motion, rows["speed"].to_numpy(float), rows["distance"].to_numpy(float) / dt)
    dist = np.where(motion, speed * dt, rows["distance"].to_numpy(float))
    dh = rows["heading_change"].to_numpy(float)
    pose = integrate_odometry(dist, dh)
    rate = np.concatenate([[0.0], dh / dt])
    speed = np.concatenate([[0.0], speed])
    for k in range(len(ns)):
        m.add(topic, ns[k], m.odometry(ns[k], pose[k, 0], pose[k, 1], pose[k, 2], speed[k], rate[k]))


def _add_observations(m: _Messages, ev: pd.DataFrame, topics: dict) -> None:
    """Ranges, bearings (a range_bearing row gives both, with one stamp) and fixes, in the log's order."""
    kinds = ev["kind"].to_numpy()
    ns = _ns(ev["t"])
    lm = ev["landmark"].fillna(-1).to_numpy(np.int64)
    c = {k: ev[k].to_numpy(float) for k in ("x", "y", "range", "bearing", "range_std", "bearing_std", "std_x", "std_y")}
    for i in range(len(ev)):
        k = kinds[i]
        if k in ("range", "range_bearing"):
            m.add(topics["ranges"], ns[i], m.range(ns[i], lm[i], c["range"][i], c["range_std"][i]))
        if k in ("bearing", "range_bearing"):
            if m.ros1:
                raise ValueError("a ROS 1 bag is written with ranges only (its Range has no variance); "
                                 "this log has bearings")
            cov = np.zeros(36)
            cov[35] = c["bearing_std"][i] ** 2
            m.add(topics["bearings"], ns[i], m.pose_cov(ns[i], f"landmark_{lm[i]}", 0.0, 0.0, c["bearing"][i], cov))
        elif k == "fix":
            cov = np.zeros(36)
            cov[0], cov[7] = c["std_x"][i] ** 2, c["std_y"][i] ** 2
            m.add(topics["fix"], ns[i], m.pose_cov(ns[i], "map", c["x"][i], c["y"][i], 0.0, cov))


def _copy_in(src: Path, dst: Path) -> None:
    """Copy the file ``src`` to ``dst`` through :func:`atomic_write`."""
    def copy(fh):
        with open(src, "rb") as f:
            shutil.copyfileobj(f, fh)
    atomic_write(dst, copy)


def write_bag(log: Log, out, *, storage: str = "mcap", topics: dict | None = None) -> Path:
    """Write ``log`` as a bag at ``out`` (module doc): a rosbag2 folder
    (``storage`` ``mcap`` or ``sqlite3``) with ``landmarks.csv`` in it, or for
    ``ros1`` a ``.bag`` file with ``landmarks.csv`` beside it (ranges only:
    ROS 1's Range has no variance).  ``topics`` overrides
    :data:`safenav.bags.TOPICS` by role.  Returns ``out``."""
    from .bags import TOPICS

    if storage not in STORAGES:
        raise ValueError(f"storage {storage!r}: one of {', '.join(STORAGES)}")
    out = Path(out)
    names = {**TOPICS, **(topics or {})}
    m = _Messages(ros1=storage == "ros1")
    _add_motion(m, log.events, names["odom"])
    _add_observations(m, log.events, names)
    if log.truth is not None:
        for t, x, y, h in log.truth[["t", "x", "y", "heading"]].itertuples(index=False):
            ns = int(_ns(t))
            m.add(names["ground_truth"], ns, m.odometry(ns, x, y, h))
    folder = out.parent if storage == "ros1" else out
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=TEMP_PREFIX, dir=folder) as tmp:
        bag = Path(tmp) / ("bag.bag" if storage == "ros1" else out.name)
        m.write(bag, storage)
        if storage == "ros1":
            _copy_in(bag, out)
        else:
            for f in sorted(bag.iterdir()):
                _copy_in(f, out / f.name)
    ids = list(log.landmarks)
    xy = np.array([log.landmarks[i] for i in ids], dtype=float).reshape(-1, 2)
    table = pd.DataFrame({"id": ids, "x": xy[:, 0], "y": xy[:, 1]})
    write_text(folder / "landmarks.csv", table.to_csv(index=False))
    return out


def _tum(t, x, y, h) -> str:
    """TUM lines ``t x y z qx qy qz qw`` (z = 0, yaw-only quaternion; identity where the heading is unknown)."""
    h = np.asarray(h, dtype=float)
    known = ~np.isnan(h)
    qz = np.where(known, np.sin(np.where(known, h, 0.0) / 2), 0.0)
    qw = np.where(known, np.cos(np.where(known, h, 0.0) / 2), 1.0)
    return "".join(f"{a!r} {b!r} {c!r} 0.0 0.0 0.0 {d!r} {e!r}\n"
                   for a, b, c, d, e in zip(*(np.asarray(v, dtype=float).tolist() for v in (t, x, y, qz, qw))))


def write_trajectories(out, trajectory: pd.DataFrame, truth: pd.DataFrame | None) -> list[Path]:
    """``trajectory.tum``, ``truth.tum`` (with truth) and ``trajectory.mcap`` in
    the folder ``out`` (module doc).  ``trajectory`` has
    :data:`safenav.replay.TRAJECTORY_COLUMNS`; in the MCAP file each estimate
    is a ``nav_msgs/Odometry`` on ``/estimate`` with its covariance (x, y,
    their cross term and the heading's in the pose covariance, the speed's in
    the twist covariance), the truth on ``/ground_truth``."""
    out = Path(out)
    tr = trajectory
    paths = [write_text(out / "trajectory.tum", _tum(tr["t"], tr["x"], tr["y"], tr["heading"]))]
    if truth is not None:
        paths.append(write_text(out / "truth.tum", _tum(truth["t"], truth["x"], truth["y"], truth["heading"])))
    m = _Messages(ros1=False)
    cols = [tr[c].to_numpy(float) for c in ("t", "x", "y", "heading", "speed", "var_x", "var_y", "cov_xy",
                                             "var_heading", "var_speed")]
    for t, x, y, h, v, vx, vy, cxy, vh, vv in zip(*cols):
        pc, tc = np.zeros(36), np.zeros(36)
        pc[0], pc[1], pc[6], pc[7], pc[35] = vx, cxy, cxy, vy, vh
        tc[0] = vv
        ns = int(_ns(t))
        m.add("/estimate", ns, m.odometry(ns, x, y, h, v, 0.0, pc, tc))
    for t, x, y, h in ([] if truth is None else truth[["t", "x", "y", "heading"]].itertuples(index=False)):
        ns = int(_ns(t))
        m.add("/ground_truth", ns, m.odometry(ns, x, y, h))
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=TEMP_PREFIX, dir=out) as tmp:
        bag = Path(tmp) / "trajectory"
        m.write(bag, "mcap")
        paths.append(out / "trajectory.mcap")
        _copy_in(bag / "trajectory.mcap", paths[-1])
    return paths

"""Robot logs in ROS bags: a bag's standard messages as a :class:`~safenav.logs.Log`.

:func:`read_bag` reads, through the pure-Python ``rosbags`` library (no ROS
installed), a ROS 2 bag (a rosbag2 folder with sqlite3 or MCAP storage, or a
single ``.mcap`` file) or a ROS 1 ``.bag`` file, and converts the messages of
its topics into the log table of ``docs/replay.md``, so that
:func:`safenav.replay.replay` runs unchanged on it.  The topics
(:data:`TOPICS`, each named by a ``--ROLE TOPIC`` flag of ``safenav replay``):

* ``odom`` (``nav_msgs/Odometry``, default ``/odom``, required): wheel
  odometry.  By default the increments of its pose between consecutive
  messages give ``odometry`` rows: the heading change Δθ = wrap(θₖ − θₖ₋₁)
  and the signed distance along the mid-interval heading,
  d = Δx cos(θₖ₋₁ + Δθ/2) + Δy sin(θₖ₋₁ + Δθ/2) (the inverse of
  :func:`safenav.bags_write.integrate_odometry`).  With ``odom_twist`` its
  twist gives ``motion`` rows instead: speed = ``twist.linear.x`` and
  Δθ = ``twist.angular.z`` · Δt over the interval since the previous message.
  The first message only starts the increments.
* ``imu`` (``sensor_msgs/Imu``, default ``/imu``): the yaw rate
  ``angular_velocity.z``.  When present, each motion row's heading change is
  the yaw rate's integral over the row's interval (trapezoidal between
  samples, the rate held constant beyond the first and last), replacing
  the odometry's.  The log format has no separate yaw-rate input, so the
  IMU enters through the heading change that the motion model already takes.
* ``ranges`` (``sensor_msgs/Range``, default ``/ranges``): the range to the
  landmark named by ``header.frame_id`` = ``landmark_<id>``; σ = √variance
  (the ``variance`` field of ROS 2 Jazzy and later) or ``range_std`` where
  the message has none.  Non-finite ranges (REP 117: no detection) are
  skipped.
* ``bearings`` (``geometry_msgs/PoseWithCovarianceStamped``, default
  ``/bearings``): the bearing to landmark ``landmark_<id>`` as the yaw of
  the pose's orientation in the vehicle frame, σ² = covariance[35] (yaw).
  A range and a bearing of one landmark with one stamp form one
  ``range_bearing`` row (one joint update, as one camera sighting).
* ``fix`` (``geometry_msgs/PoseWithCovarianceStamped``, default ``/fix``):
  position fixes, σ_x² = covariance[0], σ_y² = covariance[7] (the fix
  model has no cross term; covariance[1] is not used).
* ``ground_truth`` (``nav_msgs/Odometry``, ``geometry_msgs/PoseStamped`` or
  ``PoseWithCovarianceStamped``, default ``/ground_truth``): ``truth`` rows;
  an all-zero quaternion means the heading is unknown (NaN).

Times are header stamps, never record times.  Only ``odom`` must be in the
bag; a topic named explicitly must be there too; ``None`` switches a role
off.  A missing required topic, an unusable message type, a frame_id that is
not ``landmark_<id>`` or names a landmark the map lacks, and stamps that go
back in time on a topic are each one ``ValueError`` naming the bag and the
topic.  Rows of one stamp are ordered: motion, then observations (in each
topic's order), then fixes.  The map is ``{id: (x, y)}``, read by
:func:`read_map` from a CSV (``id,x,y``) or a scenario file.
"""

from __future__ import annotations

import argparse
import contextlib
import re
from pathlib import Path

import numpy as np
import pandas as pd

from .bags_write import TOPICS
from .logs import COLUMNS, Log
from .validation import INT32_MAX

__all__ = ["TOPICS", "MESSAGE_TYPES", "read_bag", "read_map", "is_bag", "add_bag_arguments", "load",
           "add_convert_command"]

_ODOM, _IMU, _RANGE = "nav_msgs/msg/Odometry", "sensor_msgs/msg/Imu", "sensor_msgs/msg/Range"
_POSE_COV, _POSE = "geometry_msgs/msg/PoseWithCovarianceStamped", "geometry_msgs/msg/PoseStamped"
#: role -> the message types it reads.
MESSAGE_TYPES = {"odom": (_ODOM,), "imu": (_IMU,), "ranges": (_RANGE,), "bearings": (_POSE_COV,),
                 "fix": (_POSE_COV,), "ground_truth": (_ODOM, _POSE, _POSE_COV)}
_FRAME = re.compile(r"landmark_(\d+)\Z")
_ROLE_HELP = {"odom": "wheel odometry", "imu": "yaw rate", "ranges": "landmark ranges (frame_id landmark_<id>)",
              "bearings": "landmark bearings (frame_id landmark_<id>)", "fix": "position fixes",
              "ground_truth": "ground truth"}
#: rows of one stamp: motion first, then observations, then fixes (the order of the log files we write).
_PRIORITY = {"odometry": 0, "motion": 0, "range": 1, "bearing": 1, "range_bearing": 1, "fix": 2}


def is_bag(path) -> bool:
    """Whether ``path`` is a bag: a ``.bag`` or ``.mcap`` file, or a folder with
    a rosbag2 ``metadata.yaml`` or ``.mcap``/``.db3`` storage."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file() or any(p.glob("*.mcap")) or any(p.glob("*.db3"))
    return p.suffix.lower() in (".bag", ".mcap")


def read_map(path) -> dict[int, tuple[float, float]]:
    """A landmark map ``{id: (x, y)}`` from a CSV with columns ``id,x,y`` or a
    scenario file (``.toml``/``.json``: its ``world.landmarks``)."""
    p = Path(path)
    if p.suffix.lower() in (".toml", ".json"):
        from .scenario import load_scenario

        return {int(lm.id): (float(lm.position[0]), float(lm.position[1]))
                for lm in load_scenario(p).world.landmarks}
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such map file")
    try:
        df = pd.read_csv(p)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise ValueError(f"{p}: not a CSV map with columns id,x,y ({exc})") from None
    if list(df.columns) != ["id", "x", "y"]:
        raise ValueError(f"{p}: a map's columns are id,x,y, got {','.join(map(str, df.columns))}")
    ids, x, y = (pd.to_numeric(df[c], errors="coerce").to_numpy(float) for c in ("id", "x", "y"))
    with np.errstate(invalid="ignore"):
        bad = ~((ids == np.floor(ids)) & (ids >= 0) & (ids <= INT32_MAX) & np.isfinite(x) & np.isfinite(y))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        row = df.astype(object).iloc[i].tolist()
        raise ValueError(f"{p}: row {i + 1} = {row}: an id is an integer in [0, {INT32_MAX}], x and y are finite "
                         "numbers")
    xy = np.column_stack([x, y])
    if len(set(ids.tolist())) != len(ids):
        raise ValueError(f"{p}: duplicate landmark id {pd.Series(ids)[pd.Series(ids).duplicated()].iloc[0]}")
    return {int(i): (float(x), float(y)) for i, (x, y) in zip(ids, xy)}


# --------------------------------------------------------------------------- reading messages

def _pose(p) -> tuple:
    """x, y and the quaternion of a geometry_msgs/Pose."""
    o = p.orientation
    return p.position.x, p.position.y, o.x, o.y, o.z, o.w


#: role -> the fields read from each message (taken at once: keeping whole messages costs the
#: garbage collector more than deserialising them).
_FIELDS = {
    "odom": lambda m: (*_pose(m.pose.pose), m.twist.twist.linear.x, m.twist.twist.angular.z),
    "imu": lambda m: (m.angular_velocity.z,),
    "ranges": lambda m: (m.range, getattr(m, "variance", 0.0)),
    "bearings": lambda m: (*_pose(m.pose.pose), m.pose.covariance[35]),
    "fix": lambda m: (*_pose(m.pose.pose), m.pose.covariance[0], m.pose.covariance[7]),
    "ground_truth": lambda m: _pose(m.pose.pose if hasattr(m.pose, "pose") else m.pose),
}


def _yaw(q: np.ndarray) -> np.ndarray:
    """The yaw (rotation about z) of quaternions (n, 4) = (x, y, z, w); NaN for the all-zero "unknown" one."""
    x, y, z, w = q.T
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.where((q == 0.0).all(axis=1), np.nan, yaw)


def _wrap(a):
    """Angles wrapped to (−π, π]."""
    return np.pi - np.mod(np.pi - np.asarray(a, dtype=float), 2.0 * np.pi)


class _Topic:
    """One role's messages: stamps, frame ids and the fields of :data:`_FIELDS` (columns of ``v``)."""

    def __init__(self, bag: "_Bag", role: str, name: str, ns=(), frames=(), values=()):
        self.bag, self.role, self.name = bag, role, name
        self.ns = np.array(ns, dtype=np.int64)
        self.frames = list(frames)
        self.v = np.array(values, dtype=float).reshape(len(self.ns), -1 if len(self.ns) else 0)

    def __len__(self) -> int:
        return len(self.ns)

    def fail(self, problem: str, i: int | None = None):
        at = "" if i is None else f"message {i + 1} at {float(self.ns[i]) / 1e9!r} s: "
        raise ValueError(f"{self.bag.name}: topic {self.name!r}: {at}{problem}")

    def stamps(self, *, strict: bool = False) -> np.ndarray:
        """Header stamps [s], checked to never go back in time (``strict``: to increase)."""
        d = np.diff(self.ns)
        bad = np.flatnonzero(d <= 0 if strict else d < 0)
        if len(bad):
            i = int(bad[0]) + 1
            self.fail(f"header stamps are not {'increasing' if strict else 'monotonic'}: it follows "
                      f"{float(self.ns[i - 1]) / 1e9!r} s", i)
        return self.ns / 1e9

    def landmark_ids(self, landmarks) -> np.ndarray:
        """The landmark id of each message's ``header.frame_id`` (``landmark_<id>``), checked against the map."""
        ids = np.empty(len(self), dtype=np.int64)
        for i, frame in enumerate(self.frames):
            hit = _FRAME.match(frame)
            if hit is None:
                self.fail(f"frame_id {frame!r} does not name a landmark (landmark_<id>)", i)
            lid = int(hit.group(1))
            if lid not in landmarks:
                known = sorted(landmarks)
                self.fail(f"frame_id {frame!r}: unknown landmark {lid} (the map has "
                          f"{known[:10]}{' ...' if len(known) > 10 else ''})", i)
            ids[i] = lid
        return ids


class _Bag:
    """An open bag: its topics by name."""

    def __init__(self, reader, name: str):
        self.reader = reader
        self.name = name
        self.connections: dict[str, list] = {}
        for c in reader.connections:
            self.connections.setdefault(c.topic, []).append(c)

    def topic(self, role: str, name: str | None, required: bool) -> _Topic:
        """The messages of topic ``name`` for ``role`` in the bag's order (none when absent and not
        required), after checking the message type."""
        conns = self.connections.get(name) if name else None
        if not conns:
            if required:
                raise ValueError(f"{self.name}: no topic {name!r} for {role} (the bag has: "
                                 f"{', '.join(sorted(self.connections)) or 'no topics'}; name another with "
                                 f"--{role.replace('_', '-')} TOPIC)")
            return _Topic(self, role, name or "")
        for c in conns:
            if c.msgtype not in MESSAGE_TYPES[role]:
                skip = "" if required else f"; --{role.replace('_', '-')} none skips it"
                raise ValueError(f"{self.name}: topic {name!r}: message type {c.msgtype} cannot be read as {role} "
                                 f"(it takes {' or '.join(MESSAGE_TYPES[role])}{skip})")
        de, fields = self.reader.deserialize, _FIELDS[role]
        ns, frames, values = [], [], []
        for c, _, raw in self.reader.messages(connections=conns):
            m = de(raw, c.msgtype)
            stamp = m.header.stamp
            ns.append(stamp.sec * 1_000_000_000 + stamp.nanosec)
            frames.append(m.header.frame_id)
            values.append(fields(m))
        return _Topic(self, role, name, ns, frames, values)


def _rows(kind: str, t, **cells) -> pd.DataFrame:
    return pd.DataFrame({"t": t, "kind": kind, **cells})


def _motion(odom: _Topic, twist: bool) -> pd.DataFrame:
    """odometry (pose increments) or motion (twist) rows of an Odometry topic (module doc)."""
    t = odom.stamps(strict=True)
    if len(odom) < 2:
        odom.fail(f"{len(odom)} message(s): odometry needs two or more (the first one starts the increments)")
    if twist:
        return _rows("motion", t[1:], speed=odom.v[1:, 6], heading_change=odom.v[1:, 7] * np.diff(t))
    h = _yaw(odom.v[:, 2:6])
    if np.isnan(h).any():
        odom.fail("a zero quaternion (no heading)", int(np.flatnonzero(np.isnan(h))[0]))
    dh = _wrap(np.diff(h))
    mid = h[:-1] + dh / 2.0
    dx, dy = np.diff(odom.v[:, 0]), np.diff(odom.v[:, 1])
    return _rows("odometry", t[1:], distance=dx * np.cos(mid) + dy * np.sin(mid), heading_change=dh)


def _imu_heading_change(imu: _Topic, t_rows: np.ndarray, t_first: float) -> np.ndarray:
    """∫ω dt of the IMU yaw rate over each motion row's interval (module doc)."""
    ts = imu.stamps(strict=True)
    w = imu.v[:, 0]
    cum = np.concatenate([[0.0], np.cumsum(np.diff(ts) * (w[1:] + w[:-1]) / 2.0)])

    def integral(tq):
        i = np.clip(np.searchsorted(ts, tq, side="right") - 1, 0, len(ts) - 1)
        dt = tq - ts[i]
        slope = np.zeros_like(tq)
        inner = (i < len(ts) - 1) & (dt > 0)
        j = i[inner]
        slope[inner] = (w[j + 1] - w[j]) / (ts[j + 1] - ts[j])
        return cum[i] + w[i] * dt + 0.5 * slope * dt * dt

    return np.diff(integral(np.concatenate([[t_first], t_rows])))


def _observations(ranges: _Topic, bearings: _Topic, landmarks, range_std: float) -> list[pd.DataFrame]:
    """range, bearing and range_bearing rows (a range and a bearing of one landmark at one stamp joined)."""
    parts = {}
    if len(ranges):
        t, ids = ranges.stamps(), ranges.landmark_ids(landmarks)
        r, var = ranges.v[:, 0], ranges.v[:, 1]
        std = np.where(var > 0, np.sqrt(np.where(var > 0, var, 1.0)), range_std)
        keep = np.isfinite(r)
        if (r[keep] < 0).any():
            i = int(np.flatnonzero(keep & (r < 0))[0])
            ranges.fail(f"range {r[i]} < 0", i)
        parts["range"] = pd.DataFrame({"t": t, "landmark": ids, "range": r, "range_std": std,
                                       "seq": np.arange(len(r))})[keep]
    if len(bearings):
        t, ids = bearings.stamps(), bearings.landmark_ids(landmarks)
        b, var = _yaw(bearings.v[:, 2:6]), bearings.v[:, 6]
        bad = np.flatnonzero(~(var > 0) | np.isnan(b))
        if len(bad):
            bearings.fail(f"a bearing needs an orientation and covariance[35] (yaw variance) > 0, got "
                          f"{var[bad[0]]}", int(bad[0]))
        parts["bearing"] = pd.DataFrame({"t": t, "landmark": ids, "bearing": b, "bearing_std": np.sqrt(var),
                                         "seq": np.arange(len(b))})
    if len(parts) == 2:   # one sighting: the same landmark at the same stamp on both topics
        r, b = parts["range"], parts["bearing"]
        r = r.assign(k=r.groupby(["t", "landmark"]).cumcount())
        b = b.assign(k=b.groupby(["t", "landmark"]).cumcount())
        both = r.merge(b.drop(columns="seq"), on=["t", "landmark", "k"], how="outer", indicator=True, sort=False)
        both["seq"] = both["seq"].fillna(-1)
        kind = both["_merge"].map({"both": "range_bearing", "left_only": "range", "right_only": "bearing"})
        return [both.drop(columns=["k", "_merge"]).assign(kind=kind.astype(str))]
    return [df.assign(kind=kind) for kind, df in parts.items()]


def _truth(truth: _Topic) -> pd.DataFrame | None:
    if not len(truth):
        return None
    return _rows("truth", truth.stamps(), x=truth.v[:, 0], y=truth.v[:, 1], heading=_yaw(truth.v[:, 2:6]))


def _fixes(fix: _Topic) -> pd.DataFrame | None:
    if not len(fix):
        return None
    t, cov = fix.stamps(), fix.v[:, 6:8]
    bad = np.flatnonzero(~(cov > 0).all(axis=1))
    if len(bad):
        fix.fail(f"a fix needs covariance[0] and [7] (x, y variance) > 0, got {cov[bad[0]].tolist()}", int(bad[0]))
    return _rows("fix", t, x=fix.v[:, 0], y=fix.v[:, 1], std_x=np.sqrt(cov[:, 0]), std_y=np.sqrt(cov[:, 1]),
                 seq=np.arange(len(t)))


@contextlib.contextmanager
def _open(path: Path):
    """An open rosbags ``AnyReader`` on the bag ``path``; an unreadable bag is a ValueError naming it."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such bag")
    store = Stores.ROS1_NOETIC if p.suffix.lower() == ".bag" else Stores.ROS2_JAZZY
    try:
        reader = AnyReader([p], default_typestore=get_typestore(store))
        reader.open()
    except Exception as exc:  # rosbags raises its own error classes (and struct, OS errors) for unreadable bags
        raise ValueError(f"{p}: not a readable ROS bag ({type(exc).__name__}: {exc})") from None
    try:
        yield reader
    finally:
        reader.close()


def read_bag(path, landmarks=None, *, topics: dict | None = None, odom_twist: bool = False,
             range_std: float = 1.0) -> Log:
    """The :class:`~safenav.logs.Log` of a ROS bag (module doc).

    ``landmarks`` is the map ``{id: (x, y)}`` (or a path for :func:`read_map`;
    default: ``landmarks.csv`` in the rosbag2 folder, or beside a bag file, when
    there is one).  ``topics`` overrides :data:`TOPICS` by role; a topic given
    there must be in the bag, and ``None`` switches the role off.
    ``odom_twist`` reads the odometry's twist (``motion`` rows) instead of its
    pose increments (``odometry`` rows).  ``range_std`` is the σ of ranges
    whose message has no variance.
    """
    from .logs import parse_table

    p = Path(path)
    topics = dict(topics or {})
    unknown = set(topics) - set(TOPICS)
    if unknown:
        raise ValueError(f"unknown bag topic role {sorted(unknown)[0]!r} (the roles are: {', '.join(TOPICS)})")
    if "odom" in topics and topics["odom"] is None:
        raise ValueError("the odom topic cannot be switched off: the localizer needs a motion input")
    names = {role: topics.get(role, default) for role, default in TOPICS.items()}
    if landmarks is None:
        found = (p if p.is_dir() else p.parent) / "landmarks.csv"
        landmarks = read_map(found) if found.is_file() else {}
    elif not isinstance(landmarks, dict):
        landmarks = read_map(landmarks)
    with _open(p) as reader:
        bag = _Bag(reader, str(p))
        msgs = {role: bag.topic(role, name, required=name is not None and (role == "odom" or role in topics))
                for role, name in names.items()}
    motion = _motion(msgs["odom"], odom_twist)
    if len(msgs["imu"]):
        t_rows = motion["t"].to_numpy()
        motion["heading_change"] = _imu_heading_change(msgs["imu"], t_rows, msgs["odom"].ns[0] / 1e9)
    motion["seq"] = np.arange(len(motion))
    if (len(msgs["ranges"]) or len(msgs["bearings"])) and not landmarks:
        raise ValueError(f"{p}: landmark observations on {msgs['ranges'].name or msgs['bearings'].name!r} but no map: "
                         "give --map FILE (a CSV id,x,y or a scenario file) or put landmarks.csv in the bag's folder")
    obs = _observations(msgs["ranges"], msgs["bearings"], landmarks, range_std)
    fixes = _fixes(msgs["fix"])
    events = pd.concat([motion, *obs, *([] if fixes is None else [fixes])], ignore_index=True)
    order = np.lexsort((events["seq"].to_numpy(), events["kind"].map(_PRIORITY).to_numpy(), events["t"].to_numpy()))
    events = events.iloc[order].drop(columns="seq")
    ids = list(landmarks)
    xy = np.array([landmarks[i] for i in ids], dtype=float).reshape(-1, 2)
    table = pd.concat([pd.DataFrame({"kind": "landmark", "landmark": ids, "x": xy[:, 0], "y": xy[:, 1]}), events,
                       _truth(msgs["ground_truth"])], ignore_index=True)
    return parse_table(table.reindex(columns=list(COLUMNS)).astype({"landmark": float}), str(p))


# --------------------------------------------------------------------------- command line

def add_bag_arguments(parser: argparse.ArgumentParser) -> None:
    """``safenav replay``'s bag flags: one per topic role, ``--odom-twist`` and ``--map``."""
    g = parser.add_argument_group("ROS bags (rosbag2 folder, .mcap or ROS 1 .bag; docs/bags.md)")
    for role, default in TOPICS.items():
        types = " or ".join(t.replace("/msg/", "/") for t in MESSAGE_TYPES[role])
        used = "" if role == "odom" else ", read when present; none: off"
        g.add_argument(f"--{role.replace('_', '-')}", dest=f"topic_{role}", metavar="TOPIC", default=None,
                       help=f"{_ROLE_HELP[role]}: a {types} topic (default {default}{used})")
    g.add_argument("--odom-twist", action="store_true",
                   help="motion rows from the odometry's twist instead of odometry rows from its pose increments")
    g.add_argument("--map", default=None, metavar="FILE",
                   help="landmark map: a CSV id,x,y or a scenario file (default: landmarks.csv in the bag's folder)")


def load(args, range_std: float) -> Log:
    """The log of ``args.log``: a bag (:func:`read_bag` with the bag flags) or
    any log :func:`safenav.replay.load` reads."""
    from .replay import load as load_log

    if not is_bag(args.log):
        if args.map is not None or args.odom_twist or any(getattr(args, f"topic_{r}") for r in TOPICS):
            raise ValueError(f"{args.log}: the bag flags (--map, --odom-twist, topics) apply to ROS bags only")
        return load_log(args.log, range_std=range_std)
    topics = {}
    for role in TOPICS:
        name = getattr(args, f"topic_{role}")
        if name is not None:
            topics[role] = None if name.lower() == "none" else name
    return read_bag(args.log, args.map, topics=topics, odom_twist=args.odom_twist, range_std=range_std)


def add_convert_command(sub, parents, run_folder, wrote) -> None:
    """``safenav convert LOG OUT``: any log ``safenav replay`` reads, as a ROS 2 bag (MCAP) with landmarks.csv."""
    s = sub.add_parser("convert", parents=parents,
                       help="write a log (.csv, .parquet, Plaza .mat or a bag) as a ROS 2 bag (rosbag2 folder, MCAP "
                            "storage) with landmarks.csv (docs/bags.md)")
    s.add_argument("log", help="a log file, a Plaza .mat file or a ROS bag")
    s.add_argument("out", help="the rosbag2 folder to write")
    s.add_argument("--range-std", type=float, default=None,
                   help="range sigma of ranges without one (default: 0.55 m for a .mat file, the plaza preset's; "
                        "else 1 m)")
    add_bag_arguments(s)

    def convert(args) -> int:
        from .bags_write import write_bag
        from .replay import PLAZA_RANGE_STD

        mat = Path(args.log).suffix.lower() == ".mat"
        log = load(args, args.range_std if args.range_std is not None else PLAZA_RANGE_STD if mat else 1.0)
        with run_folder(args, args.out) as run:
            write_bag(log, args.out)
            hints = [h for h, needed in (("--odom-twist: its motion rows are twists",
                                              (log.events["kind"] == "motion").any()),
                                             ("--preset plaza, the preset of .mat files", mat)) if needed]
            print(f"{args.log}: {len(log.events)} inputs, {len(log.landmarks)} landmarks, "
                  f"{0 if log.truth is None else len(log.truth)} truth poses -> {args.out}"
                  + (f" (replay it with {'; '.join(hints)})" if hints else ""))
            wrote(run)
        return 0
    s.set_defaults(func=convert)

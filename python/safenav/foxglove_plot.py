"""Read a view back and draw it from above with matplotlib: what Foxglove's 3D
panel shows of a view (:mod:`safenav.foxglove`) at one time, for where no
viewer can run (documentation, reports, a quick look over ssh).

:func:`read_view` decodes every message with the schema stored in the file;
:func:`plot_view` draws, at time ``t``, the latest message of each topic at
or before it: scene entities (lines, triangles, cylinders, spheres, arrows,
texts), point clouds, and each pose topic's pose with its history as a line.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

__all__ = ["read_view", "plot_view"]


def read_view(path) -> dict[str, tuple[str, list]]:
    """``{topic: (schema name, [(log time ns, message)])}`` of an MCAP file of
    protobuf channels, each message decoded with a class built from the
    ``FileDescriptorSet`` stored in the file."""
    from google.protobuf import descriptor_pool, message_factory
    from google.protobuf.descriptor_pb2 import FileDescriptorSet
    from mcap.reader import make_reader

    out, classes = {}, {}
    with open(path, "rb") as fh:
        for schema, channel, msg in make_reader(fh).iter_messages(log_time_order=True):
            if channel.message_encoding != "protobuf":
                raise ValueError(f"{path}: topic {channel.topic!r} is {channel.message_encoding!r}, not protobuf")
            if schema.id not in classes:
                pool = descriptor_pool.DescriptorPool()
                for f in FileDescriptorSet.FromString(schema.data).file:
                    pool.Add(f)
                classes[schema.id] = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))
            out.setdefault(channel.topic, (schema.name, []))[1].append((msg.log_time,
                                                                         classes[schema.id].FromString(msg.data)))
    return out


def _rgba(c) -> tuple:
    return c.r, c.g, c.b, c.a


def _yaw(q) -> float:
    return 2.0 * math.atan2(q.z, q.w) if (q.x, q.y) == (0.0, 0.0) else math.atan2(
        2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _draw_entity(ax, e) -> None:
    """One ``foxglove.SceneEntity`` seen from above (poses of primitives: translation and yaw only)."""
    from matplotlib.collections import PolyCollection
    from matplotlib.patches import Circle, FancyArrow

    for ln in e.lines:
        p = np.array([(q.x, q.y) for q in ln.points]).reshape(-1, 2) + (ln.pose.position.x, ln.pose.position.y)
        if len(p) == 0:
            continue
        lw = max(0.3, 6.0 * ln.thickness)
        if ln.type == 2:                       # LINE_LIST: pairs
            for a, b in zip(p[0::2], p[1::2]):
                ax.plot([a[0], b[0]], [a[1], b[1]], "-", color=_rgba(ln.color), lw=lw)
        else:
            if ln.type == 1:                   # LINE_LOOP
                p = np.vstack([p, p[:1]])
            ax.plot(p[:, 0], p[:, 1], "-", color=_rgba(ln.color), lw=lw)
    for tl in e.triangles:
        p = np.array([(q.x, q.y) for q in tl.points]).reshape(-1, 3, 2)
        ax.add_collection(PolyCollection(p, facecolors=[_rgba(tl.color)], edgecolors="none"))
    for c in e.cylinders:
        ax.add_patch(Circle((c.pose.position.x, c.pose.position.y), c.size.x / 2, facecolor=_rgba(c.color),
                            edgecolor="none"))
    for s in e.spheres:
        ax.add_patch(Circle((s.pose.position.x, s.pose.position.y), s.size.x / 2, facecolor=_rgba(s.color),
                            edgecolor="none", zorder=4))
    for a in e.arrows:
        th, n = _yaw(a.pose.orientation), a.shaft_length + a.head_length
        ax.add_patch(FancyArrow(a.pose.position.x, a.pose.position.y, n * math.cos(th), n * math.sin(th),
                                width=a.shaft_diameter, head_width=a.head_diameter, head_length=a.head_length,
                                length_includes_head=True, color=_rgba(a.color), zorder=5))
    for t in e.texts:
        ax.text(t.pose.position.x, t.pose.position.y, t.text, color=_rgba(t.color), fontsize=6)


def _points(msg) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) and RGBA (0..1) of a ``foxglove.PointCloud`` with float32 x, y and uint8 colour fields."""
    names = {f.name: f.offset for f in msg.fields}
    raw = np.frombuffer(msg.data, dtype=np.uint8).reshape(-1, msg.point_stride)

    def col(name, dtype):
        off, size = names[name], np.dtype(dtype).itemsize
        return raw[:, off:off + size].copy().view(dtype)[:, 0].astype(float)

    xy = np.c_[col("x", "<f4"), col("y", "<f4")]
    rgba = (np.c_[[col(c, "u1") for c in ("red", "green", "blue", "alpha")]].T / 255.0 if "red" in names
            else np.tile([0.2, 0.2, 0.2, 1.0], (len(xy), 1)))
    return xy, rgba


def _draw_at(ax, view: dict, t_ns: int, *, clouds: bool) -> None:
    for topic, (schema, msgs) in view.items():
        before = [m for t, m in msgs if t <= t_ns]
        if not before:
            continue
        if schema == "foxglove.SceneUpdate":
            for e in before[-1].entities:
                _draw_entity(ax, e)
        elif schema == "foxglove.PointCloud" and (clouds or topic.endswith("landmarks")):
            xy, rgba = _points(before[-1])
            ax.scatter(xy[:, 0], xy[:, 1], s=4 if topic.endswith("landmarks") else 0.3, c=rgba, marker="^"
                       if topic.endswith("landmarks") else ".", zorder=3)
        elif schema == "foxglove.PoseInFrame":
            p = np.array([(m.pose.position.x, m.pose.position.y) for m in before])
            last = before[-1].pose
            th = _yaw(last.orientation)
            ax.plot(p[:, 0], p[:, 1], "-", color="0.3" if topic.endswith("truth") else "tab:red", lw=0.6, alpha=0.6)
            ax.plot(*p[-1], marker=(3, 0, math.degrees(th) - 90), ms=7, color="k" if topic.endswith("truth")
                    else "tab:red", zorder=6)


def plot_view(mcap_path, png_path, *, t_s: float | None = None, focus: str | None = None,
              zoom_m: float = 15.0, title: str | None = None, dpi: int = 90) -> Path:
    """Draw a view from above: the whole scene (left) and, around the pose
    topic ``focus`` (default: the first ``.../estimate`` topic), a window of
    ±``zoom_m`` metres (right), both at time ``t_s`` (default: the middle of
    the recording).  Point clouds (Rerun's copy of the outlines and lines)
    are left out where scene entities draw the same.  Writes a PNG with
    :func:`safenav.results.save_figure` and returns its path."""
    from .results import pyplot, save_figure

    view = read_view(mcap_path)
    times = [t for _, msgs in view.values() for t, _ in msgs]
    if not times:
        raise ValueError(f"{mcap_path}: holds no messages")
    t_ns = (min(times) + max(times)) // 2 if t_s is None else int(round(t_s * 1e9))
    poses = [k for k, (s, _) in view.items() if s == "foxglove.PoseInFrame" and k.endswith("estimate")]
    focus = focus or (poses[0] if poses else None)
    plt = pyplot()
    fig, axes = plt.subplots(1, 2 if focus else 1, figsize=(9.0 if focus else 4.8, 4.4), squeeze=False)
    for ax in axes[0]:
        _draw_at(ax, view, t_ns, clouds=False)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m] (frame map)")
    axes[0][0].set_ylabel("y [m]")
    axes[0][0].autoscale_view()
    axes[0][0].set_title(f"whole scene at t = {t_ns / 1e9:.2f} s", fontsize=9)
    if focus:
        msgs = [m for t, m in view[focus][1] if t <= t_ns] or [view[focus][1][0][1]]
        c = msgs[-1].pose.position
        axes[0][1].set_xlim(c.x - zoom_m, c.x + zoom_m)
        axes[0][1].set_ylim(c.y - zoom_m, c.y + zoom_m)
        axes[0][1].set_title(f"around {focus}", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.1, top=0.86, wspace=0.22)
    return save_figure(fig, png_path, dpi=dpi)

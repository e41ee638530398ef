"""Per-step content of a view (:mod:`safenav.foxglove`): a recorded trial of
the simulator, and a replayed log.

A recorded trial (``Navigator.run`` with ``record=True``; the trace Figs. 4–5
draw) holds, per row k = 0 … steps (time k·Δt): the true and estimated
states, √λ_max of the estimate's position covariance (``position_std``),
the position fix (NaN when none), the BMM prediction of the chosen control,
and per step the command (v, Δθ).  Those are what is written; the landmarks
in view at each fix step come from the core's own sensor model
(``SensorSettings.landmarks_in_view`` at the true state, with the true
obstacles hiding landmarks as in the simulator).  The trial's guard events
and Algorithm 1 actions are its totals (the core does not record them per
step): they are in the trial's closing ``foxglove.Log``.
"""

from __future__ import annotations

import numpy as np

from . import foxglove_scene as fs

__all__ = ["write_trial", "write_replay", "write_poses", "write_covariance", "write_observations", "write_commands",
           "write_events", "write_vehicle", "landmarks_in_view", "ns", "ELLIPSE_SIGMA"]

#: The k of the covariance ellipse drawn around each estimate (k-σ).
ELLIPSE_SIGMA = 3.0


def ns(t_s: float) -> int:
    """Seconds to integer nanoseconds (MCAP times are unsigned)."""
    t = int(round(float(t_s) * 1e9))
    if t < 0:
        raise ValueError(f"time {t_s!r} s is negative: MCAP log times are unsigned nanoseconds")
    return t


def _pose_msg(t_ns: int, x: float, y: float, theta: float):
    from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame

    m = PoseInFrame()
    fs.set_time(m.timestamp, t_ns)
    m.frame_id = fs.FRAME
    fs.set_pose(m.pose, x, y, theta)
    return m


def _transforms(t_ns: int, frames: dict):
    """``foxglove.FrameTransforms``: map → each child frame at its (x, y, θ)."""
    from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms

    m = FrameTransforms()
    for child, (x, y, th) in frames.items():
        tf = m.transforms.add()
        fs.set_time(tf.timestamp, t_ns)
        tf.parent_frame_id, tf.child_frame_id = fs.FRAME, child
        tf.translation.x, tf.translation.y, tf.translation.z = float(x), float(y), 0.0
        q = fs.yaw_quaternion(float(th))
        tf.rotation.x, tf.rotation.y, tf.rotation.z, tf.rotation.w = q
    return m


def _log(t_ns: int, name: str, text: str, level: str = "INFO"):
    from foxglove_schemas_protobuf.Log_pb2 import Log

    m = Log()
    fs.set_time(m.timestamp, t_ns)
    m.level = Log.Level.Value(level)
    m.name, m.message = name, text
    return m


def _scene(t_ns: int, entity_id: str, draw, *, metadata=None, lifetime_s: float | None = None):
    """A ``foxglove.SceneUpdate`` of one entity filled by ``draw(entity)``."""
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    u = SceneUpdate()
    e = fs.entity(u, entity_id, t_ns, metadata=metadata)
    if lifetime_s is not None:
        e.lifetime.FromNanoseconds(ns(lifetime_s))
    draw(e)
    return u


def _tracks(view, prefix: str, t_ns: int, lines: dict) -> None:
    """Whole tracks, static: a scene update of lines and a point cloud of their points."""
    def draw(e):
        for name, (pts, rgba) in lines.items():
            if len(pts) > 1:
                fs.add_line(e, pts, rgba, thickness=0.12, z=0.06)

    view.write(f"{prefix}/tracks", _scene(t_ns, "tracks", draw, metadata={k: len(p) for k, (p, _) in lines.items()}),
               t_ns)
    pts = [p for p, _ in lines.values()]
    colors = [np.tile(c, (len(p), 1)) for p, c in lines.values()]
    view.write(f"{prefix}/track_points", fs.point_cloud(t_ns, np.vstack(pts), np.vstack(colors)), t_ns)


# --------------------------------------------------------------------------- a recorded trial

def _one_landmark(sensors, row: int):
    """A copy of ``sensors`` whose map is landmark ``row`` alone (every setting copied)."""
    from . import _core

    s = _core.SensorSettings()
    for name, attr in vars(type(sensors)).items():
        if isinstance(attr, property) and attr.fset is not None and name != "landmarks":
            setattr(s, name, getattr(sensors, name))
    s.landmarks = np.asarray(sensors.landmarks, dtype=float)[row:row + 1]
    return s


def landmarks_in_view(sensors, world, states, rows) -> dict[int, np.ndarray]:
    """{row: landmark indices in view} of the true ``states`` at ``rows``: the
    core's ``SensorSettings.landmarks_in_view`` (range, field of view, and
    occlusion by the world's true obstacles when the sensors have it on),
    asked per landmark.  Landmarks beyond ``max_range`` are skipped before asking."""
    from .planning import ObstacleChecker

    checker = ObstacleChecker(world.core_map())
    L = np.asarray(sensors.landmarks, dtype=float)
    single = [_one_landmark(sensors, i) for i in range(len(L))]
    reach = float(sensors.max_range) * (1.0 + 1e-9) + 1e-9
    out = {}
    for k in rows:
        x = np.asarray(states[k], dtype=float)
        near = np.flatnonzero(np.hypot(L[:, 0] - x[0], L[:, 1] - x[1]) <= reach)
        out[int(k)] = np.array([i for i in near if single[i].landmarks_in_view(x, checker) == 1], dtype=int)
    return out


def _closing_line(trial) -> tuple[str, str]:
    """The trial's outcome and totals, and the log level."""
    m = trial.metrics
    text = (f"{trial.outcome_name}: {trial.reason}; steps {trial.steps}, position fixes {trial.position_fixes}, "
            f"dropouts {trial.dropouts}, rejected {trial.rejected}, resets {trial.resets}, replans {trial.replans}; "
            f"guard events: slow {trial.guard_slow}, steer {trial.guard_steer}, hold {trial.guard_hold}; "
            f"Algorithm 1: default {trial.chull_default}, corrective {trial.chull_corrective}, step back "
            f"{trial.chull_step_back}; path ADE {m['path_ade']:.3f} m, goal FDE {m['goal_fde']:.3f} m, "
            f"min clearance {m['min_clearance']:.3f} m, NEES {m['nees']:.2f}")
    level = "INFO" if trial.success else "ERROR" if trial.outcome_name == "collision" else "WARNING"
    return text, level


def write_poses(view, prefix: str, frames: dict, t, states) -> None:
    """Per row: each state's pose on ``<prefix>/<name>`` (``foxglove.PoseInFrame``)
    and one ``foxglove.FrameTransforms`` on ``<prefix>/tf``, ``map`` → frame ``frames[name]``.
    ``states`` maps a name to its (rows, ≥ 4) states (x, y, v, θ)."""
    for k, tk in enumerate(t):
        for name, x in states.items():
            view.write(f"{prefix}/{name}", _pose_msg(tk, *x[k, [0, 1, 3]]), tk)
        view.write(f"{prefix}/tf", _transforms(tk, {frames[name]: x[k, [0, 1, 3]] for name, x in states.items()}), tk)


def write_covariance(view, topic: str, t, centers, covariances, metadata=None) -> list:
    """Per row: the :data:`ELLIPSE_SIGMA`-σ ellipse of a 2×2 position
    covariance around its center, one ``foxglove.SceneUpdate`` each.
    Returns the ellipses' points, one (n, 2) array per row."""
    rings = []
    for k, tk in enumerate(t):
        ring = fs.ellipse(centers[k], covariances[k], ELLIPSE_SIGMA)
        meta = {"k_sigma": ELLIPSE_SIGMA, **({m: f"{v[k]:.6g}" for m, v in metadata.items()} if metadata else {})}
        view.write(topic, _scene(tk, "covariance", lambda e, ring=ring: fs.add_line(
            e, ring, fs.COLORS["ellipse"], thickness=0.06, loop=True, z=0.08), metadata=meta), tk)
        rings.append(ring)
    return rings


def write_vehicle(view, topic: str, t, positions: dict, rings) -> None:
    """Per row: one ``foxglove.PointCloud`` of the vehicle's positions
    (``positions``: name → ((rows, 2), colour); the truth black, the estimate
    red) and the points of its ellipse.  Rerun draws point clouds and not scene
    entities, so this is what moves in Rerun."""
    faint = (*fs.COLORS["ellipse"][:3], 0.5)
    colors = np.vstack([np.asarray([c for _, c in positions.values()]), np.tile(faint, (len(rings[0]), 1))])
    for k, tk in enumerate(t):
        pts = np.vstack([np.asarray([p[k, :2] for p, _ in positions.values()]), rings[k]])
        view.write(topic, fs.point_cloud(tk, pts, colors), tk)


def write_observations(view, topic: str, t, truth, seen: dict, landmarks, ids, measured, every: int) -> None:
    """Per row: lines from the true position to the landmarks in view
    (``seen``: row → landmark indices) and the fix when one was measured."""
    for k, tk in enumerate(t):
        rows = seen.get(k, np.zeros(0, dtype=int))
        fix = measured[k] if np.isfinite(measured[k]).all() else None

        def draw(e, rows=rows, fix=fix, k=k):
            if len(rows):
                pairs = np.repeat(truth[k:k + 1, :2], len(rows), axis=0)
                fs.add_line(e, np.c_[pairs, landmarks[rows]].reshape(-1, 2), fs.COLORS["landmark_seen"],
                            thickness=0.04, segments=True, z=0.1)
            if fix is not None:
                fs.add_sphere(e, fix, 0.5, fs.COLORS["fix"], z=0.1)

        view.write(topic, _scene(tk, "observations", draw, metadata={
            "fix_step": k % every == 0, "in_view": " ".join(str(ids[i]) for i in rows),
            "fix": "none" if fix is None else f"{fix[0]:.4f} {fix[1]:.4f}"}), tk)


def write_commands(view, topic: str, t, estimate, controls, predicted) -> None:
    """Per step k: the command (v, Δθ) chosen at estimate k, an arrow along
    θ + Δθ that is v metres long, and its BMM prediction (``predicted`` row k + 1)."""
    for k, (v, dth) in enumerate(controls):
        def draw(e, k=k, v=v, dth=dth):
            fs.add_arrow(e, estimate[k, :2], estimate[k, 3] + dth, max(v, 0.05), fs.COLORS["command"])
            fs.add_sphere(e, predicted[k + 1], 0.25, fs.COLORS["predicted"], z=0.1)

        view.write(topic, _scene(t[k], "command", draw, metadata={"speed_m_s": f"{v:.6g}",
                                                                 "heading_change_rad": f"{dth:.6g}"}), t[k])


def write_events(view, topic: str, key: str, t, navigator, trial) -> None:
    """The trial's start, and its outcome with its totals (the guard's events
    and Algorithm 1's actions among them) at its last row: ``foxglove.Log``."""
    dt = float(navigator.problem.bmm.dt)
    view.write(topic, _log(t[0], key, f"trial {key}: {navigator.settings.method.name.lower()}, filter "
                                      f"{navigator.settings.filter.type.name.lower()}, Δt {dt:g} s, "
                                      f"{len(t) - 1} steps"), t[0])
    text, level = _closing_line(trial)
    view.write(topic, _log(t[-1], key, text, level), t[-1])


def write_trial(view, key: str, navigator, trial, world, t0_ns: int = 0) -> None:
    """A recorded trial under ``/trial/<key>/``: per row the true and estimated
    poses (``truth``, ``estimate``; frames ``<key>/truth`` and
    ``<key>/estimate`` on ``tf``), the 3σ circle of the estimate
    (``covariance``: radius 3·√λ_max(P_xy), which holds the 3σ ellipse), both
    positions and the circle as points (``vehicle``, for Rerun), the
    landmarks in view and the fix (``observations``), per step the command
    and its BMM prediction (``command``); the whole tracks (``tracks``,
    ``track_points``) and the start and outcome (``log``)."""
    est, truth = np.asarray(trial.estimate, dtype=float), np.asarray(trial.truth, dtype=float)
    if len(est) == 0:
        raise ValueError(f"trial {key}: has no recorded rows (make_navigator(..., record=True))")
    prefix, n = f"/trial/{key}", len(est)
    dt = float(navigator.problem.bmm.dt)
    t = [t0_ns + ns(k * dt) for k in range(n)]
    sigma = np.asarray(trial.position_std, dtype=float)
    sensors = navigator.sensors
    every = int(sensors.position_every)

    write_events(view, f"{prefix}/log", key, t, navigator, trial)
    _tracks(view, prefix, t[0], {"truth": (truth[:, :2], fs.COLORS["truth"]),
                                 "estimate": (est[:, :2], fs.COLORS["estimate"]),
                                 "followed_path": (np.asarray(trial.followed_path, dtype=float).reshape(-1, 2),
                                                   fs.COLORS["followed"])})
    write_poses(view, prefix, {"truth": f"{key}/truth", "estimate": f"{key}/estimate"}, t,
                {"truth": truth, "estimate": est})
    # √λ_max(P_xy) is all a recorded trial keeps: σ²·I, whose 3σ circle holds the 3σ ellipse
    rings = write_covariance(view, f"{prefix}/covariance", t, est[:, :2], sigma[:, None, None] ** 2 * np.eye(2),
                             metadata={"position_std_m": sigma})
    write_vehicle(view, f"{prefix}/vehicle", t, {"truth": (truth, fs.COLORS["truth"]),
                                                 "estimate": (est, fs.COLORS["estimate"])}, rings)
    write_observations(view, f"{prefix}/observations", t, truth,
                       landmarks_in_view(sensors, world, truth, range(0, n, every)),
                       np.asarray(sensors.landmarks, dtype=float), [m.id for m in world.landmarks],
                       np.asarray(trial.measured, dtype=float), every)
    write_commands(view, f"{prefix}/command", t, est, np.asarray(trial.controls, dtype=float),
                   np.asarray(trial.predicted, dtype=float))


# --------------------------------------------------------------------------- a replayed log

def _replay_observations(view, log, result, traj_t, est) -> None:
    """Each measurement input on ``/replay/observations`` (a line from the
    latest estimate to the landmark, or the fix), coloured by its status when
    the replay recorded innovations; each one not applied on ``/replay/log``."""
    from .logs import OBSERVATION_KINDS
    from .replay import causal_index

    ev = log.events
    meas = ev[ev["kind"].isin((*OBSERVATION_KINDS, "fix"))].reset_index(drop=True)
    status = (result.innovations["status"].tolist() if result.innovations is not None
              and len(result.innovations) == len(meas) else [None] * len(meas))
    j, ok = causal_index(traj_t, meas["t"].to_numpy(float))
    for i, row in meas.iterrows():
        tk = ns(row["t"])
        st = status[i]
        rgba = fs.COLORS["landmark_seen"] if st in (None, "applied") else fs.COLORS["rejected"]
        lm = None if row["kind"] == "fix" else int(row["landmark"])

        def draw(e, row=row, lm=lm, i=i, rgba=rgba):
            if lm is None:
                fs.add_sphere(e, (row["x"], row["y"]), 0.5, fs.COLORS["fix"] if rgba != fs.COLORS["rejected"]
                              else rgba, z=0.1)
            elif ok[i] and lm in log.landmarks:
                fs.add_line(e, [est[j[i], :2], log.landmarks[lm]], rgba, thickness=0.05, z=0.1)

        eid = "fix" if lm is None else f"landmark/{lm}"
        view.write("/replay/observations", _scene(tk, eid, draw, lifetime_s=1.0, metadata={
            "kind": row["kind"], "status": st or "unknown"}), tk)
        if st not in (None, "applied"):
            view.write("/replay/log", _log(tk, "replay", f"{row['kind']} input at t = {row['t']:.3f} s"
                                           + (f" (landmark {lm})" if lm is not None else "") + f": {st}",
                                           "WARNING"), tk)


def write_replay(view, log, result) -> None:
    """A replay under ``/replay/``: the log's landmarks (``landmarks``) and truth
    (``truth``), the estimate after each motion input (``estimate``, frame
    ``replay/estimate`` on ``tf``) with its 3σ ellipse from the full position
    covariance (``covariance``), each measurement input (``observations``),
    the whole tracks (``tracks``, ``track_points``) and the start, rejected
    inputs and scores (``log``)."""
    traj = result.trajectory
    t0 = ns(min([*traj["t"].head(1), *log.events["t"].head(1)], default=0.0))
    ids = list(log.landmarks)
    lm = np.array([log.landmarks[i] for i in ids], dtype=float).reshape(-1, 2)
    view.write("/replay/landmarks", fs.point_cloud(t0, lm, fs.COLORS["landmark"], ids=ids), t0)
    lines = {}
    if log.truth is not None and len(log.truth):
        gt = log.truth[["t", "x", "y", "heading"]].to_numpy(float)
        lines["truth"] = (gt[:, 1:3], fs.COLORS["truth"])
        for tt, x, y, h in gt:
            view.write("/replay/truth", _pose_msg(ns(tt), x, y, h), ns(tt))
    if not result.estimated:
        view.write("/replay/log", _log(t0, "replay", result.reason or "never started", "ERROR"), t0)
        if lines:
            _tracks(view, "/replay", t0, lines)
        return
    est = traj[["x", "y", "speed", "heading"]].to_numpy(float)
    lines["estimate"] = (est[:, :2], fs.COLORS["estimate"])
    _tracks(view, "/replay", t0, lines)
    traj_t = traj["t"].to_numpy(float)
    view.write("/replay/log", _log(ns(traj_t[0]), "replay", f"started from the {result.started_from} at "
                                   f"t = {traj_t[0]:.3f} s"), ns(traj_t[0]))
    cov = traj[["var_x", "cov_xy", "cov_xy", "var_y"]].to_numpy(float).reshape(-1, 2, 2)
    tt = [ns(x) for x in traj_t]
    write_poses(view, "/replay", {"estimate": "replay/estimate"}, tt, {"estimate": est})
    rings = write_covariance(view, "/replay/covariance", tt, est[:, :2], cov)
    write_vehicle(view, "/replay/vehicle", tt, {"estimate": (est, fs.COLORS["estimate"])}, rings)
    _replay_observations(view, log, result, traj_t, est)
    c, m = result.counts, result.metrics
    text = (f"updates applied {c['applied']}, rejected {c['rejected']}, late {c['late']}, before the start "
            f"{c['buffered']}, ignored {c['ignored']}" + (f"; against the truth ({m['label']}): RMSE "
                                                          f"{m['truth_rmse']:.3f} m, NEES {m['nees']:.2f}" if m else "")
            + (f"; {result.reason}" if result.reason else ""))
    view.write("/replay/log", _log(ns(traj_t[-1]), "replay", text), ns(traj_t[-1]))

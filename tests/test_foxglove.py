"""The view of a run (``--view FILE.mcap``, safenav.foxglove): read back with
the ``mcap`` reader and decoded with only the schemas stored in the file, then
checked against the run it shows; the view changes no result table."""

from __future__ import annotations

import math
import shutil
import subprocess

import numpy as np
import pandas as pd
import pytest
from google.protobuf import descriptor_pool, message_factory
from google.protobuf.descriptor_pb2 import FileDescriptorSet
from mcap.reader import make_reader

import safenav
import safenav.logs
from safenav import cli, foxglove, foxglove_scene as fs, results, runner
from safenav.experiments.figures import recorded_trials
from safenav.foxglove_trial import landmarks_in_view
from safenav.planning import ObstacleChecker

RUN = ["run", "--trials", "2", "--methods", "centroid", "--path-types", "P3", "--seed", "5"]

#: The schema of each kind of topic.
SCHEMAS = {"/world/field": "foxglove.SceneUpdate", "/world/obstacles": "foxglove.SceneUpdate",
           "/world/hazards": "foxglove.SceneUpdate", "/world/outlines": "foxglove.PointCloud",
           "/world/landmarks": "foxglove.PointCloud", "/plan/P3": "foxglove.SceneUpdate",
           "/plan/P3/waypoints": "foxglove.PosesInFrame", "/plan/P3/points": "foxglove.PointCloud"}
TRIAL_SCHEMAS = {"log": "foxglove.Log", "tracks": "foxglove.SceneUpdate", "track_points": "foxglove.PointCloud",
                 "truth": "foxglove.PoseInFrame", "estimate": "foxglove.PoseInFrame", "tf": "foxglove.FrameTransforms",
                 "covariance": "foxglove.SceneUpdate", "observations": "foxglove.SceneUpdate",
                 "command": "foxglove.SceneUpdate", "vehicle": "foxglove.PointCloud"}


def read_view(path) -> dict:
    """{topic: (schema name, [(log time, publish time, decoded message)])}, each message decoded with
    a message class built from the FileDescriptorSet stored in the file (not the installed package)."""
    out, classes = {}, {}
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        for schema, channel, msg in reader.iter_messages():
            assert schema.encoding == "protobuf" and channel.message_encoding == "protobuf"
            if schema.id not in classes:
                pool = descriptor_pool.DescriptorPool()
                for f in FileDescriptorSet.FromString(schema.data).file:
                    pool.Add(f)
                classes[schema.id] = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))
            decoded = classes[schema.id].FromString(msg.data)
            assert decoded.SerializeToString() == msg.data          # nothing unknown to the stored schema
            out.setdefault(channel.topic, (schema.name, []))[1].append((msg.log_time, msg.publish_time, decoded))
    return out


def stamp(m) -> int:
    return m.timestamp.seconds * 10**9 + m.timestamp.nanos


# --------------------------------------------------------------------------- geometry

def star(n, rng):
    a = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = rng.uniform(0.3, 1.0, n)
    return np.c_[r * np.cos(a), r * np.sin(a)]


@pytest.mark.parametrize("seed", range(20))
def test_triangulation_covers_a_non_convex_polygon_exactly(seed):
    rng = np.random.default_rng(seed)
    p = star(int(rng.integers(3, 14)), rng)
    if seed % 2:
        p = p[::-1]                                                  # clockwise input too
    tris = fs.triangulate(p)
    areas = [fs.signed_area(p[t]) for t in tris]
    assert len(tris) == len(p) - 2 and min(areas) > 0               # n − 2 triangles, all counter-clockwise
    assert sum(areas) == pytest.approx(abs(fs.signed_area(p)), rel=1e-12)
    with pytest.raises(ValueError, match="2 vertices"):
        fs.triangulate(p[:2])


def test_ellipse_lies_on_the_k_sigma_contour():
    rng = np.random.default_rng(3)
    for _ in range(10):
        A = rng.normal(size=(2, 2))
        P, c = A @ A.T + 0.01 * np.eye(2), rng.normal(size=2)
        e = fs.ellipse(c, P, k=3.0) - c
        assert np.einsum("ni,ni->n", e, np.linalg.solve(P, e.T).T) == pytest.approx(9.0, rel=1e-9)
    assert np.hypot(*fs.circle((1.0, 2.0), 4.0).T - np.array([[1.0], [2.0]])) == pytest.approx(4.0)


def test_yaw_quaternion_rotates_x_onto_the_heading():
    for th in (-3.0, -0.5, 0.0, 1.0, 2.9):
        x, y, z, w = fs.yaw_quaternion(th)
        assert (x, y) == (0.0, 0.0) and math.atan2(2 * w * z, w * w - z * z) == pytest.approx(th)
    assert fs.yaw_quaternion(float("nan")) == (0.0, 0.0, 0.0, 1.0)


# --------------------------------------------------------------------------- a run with and without --view

@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("view")
    assert cli.main([*RUN, "--out", str(base / "plain"), "--quiet"]) == 0
    assert cli.main([*RUN, "--out", str(base / "viewed"), "--view", str(base / "viewed" / "run.mcap"),
                     "--quiet"]) == 0
    return base


@pytest.fixture(scope="module")
def recorded():
    sc = safenav.default_scenario()
    safe = runner.plan_safe_paths(sc, ["P3"])
    sweep = runner.Sweep(sc, path_types=("P3",), methods=("centroid",), trials=2, seed=5)
    return sc, safe, recorded_trials(sc, safe, sweep)


def test_the_view_changes_no_result_table(runs):
    plain, viewed = runs / "plain", runs / "viewed"
    tables = sorted(p.name for p in plain.iterdir() if p.suffix in (".csv", ".md") and "timings" not in p.name)
    assert "trials.csv" in tables and "summary.csv" in tables
    for name in tables:
        assert (plain / name).read_bytes() == (viewed / name).read_bytes(), name
    pd.testing.assert_frame_equal(pd.read_parquet(plain / "trials.parquet"), pd.read_parquet(viewed / "trials.parquet"))
    listed = {f["path"] for f in results.verify_run(viewed)["files"]}
    assert "run.mcap" in listed and not (plain / "run.mcap").exists()


def test_a_run_view_holds_the_world_the_plan_and_the_recorded_trial(runs, recorded):
    sc, safe, rec = recorded
    view = read_view(runs / "viewed" / "run.mcap")
    navigator, trial = rec[("centroid", "P3")]
    want = {**SCHEMAS, **{f"/trial/centroid/P3/{k}": v for k, v in TRIAL_SCHEMAS.items()}}
    assert {t: s for t, (s, _) in view.items()} == want
    # counts against the run: the trial's steps in trials.csv, the world's objects
    steps = int(pd.read_csv(runs / "viewed" / "trials.csv").query("trial == 0")["steps"].iloc[0])
    assert steps == trial.steps
    n = {t: len(m) for t, (_, m) in view.items()}
    for k in ("truth", "estimate", "tf", "covariance", "observations", "vehicle"):
        assert n[f"/trial/centroid/P3/{k}"] == steps + 1, k
    assert n["/trial/centroid/P3/command"] == steps and n["/trial/centroid/P3/log"] == 2
    (_, _, obstacles), = view["/world/obstacles"][1]
    (_, _, hazards), = view["/world/hazards"][1]
    (_, _, landmarks), = view["/world/landmarks"][1]
    assert len(obstacles.entities) == len(sc.world.obstacles) and len(hazards.entities) == len(sc.world.hazards)
    assert len(landmarks.data) == len(sc.world.landmarks) * landmarks.point_stride
    risks = [float(dict((kv.key, kv.value) for kv in e.metadata)["risk"]) for e in hazards.entities]
    assert risks == [h.risk for h in sc.world.hazards]
    green = {r: e.lines[0].color.g for r, e in zip(risks, hazards.entities)}   # riskier: redder (less green)
    assert [green[r] for r in sorted(green)] == sorted(green.values(), reverse=True)


def test_trial_messages_are_the_recorded_states_at_simulation_time(runs, recorded):
    _, _, rec = recorded
    navigator, trial = rec[("centroid", "P3")]
    view = read_view(runs / "viewed" / "run.mcap")
    dt_ns = round(navigator.problem.bmm.dt * 1e9)
    for kind, states in (("estimate", trial.estimate), ("truth", trial.truth)):
        msgs = view[f"/trial/centroid/P3/{kind}"][1]
        assert [m[0] for m in msgs] == [k * dt_ns for k in range(len(states))]
        assert all(lt == pt == stamp(m) and m.frame_id == "map" for lt, pt, m in msgs)
        xy = np.array([(m.pose.position.x, m.pose.position.y) for _, _, m in msgs])
        np.testing.assert_array_equal(xy, states[:, :2])
        yaw = np.array([2 * math.atan2(m.pose.orientation.z, m.pose.orientation.w) for _, _, m in msgs])
        np.testing.assert_allclose(np.angle(np.exp(1j * (yaw - states[:, 3]))), 0.0, atol=1e-12)
    tf = view["/trial/centroid/P3/tf"][1]
    assert {(t.parent_frame_id, t.child_frame_id) for _, _, m in tf for t in m.transforms} == {
        ("map", "centroid/P3/truth"), ("map", "centroid/P3/estimate")}
    # the 3σ circle: radius 3·position_std around the estimate
    for k, (_, _, m) in enumerate(view["/trial/centroid/P3/covariance"][1][::97]):
        pts = np.array([(p.x, p.y) for p in m.entities[0].lines[0].points])
        r = np.hypot(*(pts - trial.estimate[97 * k, :2]).T)
        np.testing.assert_allclose(r, 3 * trial.position_std[97 * k], rtol=1e-9)
    # the vehicle's point cloud: truth, estimate, then the circle (float32)
    for k, (_, _, m) in list(enumerate(view["/trial/centroid/P3/vehicle"][1]))[::211]:
        off = {f.name: f.offset for f in m.fields}
        raw = np.frombuffer(m.data, np.uint8).reshape(-1, m.point_stride)
        xy = np.c_[[raw[:, off[c]:off[c] + 4].copy().view("<f4")[:, 0] for c in "xy"]].T
        np.testing.assert_allclose(xy[:2], [trial.truth[k, :2], trial.estimate[k, :2]], atol=1e-4)
        np.testing.assert_allclose(np.hypot(*(xy[2:] - trial.estimate[k, :2]).T), 3 * trial.position_std[k],
                                   rtol=1e-4, atol=1e-4)
    # commands: the recorded (v, Δθ) from the estimate's heading
    for k, (_, _, m) in enumerate(view["/trial/centroid/P3/command"][1][:50]):
        meta = {kv.key: float(kv.value) for kv in m.entities[0].metadata}
        assert meta["speed_m_s"] == pytest.approx(trial.controls[k, 0], rel=1e-5, abs=1e-9)
        assert meta["heading_change_rad"] == pytest.approx(trial.controls[k, 1], rel=1e-5, abs=1e-9)
    # messages are stored in time order
    with open(runs / "viewed" / "run.mcap", "rb") as fh:
        times = [m.log_time for _, _, m in make_reader(fh).iter_messages(log_time_order=False)]
    assert times == sorted(times)
    last = view["/trial/centroid/P3/log"][1][-1]
    assert last[0] == trial.steps * dt_ns and trial.outcome_name in last[2].message and "guard" in last[2].message


def test_landmarks_in_view_are_the_sensor_models(recorded):
    """Per landmark, the core's count; brute force: range, field of view, line of sight."""
    sc, _, rec = recorded
    navigator, trial = rec[("centroid", "P3")]
    se = navigator.sensors
    checker = ObstacleChecker(sc.world.core_map())
    rows = range(0, len(trial.truth), 37)
    seen = landmarks_in_view(se, sc.world, trial.truth, rows)
    L = np.asarray(se.landmarks)
    for k in rows:
        x = trial.truth[k]
        assert len(seen[k]) == se.landmarks_in_view(x, checker)
        d = L - x[:2]
        bearing = np.angle(np.exp(1j * (np.arctan2(d[:, 1], d[:, 0]) - x[3])))
        brute = [i for i in range(len(L)) if np.hypot(*d[i]) <= se.max_range
                 and abs(bearing[i]) <= se.field_of_view / 2 and checker.line_of_sight(x[:2], L[i])]
        assert list(seen[k]) == brute
    assert sum(len(v) for v in seen.values()) > 0


def test_writing_a_view_twice_gives_the_same_bytes(tmp_path, recorded):
    sc, safe, rec = recorded
    a = foxglove.navigation_view(tmp_path / "a.mcap", sc, safe, rec, seed=5)
    b = foxglove.navigation_view(tmp_path / "b.mcap", sc, safe, rec, seed=5)
    assert a.read_bytes() == b.read_bytes()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(results.TEMP_PREFIX)]
    with pytest.raises(ValueError, match="must end in .mcap"):
        foxglove.navigation_view(tmp_path / "a.json", sc, safe, rec)


def test_a_bad_view_name_is_refused_before_any_work(capsys, tmp_path):
    assert cli.main([*RUN, "--out", str(tmp_path), "--view", "run.json"]) == 2
    assert "--view: must be a file name ending in .mcap" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


# --------------------------------------------------------------------------- plan and replay

def test_a_plan_view_holds_the_safe_path_and_its_check_trial(tmp_path):
    assert cli.main(["plan", "--path-types", "P3", "--out", str(tmp_path), "--view", str(tmp_path / "plan.mcap"),
                     "--quiet"]) == 0
    view = read_view(tmp_path / "plan.mcap")
    assert {t: s for t, (s, _) in view.items() if not t.startswith("/trial/")} == SCHEMAS
    (_, _, poses), = view["/plan/P3/waypoints"][1]
    import json
    path = np.array(json.loads((tmp_path / "safe_paths.json").read_text())["P3"]["path"])
    np.testing.assert_allclose([(p.position.x, p.position.y) for p in poses.poses], path, atol=1e-4)
    steps = len(view["/trial/check/P3/command"][1])
    assert len(view["/trial/check/P3/estimate"][1]) == steps + 1 > 1


def test_a_replay_view_holds_every_estimate_with_its_covariance_ellipse(tmp_path):
    from test_replay import circle_log

    log_file = tmp_path / "circle.csv"
    circle_log(seconds=10.0).to_csv(log_file, index=False)
    out = tmp_path / "out"
    assert cli.main(["replay", str(log_file), "--out", str(out), "--view", str(out / "replay.mcap"), "--quiet"]) == 0
    traj = pd.read_csv(out / "trajectory.csv")
    log = safenav.logs.read_log(log_file)
    view = read_view(out / "replay.mcap")
    n = {t: len(m) for t, (_, m) in view.items()}
    assert n["/replay/estimate"] == n["/replay/covariance"] == n["/replay/tf"] == n["/replay/vehicle"] == len(traj)
    assert n["/replay/truth"] == len(log.truth)
    assert n["/replay/observations"] == int(log.events["kind"].isin(["range", "bearing", "range_bearing", "fix"]).sum())
    for k in range(0, len(traj), 13):
        _, _, m = view["/replay/covariance"][1][k]
        r = traj.iloc[k]
        P = np.array([[r.var_x, r.cov_xy], [r.cov_xy, r.var_y]])
        e = np.array([(p.x, p.y) for p in m.entities[0].lines[0].points]) - [r.x, r.y]
        np.testing.assert_allclose(np.einsum("ni,ni->n", e, np.linalg.solve(P, e.T).T), 9.0, rtol=1e-6)
        assert view["/replay/estimate"][1][k][0] == round(r.t * 1e9)
    # the replay's own results are those of a replay without a view
    assert cli.main(["replay", str(log_file), "--out", str(tmp_path / "plain"), "--quiet"]) == 0
    assert (tmp_path / "plain" / "trajectory.csv").read_bytes() == (out / "trajectory.csv").read_bytes()


@pytest.mark.skipif(shutil.which("rerun") is None, reason="the Rerun viewer (rerun-sdk) is not installed")
def test_rerun_converts_poses_transforms_points_and_logs(runs, tmp_path):
    rrd = tmp_path / "run.rrd"
    subprocess.run(["rerun", "mcap", "convert", str(runs / "viewed" / "run.mcap"), "-o", str(rrd)], check=True,
                   capture_output=True)
    text = subprocess.run(["rerun", "rrd", "print", str(rrd)], check=True, capture_output=True, text=True).stdout
    for topic, kind in (("/trial/centroid/P3/estimate", "InstancePoses3D:translations"),
                        ("/trial/centroid/P3/tf", "Transform3D:translation"),
                        ("/world/landmarks", "Points3D:positions"), ("/trial/centroid/P3/log", "TextLog:text"),
                        ("/trial/centroid/P3/vehicle", "Points3D:positions")):
        assert any(topic in line and kind in line for line in text.splitlines()), (topic, kind)


def test_plot_view_draws_the_file_from_above(runs, tmp_path):
    from safenav.foxglove_plot import plot_view, read_view as library_read_view

    mcap = runs / "viewed" / "run.mcap"
    png = plot_view(mcap, tmp_path / "view.png", t_s=10.0)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    mine, theirs = read_view(mcap), library_read_view(mcap)
    assert {t: (s, len(m)) for t, (s, m) in mine.items()} == {t: (s, len(m)) for t, (s, m) in theirs.items()}


def test_a_replay_that_never_starts_still_writes_its_view_with_the_reason(tmp_path):
    from test_replay import circle_log

    rows = circle_log(seconds=2.0)
    rows = rows[rows["kind"].isin(["landmark", "odometry", "truth"])]        # nothing to start from
    rows.to_csv(tmp_path / "blind.csv", index=False)
    out = tmp_path / "out"
    assert cli.main(["replay", str(tmp_path / "blind.csv"), "--out", str(out), "--view", str(out / "v.mcap"),
                     "--quiet"]) == 3
    view = read_view(out / "v.mcap")
    (_, _, log), = view["/replay/log"][1]
    assert log.level == 4 and "never started" in log.message                  # ERROR
    assert "/replay/estimate" not in view and len(view["/replay/truth"][1]) == int((rows["kind"] == "truth").sum())


def test_a_failed_view_leaves_no_file_behind(tmp_path):
    def fill(view):
        view.write("/x", fs.point_cloud(0, np.zeros((1, 2)), fs.COLORS["truth"]), 0)
        raise RuntimeError("stop")

    with pytest.raises(RuntimeError, match="stop"):
        foxglove.write_view(tmp_path / "v.mcap", fill)
    assert list(tmp_path.iterdir()) == []


def test_every_message_is_in_the_map_frame_and_stamped_with_its_log_time(runs):
    """Foxglove and Rerun place a message by its frame and time: one frame, ``map``;
    every ``timestamp`` (of a message, a scene entity, a transform) equals the log time."""
    view = read_view(runs / "viewed" / "run.mcap")
    checked = 0
    for topic, (schema, msgs) in view.items():
        for log_time, publish_time, m in msgs:
            assert log_time == publish_time
            if schema == "foxglove.SceneUpdate":
                assert all(e.frame_id == "map" and stamp(e) == log_time for e in m.entities), topic
            elif schema == "foxglove.FrameTransforms":
                assert all(t.parent_frame_id == "map" and stamp(t) == log_time for t in m.transforms), topic
            else:
                assert stamp(m) == log_time, topic
                if schema != "foxglove.Log":
                    assert m.frame_id == "map", topic
            checked += 1
    assert checked == sum(len(m) for _, m in view.values()) > 10000

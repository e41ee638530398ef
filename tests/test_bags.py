"""ROS bags in and trajectories out (safenav.bags, safenav.bags_write).

A log written as a bag (``safenav convert``) must replay to the same estimate
as the log itself, up to the float32 rounding of ``sensor_msgs/Range``'s
fields and nanosecond stamps (RMSE within 1 mm): Plaza1 (odometry and ranges)
and a real-like log (twist motion and range-bearing sightings).  Each
storage (rosbag2 MCAP, rosbag2 sqlite3, a lone ``.mcap`` file, ROS 1) reads
back the same rows; each bad input is one error naming the topic; evo reads
the TUM files and gives back the replay's RMSE."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from safenav import bags
from safenav import replay as rp
from safenav.bags_write import _Messages, integrate_odometry, write_bag
from safenav.cli import main
from safenav.logs import Log, load_plaza, plaza1_path, write_log
from safenav.reallike import RealLikeConfig, reallike_log

FLOATS = ["t", "x", "y", "speed", "distance", "heading_change", "range", "bearing", "range_std", "bearing_std",
          "std_x", "std_y"]


def assert_same_rows(a: Log, b: Log):
    """Same kinds, landmarks and map; values equal up to float32 (ranges) and 1 ns (stamps)."""
    assert b.landmarks == a.landmarks
    ea, eb = a.events, b.events
    assert eb["kind"].tolist() == ea["kind"].tolist()
    assert eb["landmark"].fillna(-1).tolist() == ea["landmark"].fillna(-1).tolist()
    for c in FLOATS:
        x, y = ea[c].to_numpy(float), eb[c].to_numpy(float)
        assert np.array_equal(np.isnan(x), np.isnan(y)), c
        tol = 1e-9 if c == "t" else 1e-6 * np.maximum(1.0, np.abs(x)) if c in ("range", "range_std") else 1e-12
        assert np.all(np.abs(x - y)[~np.isnan(x)] <= (tol[~np.isnan(x)] if np.ndim(tol) else tol)), c
    if a.truth is None:
        assert b.truth is None
    else:
        ta, tb = a.truth.to_numpy(float), b.truth.to_numpy(float)
        assert np.array_equal(np.isnan(ta), np.isnan(tb))
        d = ta - tb
        d[:, 3] = bags._wrap(d[:, 3])          # a quaternion's yaw is wrapped to (-pi, pi]
        assert np.nanmax(np.abs(d)) <= 1e-9


def small_log(n=40, seed=0) -> Log:
    """Odometry at 10 Hz, ranges to 3 landmarks at 5 Hz, a fix and a bearing now and then, truth without heading."""
    rng = np.random.default_rng(seed)
    lm = {2: (0.0, 0.0), 5: (10.0, 0.0), 11: (0.0, 8.0)}
    rows = [dict(kind="landmark", landmark=i, x=x, y=y) for i, (x, y) in lm.items()]
    for k in range(1, n + 1):
        t = 0.1 * k
        rows.append(dict(t=t, kind="odometry", distance=0.05 + 0.01 * rng.normal(), heading_change=0.02 * rng.normal()))
        if k % 2 == 0:
            for i in lm:
                rows.append(dict(t=t, kind="range", landmark=i, range=5 + rng.random(), range_std=0.2 + 0.1 * i))
        if k % 7 == 0:
            rows.append(dict(t=t, kind="fix", x=rng.normal(), y=rng.normal(), std_x=0.3, std_y=0.4))
        if k % 9 == 0:
            rows.append(dict(t=t + 0.05, kind="bearing", landmark=5, bearing=rng.uniform(-3, 3), bearing_std=0.05))
        rows.append(dict(t=t, kind="truth", x=0.05 * k, y=0.0))
    from safenav.logs import _parse

    return _parse(pd.DataFrame(rows), "small")


# --------------------------------------------------------------------------- round trips

def test_integrate_odometry_is_inverted_by_the_pose_increments():
    rng = np.random.default_rng(1)
    d, dh = rng.normal(size=50), rng.uniform(-3, 3, size=50)
    p = integrate_odometry(d, dh, (1.0, 2.0, 3.0))
    back_dh = bags._wrap(np.diff(p[:, 2]))
    mid = p[:-1, 2] + back_dh / 2
    assert np.allclose(back_dh, dh, atol=1e-12)   # |Δθ| < π per step
    assert np.allclose(np.diff(p[:, 0]) * np.cos(mid) + np.diff(p[:, 1]) * np.sin(mid), d, atol=1e-12)


@pytest.fixture(scope="module")
def plaza(tmp_path_factory):
    try:
        path = plaza1_path()
    except FileNotFoundError as exc:
        pytest.skip(str(exc))
    return path, tmp_path_factory.mktemp("plaza")


def test_plaza1_convert_then_replay_gives_the_same_estimate(plaza, capsys):
    path, tmp = plaza
    assert main(["convert", str(path), str(tmp / "bag")]) == 0
    assert sorted(f.name for f in (tmp / "bag").iterdir()) == ["bag.mcap", "landmarks.csv", "manifest.json",
                                                               "metadata.yaml"]
    assert_same_rows(load_plaza(path, range_std=rp.PLAZA_RANGE_STD), bags.read_bag(tmp / "bag"))
    assert main(["replay", str(path), "--out", str(tmp / "src")]) == 0
    assert main(["replay", str(tmp / "bag"), "--preset", "plaza", "--out", str(tmp / "out")]) == 0
    src, out = (json.loads((tmp / d / "replay.json").read_text()) for d in ("src", "out"))
    assert abs(out["metrics"]["truth_rmse"] - src["metrics"]["truth_rmse"]) <= 1e-3
    assert out["counts"] == src["counts"]
    a, b = (pd.read_csv(tmp / d / "trajectory.csv") for d in ("src", "out"))
    assert len(a) == len(b)
    assert np.abs(a[["x", "y"]].to_numpy() - b[["x", "y"]].to_numpy()).max() <= 1e-3


def test_reallike_csv_convert_then_replay_with_odom_twist(tmp_path, capsys):
    log = reallike_log(0, RealLikeConfig(duration=60.0))
    write_log(log, tmp_path / "run.csv")
    assert main(["convert", str(tmp_path / "run.csv"), str(tmp_path / "bag")]) == 0
    assert "--odom-twist" in capsys.readouterr().out
    back = bags.read_bag(tmp_path / "bag", odom_twist=True)
    assert_same_rows(log, back)
    assert (back.events["kind"] == "range_bearing").sum() == (log.events["kind"] == "range_bearing").sum() > 0
    assert main(["replay", str(tmp_path / "run.csv"), "--out", str(tmp_path / "src")]) == 0
    assert main(["replay", str(tmp_path / "bag"), "--odom-twist", "--out", str(tmp_path / "out")]) == 0
    src, out = (json.loads((tmp_path / d / "replay.json").read_text()) for d in ("src", "out"))
    assert abs(out["metrics"]["truth_rmse"] - src["metrics"]["truth_rmse"]) <= 1e-3
    assert out["t_start"] == pytest.approx(src["t_start"], abs=1e-6)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_rosbag2_storages_read_back_every_kind(storage, tmp_path):
    log = small_log()
    write_bag(log, tmp_path / "bag", storage=storage)
    assert any((tmp_path / "bag").glob("*.mcap" if storage == "mcap" else "*.db3"))
    back = bags.read_bag(tmp_path / "bag")
    assert_same_rows(log, back)
    assert back.truth["heading"].isna().all()      # an all-zero quaternion: heading unknown


def test_a_range_and_a_bearing_of_one_landmark_at_one_stamp_are_one_sighting(tmp_path):
    log = small_log()
    ev = log.events
    i = ev.index[ev["kind"] == "bearing"][0]
    ev = pd.concat([ev, ev.loc[[i]].assign(kind="range", bearing=np.nan, bearing_std=np.nan, range=4.0,
                                           range_std=0.3)], ignore_index=True).sort_values("t", kind="stable")
    write_bag(Log(log.landmarks, ev.reset_index(drop=True), None), tmp_path / "bag")
    back = bags.read_bag(tmp_path / "bag").events
    joint = back[back["kind"] == "range_bearing"]
    assert len(joint) == 1 and (back["kind"] == "bearing").sum() == (log.events["kind"] == "bearing").sum() - 1
    assert joint[["t", "landmark", "range", "range_std", "bearing", "bearing_std"]].iloc[0].tolist() == \
        pytest.approx([ev.loc[i, "t"], 5, 4.0, 0.3, ev.loc[i, "bearing"], 0.05])


def test_a_lone_mcap_file_with_a_map(tmp_path):
    log = small_log()
    write_bag(log, tmp_path / "bag")
    lone = tmp_path / "lone.mcap"
    lone.write_bytes((tmp_path / "bag" / "bag.mcap").read_bytes())
    assert bags.is_bag(lone)
    with pytest.raises(ValueError, match="no map: give --map"):
        bags.read_bag(lone)
    assert_same_rows(log, bags.read_bag(lone, tmp_path / "bag" / "landmarks.csv"))


def test_ros1_bag(tmp_path):
    """A ROS 1 bag (rosbags.rosbag1.Writer): its Range has no variance, so σ comes from range_std."""
    log = small_log()
    ev = log.events[~log.events["kind"].isin(["bearing"])].reset_index(drop=True)
    ev.loc[ev["kind"] == "range", "range_std"] = 0.7
    log = Log(log.landmarks, ev, log.truth)
    write_bag(log, tmp_path / "run.bag", storage="ros1")
    assert (tmp_path / "landmarks.csv").is_file()
    assert_same_rows(log, bags.read_bag(tmp_path / "run.bag", range_std=0.7))
    with pytest.raises(ValueError, match="ROS 1 bag is written with ranges only"):
        write_bag(small_log(), tmp_path / "b.bag", storage="ros1")


def test_scenario_file_as_the_map():
    from safenav.scenario import default_scenario

    path = bags.Path(bags.__file__).parent / "data" / "default_scenario.toml"
    want = {lm.id: tuple(lm.position[:2]) for lm in default_scenario().world.landmarks}
    assert want and bags.read_map(path) == want


# --------------------------------------------------------------------------- topics and flags

def odom_bag(path, t, *, twist=(0.5, 0.1), imu=None, extra=()):
    """A bag with Odometry on /odom stamped ``t`` (recorded in that order, 1 s apart) and optional IMU yaw
    rates ``imu`` = (times, rates); ``extra``: (topic, record ns, message)."""
    m = _Messages(ros1=False)
    for k, tk in enumerate(t):
        ns = int(round(tk * 1e9))
        m.add("/odom", ns, m.odometry(ns, 0.1 * k, 0.0, 0.0, *twist), record=k * 1_000_000_000)
    if imu is not None:
        T = m.T
        vec = T["geometry_msgs/msg/Vector3"]
        for tk, w in zip(*imu):
            ns = int(round(tk * 1e9))
            msg = T["sensor_msgs/msg/Imu"](header=m.header(ns, "imu"), orientation=T["geometry_msgs/msg/Quaternion"](
                x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=np.zeros(9),
                angular_velocity=vec(x=0.0, y=0.0, z=float(w)), angular_velocity_covariance=np.zeros(9),
                linear_acceleration=vec(x=0.0, y=0.0, z=0.0), linear_acceleration_covariance=np.zeros(9))
            m.add("/imu", ns, msg)
    for topic, ns, msg in extra:
        m.add(topic, ns, msg, record=ns)
    m.write(path, "mcap")
    return path


def test_odom_twist_and_imu_yaw_rate(tmp_path):
    t = np.array([1.0, 1.1, 1.25, 1.3, 1.5])
    path = odom_bag(tmp_path / "b", t, twist=(0.5, 0.2))
    pose = bags.read_bag(path)
    assert pose.events["kind"].eq("odometry").all() and len(pose.events) == 4
    assert np.allclose(pose.events["distance"], 0.1) and np.allclose(pose.events["heading_change"], 0.0)
    tw = bags.read_bag(path, odom_twist=True)
    assert np.allclose(tw.events["speed"], 0.5) and np.allclose(tw.events["heading_change"], 0.2 * np.diff(t))
    # a yaw rate linear in time, sampled at its own times: the trapezoid integral is exact
    ti = np.arange(0.95, 1.62, 0.013)
    path = odom_bag(tmp_path / "i", t, imu=(ti, 0.3 + 2.0 * ti))
    got = bags.read_bag(path, odom_twist=True).events["heading_change"].to_numpy()
    exact = 0.3 * np.diff(t) + (t[1:] ** 2 - t[:-1] ** 2)
    assert np.allclose(got, exact, atol=1e-12)
    off = bags.read_bag(path, odom_twist=True, topics={"imu": None}).events["heading_change"]
    assert np.allclose(off, 0.1 * np.diff(t))


def test_ground_truth_as_pose_stamped(tmp_path):
    m = _Messages(ros1=False)
    T = m.T
    extra = [("/gt", int(k * 1e8), T["geometry_msgs/msg/PoseStamped"](header=m.header(int(k * 1e8), "map"),
                                                                       pose=m.pose(k, -k, 0.5)))
             for k in range(3)]
    log = bags.read_bag(odom_bag(tmp_path / "b", [0.0, 0.1], extra=extra), topics={"ground_truth": "/gt"})
    assert log.truth[["x", "y"]].to_numpy().tolist() == [[0, 0], [1, -1], [2, -2]]
    assert np.allclose(log.truth["heading"], 0.5)


# --------------------------------------------------------------------------- bad input

def range_msg(m, ns, frame, r=3.0):
    return m.range(ns, 0, r, 0.5).__class__(header=m.header(ns, frame), radiation_type=1, field_of_view=0.0,
                                             min_range=0.0, max_range=float("inf"), range=r, variance=0.25)


def test_missing_topics(tmp_path):
    m = _Messages(ros1=False)
    m.add("/ranges", 0, range_msg(m, 0, "landmark_0"))
    m.write(tmp_path / "noodom", "mcap")
    with pytest.raises(ValueError, match=r"no topic '/odom' for odom \(the bag has: /ranges; name another with "
                                         r"--odom TOPIC\)"):
        bags.read_bag(tmp_path / "noodom", {0: (0.0, 0.0)})
    path = odom_bag(tmp_path / "b", [0.0, 0.1])
    bags.read_bag(path)                                   # the default /fix is absent: not used
    with pytest.raises(ValueError, match=r"no topic '/gps' for fix .*--fix TOPIC"):
        bags.read_bag(path, topics={"fix": "/gps"})       # named explicitly: required


def test_frame_ids_must_name_a_landmark_of_the_map(tmp_path):
    for frame, problem in (("beacon_3", r"frame_id 'beacon_3' does not name a landmark \(landmark_<id>\)"),
                           ("landmark_9", r"frame_id 'landmark_9': unknown landmark 9 \(the map has \[0, 1\]\)")):
        m = _Messages(ros1=False)
        msg = [("/ranges", 150_000_000, range_msg(m, 150_000_000, frame))]
        path = odom_bag(tmp_path / frame, [0.0, 0.1, 0.2], extra=msg)
        with pytest.raises(ValueError, match=rf"topic '/ranges': message 1 at 0.15 s: {problem}"):
            bags.read_bag(path, {0: (0.0, 0.0), 1: (1.0, 0.0)})


def test_wrong_message_type(tmp_path):
    m = _Messages(ros1=False)
    m.add("/odom", 0, range_msg(m, 0, "landmark_0"))
    m.write(tmp_path / "b", "mcap")
    with pytest.raises(ValueError, match=r"topic '/odom': message type sensor_msgs/msg/Range cannot be read as odom "
                                         r"\(it takes nav_msgs/msg/Odometry\)"):
        bags.read_bag(tmp_path / "b")
    path = odom_bag(tmp_path / "c", [0.0, 0.1])
    with pytest.raises(ValueError, match=r"topic '/odom': message type nav_msgs/msg/Odometry cannot be read as "
                                         r"ranges"):
        bags.read_bag(path, topics={"ranges": "/odom"})


def test_a_default_topic_of_another_type_and_an_unreadable_bag(tmp_path):
    m = _Messages(ros1=False)
    extra = [("/fix", 0, range_msg(m, 0, "landmark_0"))]     # e.g. a GNSS NavSatFix on /fix
    path = odom_bag(tmp_path / "b", [0.0, 0.1], extra=extra)
    with pytest.raises(ValueError, match=r"topic '/fix': message type sensor_msgs/msg/Range cannot be read as "
                                         r"fix \(it takes geometry_msgs/msg/PoseWithCovarianceStamped; --fix none "
                                         r"skips it\)"):
        bags.read_bag(path)
    assert len(bags.read_bag(path, topics={"fix": None}).events) == 1
    (tmp_path / "junk.mcap").write_bytes(b"not an mcap file")
    with pytest.raises(ValueError, match=r"junk.mcap: not a readable ROS bag"):
        bags.read_bag(tmp_path / "junk.mcap")


def test_cli_topic_and_map_flags(tmp_path, capsys):
    log = reallike_log(2, RealLikeConfig(duration=20.0))
    write_bag(log, tmp_path / "bag", topics={"ranges": "/beacons", "odom": "/wheels"})
    (tmp_path / "bag" / "landmarks.csv").rename(tmp_path / "map.csv")
    base = ["replay", str(tmp_path / "bag"), "--odom-twist", "--out", str(tmp_path / "o")]
    assert main([*base, "--map", str(tmp_path / "map.csv")]) == 2
    err = capsys.readouterr().err
    assert "no topic '/odom' for odom (the bag has: /beacons, /bearings, /ground_truth, /wheels" in err
    assert main([*base, "--odom", "/wheels"]) == 2
    assert "no map: give --map FILE" in capsys.readouterr().err
    assert main([*base, "--odom", "/wheels", "--map", str(tmp_path / "map.csv"), "--ranges", "/beacons"]) == 0
    with_ranges = json.loads((tmp_path / "o" / "replay.json").read_text())
    assert main([*base, "--odom", "/wheels", "--map", str(tmp_path / "map.csv"), "--ground-truth", "none"]) == 0
    bearings_only = json.loads((tmp_path / "o" / "replay.json").read_text())
    assert with_ranges["metrics"]["truth_rmse"] < 0.2 and bearings_only["metrics"] == {}


def test_stamps_that_go_back_in_time(tmp_path):
    path = odom_bag(tmp_path / "b", [0.0, 0.2, 0.1])
    with pytest.raises(ValueError, match=r"topic '/odom': message 3 at 0.1 s: header stamps are not increasing: "
                                         r"it follows 0.2 s"):
        bags.read_bag(path)
    m = _Messages(ros1=False)
    extra = [("/ranges", k, range_msg(m, ns, "landmark_0")) for k, ns in enumerate((300_000_000, 100_000_000))]
    path = odom_bag(tmp_path / "r", [0.0, 0.5], extra=extra)
    with pytest.raises(ValueError, match=r"topic '/ranges': message 2 at 0.1 s: header stamps are not monotonic"):
        bags.read_bag(path, {0: (0.0, 0.0)})


def test_bag_flags_on_a_log_file_and_a_bad_map(tmp_path, capsys):
    write_log(small_log(), tmp_path / "run.csv")
    assert main(["replay", str(tmp_path / "run.csv"), "--odom-twist", "--out", str(tmp_path / "o")]) == 2
    assert "apply to ROS bags only" in capsys.readouterr().err
    (tmp_path / "map.csv").write_text("id,x,y\n1,0,0\n1,2,3\n")
    with pytest.raises(ValueError, match="duplicate landmark id 1"):
        bags.read_map(tmp_path / "map.csv")
    (tmp_path / "map.csv").write_text("id,x,y\n1,0,0\n2,east,3\n")
    with pytest.raises(ValueError, match=r"row 2 = \[2, 'east', 3\]: an id is an integer in \[0, 2147483647\]"):
        bags.read_map(tmp_path / "map.csv")
    (tmp_path / "map.csv").write_text("name,x,y\n")
    with pytest.raises(ValueError, match="a map's columns are id,x,y"):
        bags.read_map(tmp_path / "map.csv")


# --------------------------------------------------------------------------- trajectories out

def test_evo_reads_the_tum_files_and_gives_back_the_rmse(tmp_path, capsys):
    """evo's APE on trajectory.tum against truth.tum, after the replay's own (causal) association, is its RMSE."""
    file_interface = pytest.importorskip("evo.tools.file_interface")
    from evo.core import metrics, sync
    from evo.core.trajectory import PoseTrajectory3D
    from evo import main_ape

    log = reallike_log(1, RealLikeConfig(duration=40.0))
    write_log(log, tmp_path / "run.csv")
    assert main(["replay", str(tmp_path / "run.csv"), "--out", str(tmp_path / "o")]) == 0
    summary = json.loads((tmp_path / "o" / "replay.json").read_text())
    est = file_interface.read_tum_trajectory_file(str(tmp_path / "o" / "trajectory.tum"))
    ref = file_interface.read_tum_trajectory_file(str(tmp_path / "o" / "truth.tum"))
    j, ok = rp.causal_index(est.timestamps, ref.timestamps)   # the latest estimate at or before each truth time
    est = PoseTrajectory3D(poses_se3=[est.poses_se3[i] for i in j[ok]], timestamps=ref.timestamps[ok])
    ref, est = sync.associate_trajectories(ref, est, max_diff=1e-6)
    assert ref.num_poses == summary["metrics"]["n_scored"]
    result = main_ape.ape(ref, est, pose_relation=metrics.PoseRelation.translation_part)
    assert result.stats["rmse"] == pytest.approx(summary["metrics"]["truth_rmse"], rel=1e-9)
    # headings: the TUM quaternion is the estimate's yaw
    tr = pd.read_csv(tmp_path / "o" / "trajectory.csv")
    raw = np.loadtxt(tmp_path / "o" / "trajectory.tum")
    assert np.allclose(2 * np.arctan2(raw[:, 6], raw[:, 7]), tr["heading"], atol=1e-12)


def test_a_replay_that_never_starts_writes_empty_trajectories(tmp_path, capsys):
    write_log(small_log(30), tmp_path / "run.csv")     # ranges only, too little motion: never starts
    assert main(["replay", str(tmp_path / "run.csv"), "--out", str(tmp_path / "o")]) == 3
    assert (tmp_path / "o" / "trajectory.tum").read_text() == ""
    assert len((tmp_path / "o" / "truth.tum").read_text().splitlines()) == 30
    assert main(["verify", str(tmp_path / "o")]) == 0


def test_trajectory_mcap_holds_the_estimate_with_its_covariance(tmp_path, capsys):
    write_log(reallike_log(2, RealLikeConfig(duration=20.0)), tmp_path / "run.csv")
    assert main(["replay", str(tmp_path / "run.csv"), "--out", str(tmp_path / "o")]) == 0
    tr = pd.read_csv(tmp_path / "o" / "trajectory.csv")
    from pathlib import Path

    from rosbags.highlevel import AnyReader

    with AnyReader([Path(tmp_path / "o" / "trajectory.mcap")]) as r:
        assert {c.topic: c.msgtype for c in r.connections} == {"/estimate": "nav_msgs/msg/Odometry",
                                                              "/ground_truth": "nav_msgs/msg/Odometry"}
        est = [r.deserialize(raw, c.msgtype) for c, _, raw in r.messages() if c.topic == "/estimate"]
    assert len(est) == len(tr)
    cov = np.array([m.pose.covariance for m in est])
    assert np.array_equal(cov[:, 0], tr["var_x"]) and np.array_equal(cov[:, 7], tr["var_y"])
    assert np.array_equal(cov[:, 1], tr["cov_xy"]) and np.array_equal(cov[:, 35], tr["var_heading"])
    assert np.array_equal([m.twist.covariance[0] for m in est], tr["var_speed"])
    assert np.array_equal([m.pose.pose.position.x for m in est], tr["x"])
    stamps = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in est])
    assert np.allclose(stamps, tr["t"], atol=1e-9)

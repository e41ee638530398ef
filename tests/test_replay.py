"""``safenav replay``: a log through the online localizer, scored against its truth.

A simulated log (a vehicle on a circle among four landmarks: odometry at
10 Hz, range-bearing sightings at 5 Hz, truth rows) must replay to a small
causal error with a consistent NEES, from the data alone and from a prior;
the command writes the trajectory and prints the scores; Plaza1 from the
gtsam wheel replays when gtsam is installed."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from safenav import replay as rp
from safenav.cli import main
from safenav.guidance import localizer_settings
from safenav.logs import Log, read_log, write_log

LANDMARKS = {3: (0.0, 0.0), 4: (20.0, 0.0), 7: (0.0, 20.0), 9: (20.0, 20.0)}


def circle_log(seconds=60.0, seed=0) -> Log:
    rng = np.random.default_rng(seed)
    R, w, c = 6.0, 0.2, np.array([10.0, 10.0])
    events, truth = [], []
    prev = None
    for k in range(int(seconds * 10) + 1):
        t = k * 0.1
        a = w * t
        p = c + R * np.array([math.cos(a), math.sin(a)])
        heading = a + math.pi / 2
        truth.append((t, p[0], p[1], heading))
        if prev is not None:
            events.append(dict(t=t, kind="odometry", distance=R * w * 0.1 * (1 + 0.01 * rng.normal()),
                               heading_change=w * 0.1 + 0.002 * rng.normal()))
        prev = t
        if k % 2 == 0:
            for i, lm in LANDMARKS.items():
                d = np.asarray(lm) - p
                events.append(dict(t=t, kind="range_bearing", landmark=i,
                                   range=float(np.hypot(*d)) + 0.1 * rng.normal(),
                                   bearing=float(math.atan2(d[1], d[0]) - heading) + 0.02 * rng.normal(),
                                   range_std=0.1, bearing_std=0.02))
    ev = pd.DataFrame(events)
    tr = pd.DataFrame(truth, columns=["t", "x", "y", "heading"])
    rows = [dict(kind="landmark", landmark=i, x=x, y=y) for i, (x, y) in LANDMARKS.items()]
    rows += ev.to_dict("records") + [dict(kind="truth", **r) for r in tr.to_dict("records")]
    return pd.DataFrame(rows)


@pytest.fixture(scope="module")
def log_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("log") / "circle.csv"
    circle_log().to_csv(path, index=False)
    return path


def test_replay_from_the_data_is_accurate_and_consistent(log_file):
    log = read_log(log_file)
    r = rp.replay(log)
    m = r.metrics
    assert r.started_from == "data" and m["label"] == "causal"
    assert m["n_before_start"] > 0 and m["n_scored"] + m["n_before_start"] == len(log.truth)
    assert m["truth_rmse"] < 0.1 and m["truth_ade"] <= m["truth_rmse"]
    assert 0.2 < m["nees"] < 6.0
    assert r.counts["late"] == 0 and r.counts["applied"] > 1000
    assert list(r.trajectory.columns) == list(rp.TRAJECTORY_COLUMNS)
    assert np.all(np.diff(r.trajectory["t"]) > 0)


def test_replay_from_a_prior_scores_every_pose(log_file):
    log = read_log(log_file)
    t0, x, y, h = log.truth.iloc[0]
    r = rp.replay(log, localizer_settings(), prior=(t0, [x, y, 1.2, h], np.diag([0.1, 0.1, 0.5, 0.05]) ** 2))
    assert r.started_from == "prior" and r.metrics["n_before_start"] == 0 and r.metrics["truth_rmse"] < 0.1


def test_score_is_causal():
    """The estimate scored at a truth time is the latest at or before it."""
    traj = pd.DataFrame({"t": [1.0, 2.0], "x": [0.0, 10.0], "y": [0.0, 0.0], "var_x": [1.0, 1.0],
                         "var_y": [1.0, 1.0], "cov_xy": [0.0, 0.0]})
    truth = pd.DataFrame({"t": [0.5, 1.0, 1.9, 2.0], "x": [0.0, 1.0, 1.0, 10.0], "y": [0.0] * 4})
    m = rp.score(traj, truth)
    assert m["n_before_start"] == 1 and m["n_scored"] == 3
    assert m["truth_ade"] == pytest.approx((1.0 + 1.0 + 0.0) / 3)
    assert m["truth_fde"] == 0.0 and m["truth_rmse"] == pytest.approx(math.sqrt(2.0 / 3.0))


def test_score_equals_the_textbook_formulas():
    """RMSE, ADE, FDE, the 2-dof NEES eᵀP⁻¹e and the share outside 3σ of
    ``score`` against numpy's direct evaluation (np.linalg.solve per pose)."""
    rng = np.random.default_rng(5)
    n = 200
    t = np.arange(n) * 0.1
    A = rng.normal(size=(n, 2, 2))
    P = A @ A.transpose(0, 2, 1) + 0.05 * np.eye(2)
    traj = pd.DataFrame({"t": t, "x": rng.normal(size=n), "y": rng.normal(size=n), "var_x": P[:, 0, 0],
                         "var_y": P[:, 1, 1], "cov_xy": P[:, 0, 1]})
    truth = pd.DataFrame({"t": t, "x": rng.normal(size=n), "y": rng.normal(size=n)})
    m = rp.score(traj, truth)
    e = traj[["x", "y"]].to_numpy() - truth[["x", "y"]].to_numpy()
    d = np.linalg.norm(e, axis=1)
    nees = np.einsum("ni,ni->n", e, np.linalg.solve(P, e[:, :, None])[:, :, 0])
    assert m["n_scored"] == n and m["n_before_start"] == 0 and m["nees_dof"] == 2
    assert m["truth_ade"] == pytest.approx(d.mean(), rel=1e-13)
    assert m["truth_fde"] == pytest.approx(d[-1], rel=1e-14)
    assert m["truth_rmse"] == pytest.approx(np.sqrt(np.mean(d ** 2)), rel=1e-13)
    assert m["nees"] == pytest.approx(nees.mean(), rel=1e-10)
    assert m["outside_3sigma"] == np.mean(nees > 9.0)


def test_score_with_no_pose_after_the_start_is_nan():
    traj = pd.DataFrame({"t": [5.0], "x": [0.0], "y": [0.0], "var_x": [1.0], "var_y": [1.0], "cov_xy": [0.0]})
    truth = pd.DataFrame({"t": [1.0, 2.0], "x": [0.0, 1.0], "y": [0.0, 0.0]})
    m = rp.score(traj, truth)
    assert m["n_scored"] == 0 and m["n_before_start"] == 2 and math.isnan(m["truth_ade"]) and math.isnan(m["nees"])


def test_replay_command_writes_the_trajectory_and_prints_the_scores(log_file, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["replay", str(log_file), "--out", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "RMSE" in text and "causal" in text
    summary = json.loads((out / "replay.json").read_text())
    assert summary["metrics"]["truth_rmse"] < 0.1 and summary["started_from"] == "data"
    traj = pd.read_csv(out / "trajectory.csv")
    assert len(traj) > 100 and (out / "manifest.json").is_file()
    assert main(["verify", str(out), "--quiet"]) == 0


def test_replay_command_rejects_a_bad_log(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,kind,landmark,range,range_std\n1.0,range,5,3.0,0.1\n")
    assert main(["replay", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "landmark" in capsys.readouterr().err


def test_replay_round_trips_through_parquet(log_file, tmp_path):
    log = read_log(log_file)
    pq = write_log(log, tmp_path / "log.parquet")
    a, b = rp.replay(log), rp.replay(read_log(pq))
    pd.testing.assert_frame_equal(a.trajectory, b.trajectory)

"""Real-like logs (safenav.reallike) and replays that never start.

The generator must give the documented log (motion rows of the commanded
(v, ω) at 50–100 Hz, range_bearing rows from a forward camera, truth rows),
deterministic for a seed, with the noise it states; the commands must differ
from what the robot did.  A replay of such a log starts from the data within
5 s of the first sighting of a second landmark.  A replay that never starts
says why (``reason``), and ``safenav replay`` exits 3 while still writing its
files."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from safenav import replay as rp
from safenav.cli import main
from safenav.logs import Log, read_log, write_log
from safenav.reallike import RealLikeConfig, first_sighting, reallike_log


@pytest.fixture(scope="module")
def log0():
    return reallike_log(0)


def _true_at(log, t):
    tr = log.truth
    th = np.unwrap(tr["heading"].to_numpy())
    return (np.interp(t, tr["t"], tr["x"]), np.interp(t, tr["t"], tr["y"]),
            np.angle(np.exp(1j * np.interp(t, tr["t"], th))))


def test_the_log_has_the_documented_rows_and_rates(log0):
    ev = log0.events
    assert set(ev["kind"]) == {"motion", "range_bearing"}
    m = ev[ev["kind"] == "motion"]
    rate = 1.0 / np.diff(m["t"].to_numpy()).mean()
    assert 50 <= rate <= 100
    assert (m["speed"] >= 0).all() and m["distance"].isna().all()
    o = ev[ev["kind"] == "range_bearing"]
    assert len(o) > 100 and o["landmark"].notna().all()
    assert o.groupby("t").size().max() <= 2                           # at most two sightings per frame
    cfg = RealLikeConfig()
    assert (np.abs(o["bearing"]) <= math.radians(cfg.fov_deg) / 2 + 5 * math.radians(cfg.bearing_std_deg)).all()
    assert (o["range"] <= cfg.max_range + 1.0).all()
    assert log0.truth is not None and log0.truth["heading"].notna().all()


def test_deterministic_for_a_seed_and_written_by_the_log_writer(tmp_path, log0):
    again = reallike_log(0)
    pd.testing.assert_frame_equal(again.events, log0.events)
    pd.testing.assert_frame_equal(again.truth, log0.truth)
    assert not reallike_log(1).events["t"].equals(log0.events["t"])
    for name in ("log.csv", "log.parquet"):
        back = read_log(write_log(log0, tmp_path / name))
        pd.testing.assert_frame_equal(back.events, log0.events)
        pd.testing.assert_frame_equal(back.truth, log0.truth)
        assert back.landmarks == log0.landmarks


def test_sightings_carry_the_stated_noise(log0):
    o = log0.events[log0.events["kind"] == "range_bearing"]
    x, y, h = _true_at(log0, o["t"].to_numpy())
    lm = np.array([log0.landmarks[int(i)] for i in o["landmark"]])
    r = np.hypot(lm[:, 0] - x, lm[:, 1] - y)
    b = np.arctan2(lm[:, 1] - y, lm[:, 0] - x) - h
    er = (o["range"].to_numpy() - r) / o["range_std"].to_numpy()
    eb = np.angle(np.exp(1j * (o["bearing"].to_numpy() - b))) / o["bearing_std"].to_numpy()
    # truth rows are interpolated at 20 Hz: a little extra spread over the stated σ
    for e in (er, eb):
        assert abs(e.mean()) < 0.2 and 0.8 < e.std() < 1.3


def test_the_commands_are_not_what_the_robot_did(log0):
    m = log0.events[log0.events["kind"] == "motion"]
    x, y, th = _true_at(log0, 0.0)
    for v, dth, dt in zip(m["speed"], m["heading_change"], np.diff(np.r_[0.0, m["t"].to_numpy()])):
        th += dth
        x += v * dt * math.cos(th)
        y += v * dt * math.sin(th)
    xe, ye, _ = _true_at(log0, m["t"].iloc[-1])
    assert math.hypot(x - xe, y - ye) > 0.5     # dead reckoning on the commands drifts from the truth


def test_bad_config_names_the_field():
    with pytest.raises(ValueError, match="fov_deg"):
        reallike_log(0, RealLikeConfig(fov_deg=0.0))
    with pytest.raises(ValueError, match="seed"):
        reallike_log(-1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_replay_starts_within_5_s_of_the_second_landmark(seed):
    log = reallike_log(seed)
    res = rp.replay(log)
    t2 = first_sighting(log, distinct=2)
    assert res.estimated and res.t_start - t2 < 5.0
    assert res.metrics["truth_rmse"] < 0.3
    assert res.reason == "" or "before the start" in res.reason


# --------------------------------------------------------------------------- never silent

def one_landmark_log() -> Log:
    log = reallike_log(0)
    ev = log.events
    first = ev.loc[ev["kind"] == "range_bearing", "landmark"].iloc[0]
    keep = (ev["kind"] != "range_bearing") | (ev["landmark"] == first)
    return Log(landmarks=log.landmarks, events=ev[keep].reset_index(drop=True), truth=log.truth)


def test_a_replay_that_never_starts_says_why():
    res = rp.replay(one_landmark_log())
    assert not res.estimated and res.metrics == {}
    assert res.reason.startswith("never started: waiting:") and "at most 1 ranged" in res.reason


def test_the_command_exits_3_and_writes_its_files_when_nothing_is_estimated(tmp_path, capsys):
    path = write_log(one_landmark_log(), tmp_path / "one.csv")
    out = tmp_path / "out"
    assert main(["replay", str(path), "--out", str(out)]) == 3
    err = capsys.readouterr().err
    assert "never started" in err and len(err.strip().splitlines()) >= 1
    summary = json.loads((out / "replay.json").read_text())
    assert summary["reason"].startswith("never started") and summary["counts"]["motion"] == 0
    assert summary["t_start"] is None and summary["metrics"] == {}
    assert (out / "trajectory.csv").exists() and (out / "manifest.json").exists()
    assert main(["verify", str(out), "--quiet"]) == 0


def test_a_late_start_is_reported_with_the_unscored_poses(tmp_path, capsys):
    path = write_log(reallike_log(1), tmp_path / "late.csv")
    assert main(["replay", str(path), "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    summary = json.loads((tmp_path / "o" / "replay.json").read_text())
    assert "truth poses lie before the start" in summary["reason"] and summary["reason"] in out
    assert summary["metrics"]["n_before_start"] > 0

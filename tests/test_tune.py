"""``safenav tune``: noise identification from a logged run.

Real-like logs (safenav.reallike: commanded v, ω at 67 Hz with scale, bias
and noise, a camera's range+bearing rows with their true σ, truth) of 40 s.
Started from observation σ five times too small — the localizer then never
starts from the data — the tuned preset must bring the mean NIS into its χ²
band and the position NEES near 2, improve a replay of another seed, work
without truth, round-trip through its file and reject bad files by key."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from safenav import replay as rp
from safenav import tune as tn
from safenav.cli import main
from safenav.guidance import Localizer, localizer_settings
from safenav.logs import EVENT_COLUMNS, Log, write_log
from safenav.reallike import RealLikeConfig, reallike_log

CFG = RealLikeConfig(duration=40.0)
WRONG = tn.NoiseOverrides(range_std_scale=0.2, bearing_std_scale=0.2)   # σ five times too small


@pytest.fixture(scope="module")
def logs():
    return reallike_log(1, CFG), reallike_log(2, CFG)


@pytest.fixture(scope="module")
def tuned(logs):
    return tn.tune(logs[0], noise=WRONG, max_evaluations=100)


@pytest.fixture(scope="module")
def tuned_blind(logs):
    log = logs[0]
    return tn.tune(Log(landmarks=log.landmarks, events=log.events, truth=None), noise=WRONG, max_evaluations=100)


def _nees_band(c: dict) -> tuple[float, float]:
    """95 % band of the mean position NEES with one independent sample per applied update (the filter's
    error decorrelates at updates, not at the 20 Hz truth rows)."""
    n = c["nis"]["range_bearing"]["n"]
    return tn._chi2_band(n, 2.0)


def test_tuned_preset_is_consistent(tuned):
    assert tuned.method == "truth-based"
    assert not tuned.before["started"]          # σ ×0.2: the start from the data fails
    nis = tuned.after["nis"]["range_bearing"]
    assert nis["dof"] == 2.0
    lo, hi = nis["band"]
    assert lo <= nis["mean"] <= hi, nis
    lo, hi = _nees_band(tuned.after)
    assert lo <= tuned.after["nees"] <= hi, tuned.after["nees"]
    # the log's σ are the true ones: the scales come back near 1
    assert 0.7 < tuned.parameters["range_std_scale"] < 1.4
    assert 0.7 < tuned.parameters["bearing_std_scale"] < 1.4
    assert tuned.evaluations <= 100 + 10


def test_tuned_on_one_seed_improves_another(tuned, logs):
    other = logs[1]
    wrong = tn.consistency(other, rp.preset_settings("default"), WRONG)
    default = tn.consistency(other, rp.preset_settings("default"))
    after = tn.consistency(other, tuned.settings, tuned.noise)
    assert after["started"]
    if wrong["started"]:
        assert abs(math.log(after["nees"] / 2)) < abs(math.log(wrong["nees"] / 2))
    assert after["rmse"] < default["rmse"]
    lo, hi = after["nis"]["range_bearing"]["band"]
    assert lo <= after["nis"]["range_bearing"]["mean"] <= hi


def test_innovation_only(tuned_blind, logs):
    r = tuned_blind
    assert r.method == "innovation-only"
    assert "nees" not in r.after and "j_truth" not in r.after
    nis = r.after["nis"]["range_bearing"]
    assert nis["band"][0] <= nis["mean"] <= nis["band"][1]
    assert 0.7 < r.parameters["range_std_scale"] < 1.4
    assert 0.7 < r.parameters["bearing_std_scale"] < 1.4
    with pytest.raises(ValueError, match="no truth"):
        tn.tune(Log(landmarks=logs[0].landmarks, events=logs[0].events), use_truth=True)
    with pytest.raises(ValueError, match="use_truth"):
        tn.tune(logs[0], use_truth="yes")


def test_innovations_recorded_without_changing_the_replay(logs):
    a = rp.replay(logs[0])
    b = rp.replay(logs[0], innovations=True)
    pd.testing.assert_frame_equal(a.trajectory, b.trajectory)
    assert a.metrics == b.metrics and a.innovations is None
    inn = b.innovations
    assert len(inn) == int((logs[0].events["kind"] != "motion").sum())
    live = inn[np.isfinite(inn["nis"])]
    assert set(live["status"]) <= {"applied", "rejected"} and (live["dim"] == 2).all()
    # the truth likelihood's NEES is the core's trajectory score's, pose for pose
    assert tn._truth_nll(b, logs[0].truth)[1] == pytest.approx(b.metrics["nees"], rel=1e-9)


def test_log_det_s_is_that_of_the_prior():
    """A fix at the time of a motion input (no prediction between): log det S = log det(P⁻_xy + R) with P⁻
    the covariance before the fix, whether the fix is applied or rejected by its gate."""
    rng = np.random.default_rng(3)
    rows, t, x = [], 0.0, np.array([1.0, 2.0])
    for k in range(40):
        t += 0.1
        x = x + [0.05, 0.0]
        rows.append(dict(t=t, kind="motion", speed=0.5, heading_change=0.0))
        z = x + rng.normal(0, 0.2, 2) + (5.0 if k == 30 else 0.0)      # one gross fix: rejected
        rows.append(dict(t=t, kind="fix", x=z[0], y=z[1], std_x=0.2, std_y=0.3))
    events = pd.DataFrame(rows, columns=list(EVENT_COLUMNS))
    events["landmark"] = pd.array([pd.NA] * len(events), dtype="Int64")
    log = Log(landmarks={}, events=events)
    prior = (0.0, np.array([1.0, 2.0, 0.5, 0.0]), np.diag([0.3, 0.3, 0.1, 0.01]) ** 2)
    res = rp.replay(log, prior=prior, innovations=True)
    loc = Localizer(localizer_settings(), np.zeros((0, 2)), [])
    loc.initialize(*prior)
    want, status = [], []
    for r in events.itertuples():
        if r.kind == "motion":
            loc.motion(r.t, r.speed, r.heading_change)
        else:
            R = np.diag([r.std_x ** 2, r.std_y ** 2])
            want.append(np.linalg.slogdet(loc.P[:2, :2] + R)[1])
            status.append(loc.fix(r.t, r.x, r.y, R).status.name.lower())
    assert "rejected" in status and list(res.innovations["status"]) == status
    np.testing.assert_allclose(res.innovations["logdet_s"], want, rtol=0, atol=1e-9)


def test_preset_round_trip(tmp_path):
    s = rp.preset_settings("plaza", gate=0.995)
    s.bmm.set_param("speed_noise", 0.0123)
    noise = tn.NoiseOverrides(range_std_scale=1.7, bearing_std=0.02)
    path = tn.save_preset(tmp_path / "p.toml", s, noise, base="plaza", comment="a test")
    s2, n2 = tn.load_preset(path)
    assert tn._settings_tables(s2) == tn._settings_tables(s)
    assert n2 == noise and tn.preset_base(path) == "plaza"
    assert n2.std("bearing", 0.5) == 0.02 and n2.std("range", 2.0) == pytest.approx(3.4)
    # JSON with the same tables
    import json
    import tomllib
    jpath = tmp_path / "p.json"
    jpath.write_text(json.dumps(tomllib.loads(path.read_text())))
    s3, n3 = tn.load_preset(jpath)
    assert tn._settings_tables(s3) == tn._settings_tables(s) and n3 == noise


def test_a_saved_preset_states_each_value_once_and_an_edit_takes_effect(tmp_path):
    import tomllib
    s = rp.preset_settings("plaza")
    s.filter.bandwidth_scale = 0.5
    path = tn.save_preset(tmp_path / "p.toml", s)
    tables = tomllib.loads(path.read_text())
    keys = [k for t in ("filter", "bmm", "localizer", "augment") for k in tables[t]]
    assert not [k for k in tables["localizer"] if k.startswith(("bmm_", "augment_", "filter_"))]
    assert len(keys) == len(set(keys)) and tables["filter"]["bandwidth_scale"] == 0.5
    edited = path.read_text().replace(f"speed_noise = {tables['bmm']['speed_noise']!r}", "speed_noise = 0.3")
    assert edited != path.read_text()
    path.write_text(edited)
    s2, _ = tn.load_preset(path)
    assert s2.bmm.speed_noise == 0.3 and s2.filter.bandwidth_scale == 0.5


GOOD = """[preset]
format = "safenav-preset"
version = 1
[bmm]
speed_noise = 0.1
heading_noise = 0.01
position_noise = 0.01
"""


@pytest.mark.parametrize("text, key", [
    (GOOD.replace('[preset]\nformat = "safenav-preset"\nversion = 1\n', ""), r"\[preset\]"),
    (GOOD.replace("version = 1\n", ""), "version"),
    (GOOD.replace("version = 1", "version = 7"), "version"),
    (GOOD.replace("speed_noise = 0.1\n", ""), "speed_noise"),
    (GOOD.replace("speed_noise = 0.1", "speed_noise = -1.0"), "speed_noise"),
    (GOOD.replace("heading_noise = 0.01", 'heading_noise = "small"'), "heading_noise"),
    (GOOD.replace("position_noise = 0.01", "position_noise = true"), "position_noise"),
    (GOOD + "speed_nose = 0.1\n", "speed_nose"),
    (GOOD + "[observations]\nrange_std_scale = 0.0\n", "range_std_scale"),
    (GOOD + "[observations]\nbearing_std = \"x\"\n", "bearing_std"),
    (GOOD + "[localizer]\ngate_probability = 2.0\n", "gate_probability"),
    (GOOD + "[filter]\ntype = \"kalman\"\n", "type"),
    (GOOD + "[sensor]\nx = 1\n", "sensor"),
    (GOOD + "[augment]\nstates = [\"range_scale\", \"wheel\"]\n", "states"),
    ("[preset\n", "not a valid TOML"),
])
def test_bad_preset_files(tmp_path, text, key):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=key):
        tn.load_preset(path)
    assert tn.load_preset(_write(tmp_path / "good.toml", GOOD))[0].bmm.speed_noise == 0.1


def _write(path, text):
    path.write_text(text)
    return path


def test_cli_tune_then_replay(tmp_path, logs, capsys):
    csv = tmp_path / "run.csv"
    write_log(logs[0], csv)
    preset = tmp_path / "tuned.toml"
    assert main(["tune", str(csv), "--out", str(preset), "--evaluations", "12", "-q"]) == 0
    out = capsys.readouterr().out
    assert "truth-based" in out and "before:" in out and "after:" in out and "speed_noise" in out
    settings, noise = tn.load_preset(preset)
    assert settings.bmm.speed_noise > 0 and noise.range_std_scale > 0
    assert main(["replay", str(csv), "--preset", str(preset), "--out", str(tmp_path / "r"), "-q"]) == 0
    assert "RMSE" in capsys.readouterr().out
    assert main(["tune", str(csv), "--out", str(tmp_path / "b.toml"), "--evaluations", "8", "--no-truth", "-q"]) == 0
    assert "innovation-only" in capsys.readouterr().out
    assert main(["replay", str(csv), "--preset", "nonsense", "--out", str(tmp_path / "x"), "-q"]) == 2
    assert "neither a named preset" in capsys.readouterr().err
    assert main(["replay", str(csv), "--preset", str(tmp_path / "missing.toml"), "--out", str(tmp_path / "x")]) == 2
    assert "missing.toml" in capsys.readouterr().err


def test_several_logs_pool(logs):
    """Two runs tuned together: the pooled consistency weighs each run by its samples."""
    s = rp.preset_settings("default")
    a, b = (tn.consistency(g, s) for g in logs)
    both = tn.consistency(list(logs), s)
    kind = "range_bearing"
    n = a["nis"][kind]["n"] + b["nis"][kind]["n"]
    assert both["nis"][kind]["n"] == n
    assert both["nis"][kind]["mean"] == pytest.approx(
        (a["nis"][kind]["mean"] * a["nis"][kind]["n"] + b["nis"][kind]["mean"] * b["nis"][kind]["n"]) / n)
    m = a["n_scored"] + b["n_scored"]
    assert both["rmse"] == pytest.approx(math.sqrt((a["rmse"] ** 2 * a["n_scored"] + b["rmse"] ** 2 * b["n_scored"]) / m))
    r = tn.tune(list(logs), max_evaluations=6)
    assert r.method == "truth-based" and r.after["nis"][kind]["n"] >= 1
    with pytest.raises(ValueError, match="sequence of Logs"):
        tn.tune([])

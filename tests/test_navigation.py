"""SafeNav navigation (Algorithms 1, 2 and 4), the Monte Carlo runner and the
``safenav demo/run/plan`` commands.

Controllers are checked against the algorithms' text on hand-built corridors;
trial metrics against the metric functions of :mod:`safenav.metrics` on the
recorded trajectories; the runner for determinism across workers, chunks and
a Dask LocalCluster."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

import safenav
from safenav import _core, metrics, results, runner
from safenav import navigation as nv
from safenav import planning as P
from safenav.geometry import Corridor
from safenav.motion import Bmm, BmmParams

ZONES = safenav.RiskZones(half_width=4.0, weights=[2.0, 4.0, 6.0, 8.0])
STRAIGHT = np.array([(5.0, 20.0), (55.0, 20.0)])
BEND = np.array([(5.0, 5.0), (30.0, 5.0), (30.0, 35.0), (55.0, 35.0)])
# Landmarks every 10 m on both sides of both paths: always >= 3 in view.
LANDMARKS = np.array([(x, y) for x in range(0, 81, 10) for y in (0.0, 12.0, 28.0, 42.0)], float)


def bmm_params(noise: bool = True) -> BmmParams:
    p = BmmParams()
    if not noise:
        p.speed_noise = p.heading_noise = p.position_noise = 0.0
    return p


def build(path, **kw):
    return nv.Navigator(*parts(path, **kw))


def parts(path, *, method="centroid", circles=(), polygons=(), noise=True, filter="ekf", source_std=None,
          clearance=1.0, landmarks=LANDMARKS, replan=True, max_steps=0, record=True, n_particles=200):
    problem = nv.NavigationProblem()
    problem.path = np.asarray(path, float)
    problem.zones = ZONES
    problem.map = P.make_map(lower=(0, 0), upper=(60, 40), circles=circles, polygons=polygons, clearance=clearance)
    problem.bmm = bmm_params(noise)
    s = nv.NavigationSettings()
    s.method = nv.METHODS[method]
    s.replan = replan
    s.max_steps = max_steps
    s.record = record
    s.planner = P.PlannerSettings(max_iterations=1500, corridor_bias=0.5, smooth=True)
    fo = _core.FilterOptions()
    fo.type = nv.FILTERS[filter]
    fo.n_particles = n_particles
    s.filter = fo
    se = nv.SensorSettings()
    se.position = nv.position_source("lanbloc")
    if source_std is not None:
        se.position.std = np.asarray(source_std, float)
    if not noise:
        se.position.std = np.array([1e-6, 1e-6])
        se.imu_speed_std = se.imu_heading_std = 1e-6
    se.landmarks = landmarks
    return problem, s, se


# --------------------------------------------------------------------------- Algorithm 2

def test_centroid_control_steers_at_the_nearest_centroid_ahead():
    corridor = Corridor(BEND, ZONES)
    segs = corridor.segments(length=10.0, sub_segments=4)
    rng = np.random.default_rng(3)
    for _ in range(50):
        est = np.array([rng.uniform(5, 55), rng.uniform(5, 35), 2.0, rng.uniform(-math.pi, math.pi)])
        target = segs.nearest_centroid_ahead(est[:2])
        goal = target.point if target.ahead else BEND[-1]
        u = nv.centroid_control(segs, est, 2.0)
        want = safenav.wrap_angle(math.atan2(goal[1] - est[1], goal[0] - est[0]) - est[3])
        assert u[0] == 2.0
        assert u[1] == pytest.approx(want, abs=1e-12)
        # "Nearest": no centroid ahead of the vehicle is closer.
        c, s = segs.centroids, segs.centroid_arc_lengths
        ahead = s > corridor.project(est[:2]).arc_length
        if ahead.any():
            assert np.linalg.norm(goal - est[:2]) <= np.linalg.norm(c[ahead] - est[:2], axis=1).min() + 1e-12


# --------------------------------------------------------------------------- Algorithm 1

def test_chull_keeps_the_default_command_inside_the_hulls():
    corridor = Corridor(STRAIGHT, ZONES)
    segs = corridor.segments(length=10.0)
    bmm = Bmm(bmm_params())
    est = np.array([12.0, 21.0, 2.0, 0.0])
    d = nv.chull_control(segs, bmm, est, 2.0, 5.0, 0.5)
    assert d.action == nv.ChullAction.KEEP
    aim = corridor.point_at(corridor.project(est[:2]).arc_length + 5.0)  # the look-ahead point
    assert d.control[1] == pytest.approx(math.atan2(aim[1] - 21.0, aim[0] - 12.0), abs=1e-12)
    assert d.control[0] == 2.0
    assert np.allclose(d.predicted, bmm.predict(est, d.control)[:2])
    assert segs.in_current_or_next(d.segment, d.predicted)


def test_chull_corrects_when_the_prediction_leaves_both_hulls():
    corridor = Corridor(STRAIGHT, ZONES)
    segs = corridor.segments(length=10.0)
    p = bmm_params()
    bmm = Bmm(p)
    # On the hull's edge (y = 20 + W), moving straight out at top speed: the
    # heading change is clipped to m*dt, so the default command's prediction
    # leaves the hulls and line 17's corrective control takes over.
    edge_y = 20.0 + ZONES.half_width * 0.999
    est = np.array([22.0, edge_y, p.max_speed, math.pi / 2])
    default_pred = bmm.predict(est, np.array([2.0, 0.0]))[:2]
    assert not segs.in_current_or_next(segs.segment_at(corridor.project(est[:2]).arc_length), default_pred)
    d = nv.chull_control(segs, bmm, est, 2.0, 5.0, 0.5)
    assert d.action == nv.ChullAction.CORRECTIVE
    aim = corridor.point_at(corridor.project(est[:2]).arc_length + 1.0)
    assert d.control[1] == pytest.approx(safenav.wrap_angle(math.atan2(aim[1] - edge_y, aim[0] - 22.0) - math.pi / 2))


def test_chull_steps_back_outside_every_adjacent_hull():
    corridor = Corridor(STRAIGHT, ZONES)
    segs = corridor.segments(length=10.0)
    bmm = Bmm(bmm_params())
    est = np.array([30.0, 20.0 + 3 * ZONES.half_width, 1.0, 0.0])
    d = nv.chull_control(segs, bmm, est, 2.0, 5.0, 0.5)
    assert d.action == nv.ChullAction.STEP_BACK
    assert d.control[0] == 0.5                     # step-back speed
    foot = corridor.project(est[:2]).foot          # toward the nearest path point: straight down
    assert d.control[1] == pytest.approx(math.atan2(foot[1] - est[1], foot[0] - est[0]))


def test_chull_shortens_the_lookahead_around_an_obstacle_corner():
    corridor = Corridor(BEND, ZONES)
    segs = corridor.segments(length=10.0)
    bmm = Bmm(bmm_params())
    # Just before the bend; a disc sits inside the corner, on the chord to the
    # 5 m look-ahead point (27, 5) -> (30, 7).
    est = np.array([27.0, 5.0, 2.0, 0.0])
    checker = P.ObstacleChecker(P.make_map(lower=(0, 0), upper=(60, 40), circles=[(29.0, 6.2, 0.6)]))
    free = nv.chull_control(segs, bmm, est, 2.0, 5.0, 0.5)
    safe = nv.chull_control(segs, bmm, est, 2.0, 5.0, 0.5, checker)
    aim5 = corridor.point_at(corridor.project(est[:2]).arc_length + 5.0)
    assert not checker.segment_free(est[:2], aim5)
    assert free.control[1] == pytest.approx(math.atan2(aim5[1] - 5.0, aim5[0] - 27.0))
    assert safe.control[1] < free.control[1]       # a shorter look-ahead turns later


# --------------------------------------------------------------------------- whole trials

@pytest.mark.parametrize("method", ["chull", "centroid"])
@pytest.mark.parametrize("path", [STRAIGHT, BEND], ids=["straight", "bend"])
def test_noise_free_trials_arrive_inside_the_corridor(method, path):
    trial = build(path, method=method, noise=False).run(seed=0)
    assert trial.outcome_name == "arrived", trial.reason
    assert trial.success
    assert trial.metrics["max_deviation"] < ZONES.half_width
    assert np.linalg.norm(trial.estimate[-1, :2] - path[-1]) <= 1.0
    assert trial.metrics["truth_ade"] < 1e-3
    assert trial.replans == 0 and trial.dropouts < 0.1 * trial.steps


@pytest.mark.parametrize("method", ["chull", "centroid"])
def test_trial_metrics_match_the_metric_functions(method):
    trial = build(BEND, method=method).run(seed=5)
    assert trial.success, trial.reason
    est, truth, m = trial.estimate[:, :2], trial.truth[:, :2], trial.metrics
    assert m["path_ade"] == pytest.approx(metrics.distance_to_path(est, BEND).mean(), rel=1e-9)  # eq. 21 (our pairing)
    assert m["goal_fde"] == pytest.approx(np.linalg.norm(est[-1] - BEND[-1]), rel=1e-9)          # eq. 22
    assert m["path_error_percent"] == pytest.approx(metrics.path_length_error_percent(est, BEND), rel=1e-9)
    assert m["awrs"] == pytest.approx(metrics.awrs(est, BEND, ZONES), rel=1e-9)                # eq. 20
    assert m["awrs_true"] == pytest.approx(metrics.awrs(truth, BEND, ZONES), rel=1e-9)
    assert m["truth_ade"] == pytest.approx(np.linalg.norm(est - truth, axis=1).mean(), rel=1e-9)
    assert m["truth_fde"] == pytest.approx(np.linalg.norm(est[-1] - truth[-1]), rel=1e-9)
    assert m["max_deviation"] == pytest.approx(metrics.distance_to_path(truth, BEND).max(), rel=1e-9)
    # Bookkeeping: one row per step, fixes where LanBLoc measured.
    n = trial.steps + 1
    assert trial.truth.shape == (n, 4) and trial.controls.shape == (trial.steps, 2)
    assert np.isfinite(trial.measured[1:, 0]).sum() == trial.position_fixes
    assert trial.position_fixes + trial.dropouts == trial.steps


def test_trial_truth_metrics_are_the_trajectory_score_of_its_recorded_poses():
    """The loop feeds the one accumulator (metrics.TrajectoryScore) pose by pose:
    fed the recorded trajectories, it gives the trial's numbers bit for bit."""
    trial = build(BEND, method="centroid").run(seed=7)
    est, truth = trial.estimate[:, :2], trial.truth[:, :2]
    acc = metrics.TrajectoryScore(len(est))
    acc.add_rows(np.ascontiguousarray(est), np.tile([1.0, 0.0, 0.0, 1.0], (len(est), 1)), np.ascontiguousarray(truth))
    assert acc.truth_ade == trial.metrics["truth_ade"] and acc.truth_fde == trial.metrics["truth_fde"]
    L = metrics.path_length(BEND)
    assert trial.metrics["path_error_percent"] == pytest.approx(abs(acc.length - L) / L * 100.0, rel=1e-12)


def test_outcome_names_are_the_cores():
    assert nv.OUTCOMES == ("arrived", "collision", "left_corridor", "step_limit", "lost_localization", "no_path",
                           "blocked")
    for code, name in enumerate(nv.OUTCOMES):
        assert _core.outcome_name(nv.TrialOutcome(code)) == name


def test_same_seed_same_trial_and_run_many_equals_run():
    nav = build(BEND, method="centroid")
    a, b = nav.run(seed=11), nav.run(seed=11)
    assert np.array_equal(a.estimate, b.estimate) and np.array_equal(a.truth, b.truth)
    c = nav.run(seed=12)
    assert not np.array_equal(a.truth, c.truth)
    many = nav.run_many([11, 12])
    assert many["path_ade"][0] == a.metrics["path_ade"] and many["path_ade"][1] == c.metrics["path_ade"]
    assert list(many["steps"]) == [a.steps, c.steps]


def test_particle_filter_in_the_loop():
    trial = build(BEND, method="centroid", filter="pf", n_particles=300).run(seed=2)
    assert trial.success, trial.reason
    assert trial.metrics["truth_ade"] < 0.2


def test_dropouts_without_landmarks_predict_and_grow_the_covariance():
    # Landmarks only near the start: after ~30 m no fix; IMU-only prediction.
    few = np.array([(15.0, 14.0), (18.0, 26.0), (22.0, 15.0), (25.0, 25.0)])
    trial = build(STRAIGHT, method="centroid", landmarks=few).run(seed=1)
    assert trial.success, trial.reason
    assert trial.dropouts > trial.steps // 2
    fixes = np.isfinite(trial.measured[:, 0])
    last_fix = np.flatnonzero(fixes).max()
    assert trial.position_std[-1] > 3 * trial.position_std[last_fix]


def test_blocked_path_triggers_replanning_and_still_arrives():
    # A disc on the straight safe path: detected ahead, RAw-RRT* detour.
    trial = build(STRAIGHT, method="centroid", circles=[(30.0, 20.0, 2.0)]).run(seed=4)
    assert trial.outcome_name == "arrived", trial.reason
    assert trial.replans >= 1
    truth = trial.truth[:, :2]
    assert np.all(np.linalg.norm(truth - [30.0, 20.0], axis=1) > 2.0)   # never inside the disc
    assert len(trial.followed_path) > 2                                   # the detour was spliced in
    assert P.path_is_free(P.make_map(lower=(0, 0), upper=(60, 40), circles=[(30.0, 20.0, 2.0)]),
                          trial.followed_path)


def test_no_way_through_ends_with_a_clear_failure():
    wall = [np.array([(29.0, 0.0), (31.0, 0.0), (31.0, 40.0), (29.0, 40.0)])]
    trial = build(STRAIGHT, method="chull", polygons=wall).run(seed=0)
    assert trial.outcome_name == "no_path"
    assert not trial.success
    assert "no detour" in trial.reason or "replans" in trial.reason
    assert trial.steps < 400                        # stopped where it was blocked, not at the step limit
    assert np.all(trial.truth[:, 0] < 29.0)


def test_step_limit_is_an_explicit_outcome():
    trial = build(STRAIGHT, method="centroid", max_steps=50).run(seed=0)
    assert trial.outcome_name == "step_limit" and trial.steps == 50
    assert "50 steps" in trial.reason


def test_position_callback_replaces_the_source():
    nav = build(STRAIGHT, method="centroid")
    calls = []

    def camera(truth, step):
        calls.append(step)
        if step % 2:
            return None                               # a failed localization: dropout
        return truth[:2] + 0.01, np.eye(2) * 1e-4

    trial = nav.run(seed=3, position=camera)
    assert trial.success, trial.reason
    assert calls[0] == 0 and len(calls) == trial.steps + 1
    assert trial.dropouts == (trial.steps + 1) // 2  # the odd steps 1, 3, …
    assert np.allclose(trial.measured[2, :], trial.truth[2, :2] + 0.01)

    def broken(truth, step):
        raise RuntimeError("camera unplugged")

    with pytest.raises(RuntimeError, match="camera unplugged"):
        nav.run(seed=3, position=broken)
    with pytest.raises(ValueError, match="None or"):
        nav.run(seed=3, position=lambda t, s: (1.0, 2.0, 3.0))


# --------------------------------------------------------------------------- bad input

def _with(obj, **kw):
    for k, v in kw.items():
        setattr(obj, k, v)
    return obj


@pytest.mark.parametrize("edit, match", [
    (lambda pr, s, se: setattr(pr, "path", np.array([[0.0, 0.0], [np.nan, 1.0]])), "path"),
    (lambda pr, s, se: setattr(s, "cruise_speed", -1.0), "cruise_speed = -1"),
    (lambda pr, s, se: setattr(s, "arrival_radius", float("nan")), "arrival_radius"),
    (lambda pr, s, se: setattr(se, "min_landmarks", -2), "min_landmarks = -2"),
    (lambda pr, s, se: setattr(se, "max_range", 0.0), "max_range = 0"),
    (lambda pr, s, se: setattr(se, "position", _with(se.position, outlier_probability=2.0)),
     "outlier_probability = 2"),
    (lambda pr, s, se: setattr(se, "position_every", 0), "position_every = 0"),
])
def test_bad_navigation_input_names_the_value(edit, match):
    pr, s, se = parts(STRAIGHT)
    edit(pr, s, se)
    with pytest.raises(ValueError, match=match):
        nv.Navigator(pr, s, se)


def test_bad_names_are_clear_errors():
    sc = safenav.default_scenario()
    with pytest.raises(ValueError, match="method = 'zigzag'"):
        nv.make_navigator(sc, STRAIGHT, method="zigzag")
    with pytest.raises(ValueError, match="source = 'gps'"):
        nv.make_navigator(sc, STRAIGHT, source="gps")
    with pytest.raises(ValueError, match="trials = 0"):
        runner.Sweep(sc, trials=0)
    with pytest.raises(ValueError, match="'P9' is not a path type"):
        runner.Sweep(sc, path_types=("P9",))


# --------------------------------------------------------------------------- the runner

@pytest.fixture(scope="module")
def small_sweep():
    sc = safenav.default_scenario()
    paths = {"P3": np.asarray(nv.plan_safe_path(sc, "P3", iterations=1500).path)}
    sweep = runner.Sweep(sc, path_types=("P3",), methods=("chull", "centroid"), trials=12, seed=5, chunk=5)
    return sweep, paths


def _strip_times(df):
    return df.drop(columns=["time_ms", "time_per_step_us"])


def test_sweep_is_identical_across_workers_and_chunks(small_sweep):
    sweep, paths = small_sweep
    one = runner.run_sweep(sweep, workers=1, safe_paths=paths)
    two = runner.run_sweep(sweep, workers=2, safe_paths=paths)
    other = runner.run_sweep(runner.Sweep(sweep.scenario, path_types=("P3",), methods=("chull", "centroid"),
                                          trials=12, seed=5, chunk=7), workers=2, safe_paths=paths)
    pd.testing.assert_frame_equal(_strip_times(one), _strip_times(two))
    pd.testing.assert_frame_equal(_strip_times(one), _strip_times(other))
    assert len(one) == 24 and list(one["trial"][:12]) == list(range(12))
    # Common random numbers: both methods see the same trial seeds.
    assert list(one[one.method == "chull"]["seed"]) == list(one[one.method == "centroid"]["seed"])
    # A trial of the table is the same trial run alone.
    nav = nv.make_navigator(sweep.scenario, paths["P3"], method="centroid")
    row = one[one.method == "centroid"].iloc[3]
    alone = nav.run(int(row["seed"]))
    assert alone.metrics["path_ade"] == row["path_ade"] and alone.steps == row["steps"]


def test_summary_is_computed_from_the_raw_table(small_sweep, tmp_path):
    sweep, paths = small_sweep
    raw = runner.run_sweep(sweep, workers=2, safe_paths=paths)
    summary = runner.summarize(raw)
    for _, r in summary.iterrows():
        g = raw[(raw.method == r["method"]) & (raw.path_type == r["path_type"])]
        ok = g[g.success]
        assert r["trials"] == len(g)
        assert r["success_rate"] == pytest.approx(g.success.mean())
        for k in runner.METRICS:
            assert r[k] == pytest.approx(ok[k].mean())
        assert r["time_ms"] == pytest.approx(g.time_ms.median())
    files = results.write_table(raw, tmp_path / "trials")
    assert sorted(p.name for p in files) == ["trials.csv", "trials.parquet", "trials_timings.csv"]
    back = results.read_table(tmp_path / "trials.parquet")
    pd.testing.assert_frame_equal(back, raw)
    assert not list(tmp_path.glob(".safenav-tmp-*"))


def test_dask_local_cluster_equals_local_run(small_sweep):
    distributed = pytest.importorskip("distributed")
    sweep, paths = small_sweep
    local = runner.run_sweep(sweep, workers=2, safe_paths=paths)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=True, dashboard_address=None) as cl, \
            distributed.Client(cl) as client:
        remote = runner.run_sweep(sweep, scheduler=client, safe_paths=paths)
    pd.testing.assert_frame_equal(_strip_times(local), _strip_times(remote))


# --------------------------------------------------------------------------- the command line

def test_demo_command_writes_tables_and_figures(tmp_path, capsys):
    from safenav.cli import main

    assert main(["demo", "--trials", "3", "--out", str(tmp_path), "--quiet", "--path-types", "P2", "P3"]) == 0
    out = capsys.readouterr().out
    assert "SafeNav-CHull" in out and "SafeNav-Centroid" in out and "paper ADE" in out
    for name in ("trials.csv", "trials.parquet", "trials_timings.csv", "summary.csv",
                 "table_navigation_ekf_lanbloc.md", "table_percent_error_ekf_lanbloc.csv", "fig4_chull.png",
                 "fig5_centroid.png", "fig5_centroid.svg", "manifest.json"):
        assert (tmp_path / name).stat().st_size > 0, name
    raw = pd.read_parquet(tmp_path / "trials.parquet")
    assert len(raw) == 3 * 2 * 2
    table = pd.read_csv(tmp_path / "table_navigation_ekf_lanbloc.csv")
    chull_p2 = table[(table.Approach == "SafeNav-CHull") & (table.Path == "P2")].iloc[0]
    ok = raw[(raw.method == "chull") & (raw.path_type == "P2") & raw.success]
    assert chull_p2["ADE"] == pytest.approx(ok.path_ade.mean())
    assert chull_p2["paper ADE"] == 2.72


def test_run_and_plan_commands_on_a_scenario_file(tmp_path, capsys):
    from safenav.cli import main

    sc = safenav.default_scenario()
    f = tmp_path / "s.toml"
    safenav.save_scenario(sc, f)
    assert main(["plan", "--scenario", str(f), "--path-types", "P3", "--iterations", "800",
                 "--out", str(tmp_path / "plan")]) == 0
    assert (tmp_path / "plan" / "safe_paths.json").exists() and (tmp_path / "plan" / "safe_paths.png").exists()
    import json
    safety = json.loads((tmp_path / "plan" / "safe_paths.json").read_text())["P3"]["safety"]
    assert safety["min_clearance_m"] >= sc.navigation.planning_clearance and safety["exposure_m"] >= 0
    assert "safety: min clearance" in capsys.readouterr().out
    assert main(["run", "--scenario", str(f), "--trials", "2", "--methods", "centroid", "--filters", "pf", "--particles", "100",
                 "--path-types", "P3", "--out", str(tmp_path / "run"), "--quiet"]) == 0
    raw = pd.read_csv(tmp_path / "run" / "trials.csv")
    assert set(raw["filter"]) == {"pf"} and len(raw) == 2
    bad = tmp_path / "bad.toml"
    bad.write_text(f.read_text().replace("cruise_speed = 2.0", "cruise_speed = -3.0"))
    assert main(["run", str(bad), "--trials", "1", "--quiet", "--out", str(tmp_path / "x")]) == 2
    assert "navigation.cruise_speed" in capsys.readouterr().err


def test_camera_loop_source_runs_the_vision_pipeline_in_the_sweep(small_sweep):
    sweep, paths = small_sweep
    cam = runner.Sweep(sweep.scenario, path_types=("P3",), methods=("centroid",), sources=("lanbloc-camera",),
                       trials=1, position_every=40, seed=5)
    raw = runner.run_sweep(cam, workers=1, safe_paths=paths)
    row = raw.iloc[0]
    assert row["source"] == "lanbloc-camera" and row["success"], row["reason"]
    # One rendered frame every 40 steps: each gave a fix (applied, or rejected by the gate) or a dropout.
    frames = row["steps"] // 40
    assert frames - row["rejected"] <= row["position_fixes"] + row["dropouts"] <= frames
    assert row["position_fixes"] > 0
    assert row["truth_ade"] < 2.0


def _source_residual_stats(residuals, profile):
    """Per-trial (bias estimate, white std, outlier share, walk drift) of fix residuals (n_trials, n_fixes, 2)."""
    r = np.asarray(residuals)
    first, last = r[:, :200].mean(axis=1), r[:, -200:].mean(axis=1)
    bias = r.mean(axis=1)
    dev = r - np.median(r, axis=1, keepdims=True)
    white = np.median(np.abs(np.diff(dev, axis=1)), axis=(0, 1)) / 0.6745 / np.sqrt(2)  # robust σ of w
    far = (np.abs(dev) > 5 * np.asarray(profile.std)).any(axis=2).mean()
    return bias, white, far, last - first


def test_navigation_loop_draws_its_fixes_from_the_same_sampler():
    """The loop seeds its sensors with derive_seed(trial seed, 1) and draws its
    first fix (the initial estimate) first: the same fix the synthetic set's
    sampler gives for that seed.  A bias-only profile then shows one bias for
    the whole trial, the sampler's."""
    every_term = nv.PositionNoise(std=(0.2, 0.1), bias_std=0.3, bias_walk_std=0.01, outlier_probability=0.2,
                                  outlier_std=1.0, needs_landmarks=False)
    bias_only = nv.PositionNoise(std=(1e-5, 1e-5), bias_std=0.5, needs_landmarks=False)
    for noise in (every_term, bias_only, nv.position_source("lanbloc")):
        pr, s, se = parts(STRAIGHT)
        se.position = noise
        nav = nv.Navigator(pr, s, se)
        for seed in (3, 4):
            t = nav.run(seed)
            truth, measured = np.asarray(t.truth)[:, :2], np.asarray(t.measured)
            first = noise.sample(truth[:1], _core.derive_seed(seed, 1))
            np.testing.assert_array_equal(measured[:1], first)
            if noise is bias_only:
                e = measured - truth
                assert np.abs(e - (first - truth[:1])).max() < 1e-4
                assert np.abs(e).max() > 0.05  # a real bias, not zero


@pytest.mark.parametrize("name", ["deeploc-gps", "deeploc-ekf-gps", "sensor-fusion"])
def test_emulated_sources_have_their_stated_error_statistics(name):
    """The measurement-level sources draw z = p + b + w (+ outliers) as their
    profile says, in the C++ loop and in the synthetic data set alike."""
    from dataclasses import replace

    from scipy.stats import norm

    from safenav.datasets import synthetic_trajectory
    from safenav.experiments import source_config

    scenario = safenav.default_scenario()
    prof = nv.SOURCES[name]
    assert prof.emulated and "(emulated)" in prof.label
    n_trials, n_fix = 40, 1500
    safe = nv.plan_safe_path(scenario, "P2").path
    navigator = nv.make_navigator(scenario, safe, method="centroid", source=name)
    loop = []
    for s in range(n_trials):
        t = navigator.run(100 + s)
        loop.append((np.asarray(t.measured) - np.asarray(t.truth)[:, :2])[:n_fix])
    cfg = replace(source_config(name), n_steps=n_fix)
    syn = [synthetic_trajectory(cfg, 100 + s) for s in range(n_trials)]
    syn = [d.position - d.states[1:, :2] for d in syn]
    for residuals in (loop, syn):
        bias, white, far, drift = _source_residual_stats(residuals, prof)
        assert white == pytest.approx(prof.std, rel=0.1)
        # a constant bias per trial: the per-trial means scatter with bias_std (40 trials: ±25 %)
        # (plus the walk's and the white noise's share of a mean over n_fix fixes)
        noise = np.asarray(prof.std) ** 2 + prof.outlier_probability * prof.outlier_std**2
        spread = np.sqrt(prof.bias_std**2 + prof.bias_walk_std**2 * n_fix / 3 + noise / n_fix)
        assert bias.std(axis=0) == pytest.approx(spread, rel=0.35)
        # the walk moves the bias between the first and the last 200 fixes (the white noise of two means too)
        walk = np.sqrt(prof.bias_walk_std**2 * (n_fix - 200) + 2 * noise / 200)
        assert drift.std(axis=0) == pytest.approx(walk, rel=0.35)
        # outliers: the share of fixes beyond 5σ of the white noise in either axis
        out_std = np.hypot(prof.outlier_std, np.asarray(prof.std))
        expect = prof.outlier_probability * (1 - np.prod(1 - 2 * norm.sf(5 * np.asarray(prof.std) / out_std)))
        assert far == pytest.approx(expect, rel=0.3, abs=2e-4)
    # the filter is told the profile's covariance, the same in both
    np.testing.assert_array_equal(cfg.position_cov(), navigator.sensors.position.reported_cov())

"""Certified missions (safenav.certify): a blind narrow gap is not certified
as given, the proposed landmarks certify it, the proposed scenario loads and
runs, an easy path needs none, an impossible one says why, and the cover's
count is the brute-force minimum."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from safenav import certify as C
from safenav import certify_report
from safenav import cli
from safenav import navigation as nv
from safenav import placement as P
from safenav.belief import propagate_belief, propagate_belief_along, robust_sight
from safenav.scenario import Scenario, load_scenario, save_scenario


def gap_world(half: float = 3.0, eps: float = 1e-4, extra_obstacles=(), **detection) -> Scenario:
    """A 140 x 40 m field, start (5, 20) with a fix in view, destination
    (120, 20); two blocks fill x in [80, 90] but for a gap of half-width
    ``half`` about y = 20.  No landmark is in view from x = 18 to the gap's
    far end: the gap is passed dead-reckoning."""
    lms = [((115, 17), 1), ((115, 23), 1), ((130, 20), 1),   # destination cluster, centroid (120, 20)
           ((2, 18), 0), ((2, 22), 0), ((11, 20), 0),        # start cluster, centroid (5, 20)
           ((15, 16), 2), ((15, 24), 2), ((18, 20), 2)]      # ahead of the start: a fix there
    obstacles = [{"type": "polygon", "vertices": [[80.0, 0.0], [90.0, 0.0], [90.0, 20 - half], [80.0, 20 - half]]},
                 {"type": "polygon", "vertices": [[80.0, 20 + half], [90.0, 20 + half], [90.0, 40.0], [80.0, 40.0]]},
                 *extra_obstacles]
    d = {"name": "gap", "world": {"field": {"x_min": 0.0, "y_min": 0.0, "x_max": 140.0, "y_max": 40.0},
                                  "obstacles": obstacles,
                                  "landmarks": [{"id": i, "position": [float(x), float(y)], "class": "tower",
                                                 "cluster": c} for i, ((x, y), c) in enumerate(lms)]},
         "path_types": [{"name": "A", "clusters": [0, 1]}],
         "navigation": {"collision_probability": eps, "plan_iterations": 1500}}
    if detection:
        d["detection"] = detection
    return Scenario.from_dict(d)


@pytest.fixture(scope="module")
def gap():
    sc = gap_world()
    return sc, np.asarray(nv.plan_safe_path(sc, "A").path)


def _recheck(scenario, path, k, expected: bool = False):
    """The certificate's two conditions, recomputed from propagate_belief
    with the robust camera (or, ``expected``, the vehicle's own)."""
    kw = C.mission_inputs(scenario, path)
    prof = propagate_belief(path, **kw) if expected else propagate_belief(path, **robust_sight(), **kw)
    room = (np.asarray(prof.clearance) - kw["vehicle_radius"] - kw["margin"] - k * np.asarray(prof.sigma_toward))
    return prof, room


def test_blind_gap_is_not_certified_as_given_and_landmarks_certify_it(gap):
    sc, path = gap
    cert = C.certify_path(sc, "A", path)
    eps = sc.navigation.collision_probability
    # k = Φ⁻¹(1 − ε/N), the guard's risk-budget k
    from scipy.stats import norm
    assert cert.k == pytest.approx(norm.ppf(1 - eps / cert.exposures), rel=1e-9)
    # as given: the gap (x in [80, 90]) is passed with sigma too large for its clearance
    assert not cert.given.certified
    prof, room = _recheck(sc, path, cert.k)
    bad = np.asarray(prof.positions)[room <= 0]
    assert len(bad) and (bad[:, 0] >= 77.0).all() and (bad[:, 0] <= 93.0).all()   # at the gap
    assert (np.asarray(prof.landmarks)[room <= 0] < sc.detection.min_landmarks).all()   # blind there
    # proposed: a fix's worth of landmarks, and the path passes
    assert cert.status == C.NEEDS_LANDMARKS and cert.n_added == sc.detection.min_landmarks
    # landmarks keep the planning clearance p from the whole path (not only from the stretch)
    from safenav import _core
    assert (_core.distance_to_route(path, cert.added) > sc.navigation.planning_clearance).all()
    placed = C.with_landmarks(sc, cert.added)
    prof2, room2 = _recheck(placed, path, cert.k)
    assert (room2 > 0).all() and prof2.collision_probability <= eps
    assert prof2.sigma.max() < prof.sigma.max()
    # fewer cannot give a fix at all (min_landmarks = 3 are needed in view)
    for drop in range(cert.n_added):
        fewer = C.with_landmarks(sc, np.delete(cert.added, drop, axis=0))
        assert not C.check_profile(_recheck(fewer, path, cert.k)[0], cert.k, eps, 1.0, 1.0).certified


def test_proposed_scenario_loads_and_runs(gap, tmp_path, capsys):
    sc, path = gap
    certs, proposed = C.certify_paths(sc, {"A": path})
    assert proposed is not None and len(proposed.world.landmarks) == len(sc.world.landmarks) + certs[0].n_added
    f = save_scenario(proposed, tmp_path / "proposed.toml")
    loaded = load_scenario(f)
    assert loaded.world.landmark_array().shape == proposed.world.landmark_array().shape
    # the loaded scenario certifies the same path as given
    again = C.certify_path(loaded, "A", path)
    assert again.status == C.CERTIFIED and again.n_added == 0
    # and a tiny navigation run on it arrives
    r = nv.make_navigator(loaded, path, record=False, max_steps=3000).run(0)
    assert r.outcome_name == "arrived", r.outcome_name


def test_wide_gap_is_certified_as_given():
    sc = gap_world(half=8.0)
    path = np.asarray(nv.plan_safe_path(sc, "A").path)
    cert = C.certify_path(sc, "A", path)
    assert cert.status == C.CERTIFIED and cert.n_added == 0 and cert.given.certified
    assert cert.given.collision_probability <= sc.navigation.collision_probability and cert.given.min_room > 0
    # the check is the robust camera's; the expected belief (the vehicle's camera) sits beside it, never worse
    robust, _ = _recheck(sc, path, cert.k)
    expected, room = _recheck(sc, path, cert.k, expected=True)
    np.testing.assert_array_equal(cert.given.profile.sigma, robust.sigma)
    e = cert.given.expected
    assert e is not None and e.certified and e.expected is None
    np.testing.assert_array_equal(e.profile.sigma, expected.sigma)
    assert e.min_room == pytest.approx(room.min()) and e.min_room >= cert.given.min_room
    assert e.sigma_max <= cert.given.sigma_max and e.collision_probability <= cert.given.collision_probability
    assert cert.to_dict()["as_given"]["expected"]["sigma_max_m"] == e.sigma_max


def test_start_inside_an_obstacles_k_sigma_zone_cannot_be_certified():
    # a boulder 2.02 m from the start: 0.02 m beyond vehicle radius + margin (2 m),
    # less than k times the sigma of a fix (k > 4, sigma > 0.01 m)
    boulder = {"type": "circle", "center": [5.0, 24.52], "radius": 2.5}
    sc = gap_world(half=8.0, extra_obstacles=[boulder])
    path = np.asarray(nv.plan_safe_path(sc, "A").path)
    cert = C.certify_path(sc, "A", path)
    assert cert.status == C.CANNOT and cert.n_added == 0
    assert "at the start" in cert.reason and "k-σ zone" in cert.reason
    assert cert.given.failing[0]
    prof = cert.given.profile            # 0.02 m beyond r + margin, less than k times a fix's sigma there
    assert 0 < prof.clearance[0] - 2.0 < cert.k * prof.sigma_toward[0]


def test_no_path_is_reported(tmp_path, capsys):
    # a gap narrower than vehicle radius + margin on each side: RAw-RRT* finds no path
    f = save_scenario(gap_world(half=1.5), tmp_path / "narrow.toml")
    out = tmp_path / "plan"
    assert cli.main(["plan", "--scenario", str(f), "--out", str(out), "--iterations", "300"]) == 0
    assert "A: CANNOT BE CERTIFIED" in capsys.readouterr().out
    (c,) = json.loads((out / "certificate.json").read_text())["paths"]
    assert c["status"] == C.CANNOT and c["reason"].startswith("no path") and c["k"] is None


def test_cover_count_is_the_brute_force_minimum():
    # one landmark gives a fix (min_landmarks = 1), a 9 m, 60° placement
    # camera: a straight blind 8 m stretch needs more than one landmark
    sc = gap_world(half=8.0, max_range_m=10.0, min_landmarks=1)
    route = np.array([[30.0, 20.0], [38.0, 20.0]])
    res = C.cover_stretch(sc, route, 1, spacing=2.0)
    assert res.covered
    cam = C.placement_camera(sc)
    allowed = np.setdiff1d(np.arange(len(res.candidates)), res.too_close)   # farther than p from the route
    assert np.isin(res.indices, allowed).all()
    cand = res.candidates[allowed]

    def covers(subset) -> bool:
        return P.check_coverage(route, cand[list(subset)], cam, k=1, corners=True).min_count >= 1

    assert covers(np.searchsorted(allowed, res.indices))
    assert 2 <= res.count <= 3
    for n in range(1, res.count):        # no smaller subset of the same candidates covers the stretch
        assert not any(covers(s) for s in itertools.combinations(range(len(cand)), n))


def test_plan_command_writes_the_certificate(tmp_path, capsys):
    sc = gap_world()
    f = save_scenario(sc, tmp_path / "gap.toml")
    out = tmp_path / "plan"
    assert cli.main(["plan", "--scenario", str(f), "--out", str(out), "--iterations", "1500"]) == 0
    text = capsys.readouterr().out
    assert "A: NEEDS LANDMARKS (3 landmark(s))" in text
    cert = json.loads((out / "certificate.json").read_text())
    assert cert["paths"][0]["status"] == C.NEEDS_LANDMARKS and cert["proposed_scenario"] == "proposed_scenario.toml"
    assert cert["paths"][0]["as_given"]["sigma_max_m"] > cert["paths"][0]["with_landmarks"]["sigma_max_m"]
    assert "| A | needs landmarks |" in (out / "certificate.md").read_text()
    proposed = load_scenario(out / "proposed_scenario.toml")
    assert len(proposed.world.landmarks) == len(sc.world.landmarks) + 3
    assert cli.main(["verify", str(out)]) == 0
    # safenav run accepts the proposed scenario (a one-trial sweep)
    assert cli.main(["run", "--scenario", str(out / "proposed_scenario.toml"), "--trials", "1", "--methods",
                     "centroid", "--filters", "ekf", "--out", str(tmp_path / "run"), "--quiet"]) == 0
    assert "0 of 1 trials collided" in capsys.readouterr().out
    assert cli.main(["plan", "--scenario", str(f), "--out", str(out), "--landmark-spacing", "0"]) == 2


def test_belief_planner_path_or_fallback(gap):
    sc, path = gap
    # the only way is the blind gap: no path meets k there, so the RAw-RRT* path gets the landmarks
    # (and is then replanned with them: test_replanning_after_proposed_landmarks)
    (c,), proposed = C.certify_paths(sc, {"A": path}, planner="belief")
    assert "belief planner: INFEASIBLE" in c.reason and np.array_equal(c.proposed_for, path)
    assert c.status == C.NEEDS_LANDMARKS and proposed is not None
    # a wide gap: the belief planner's own path, certified as given
    wide = gap_world(half=8.0)
    (w,), none = C.certify_paths(wide, {"A": np.asarray(nv.plan_safe_path(wide, "A").path)}, planner="belief")
    assert w.planner == "belief (RRBT)" and w.status == C.CERTIFIED and none is None


def test_bad_settings_are_refused(gap):
    sc, path = gap
    with pytest.raises(ValueError, match="spacing = 0"):
        C.certify_path(sc, "A", path, spacing=0)
    with pytest.raises(ValueError, match="rounds = -1"):
        C.certify_path(sc, "A", path, rounds=-1)


def test_cover_stretch_takes_a_route_with_repeated_points():
    sc = gap_world(half=8.0, max_range_m=10.0, min_landmarks=1)
    route = np.array([[30.0, 20.0], [34.0, 20.0], [34.0, 20.0], [38.0, 20.0]])   # as planners may return
    res = C.cover_stretch(sc, route, 1, spacing=2.0)
    assert res.covered and res.count == C.cover_stretch(sc, route[[0, 3]], 1, spacing=2.0).count


def test_replanning_after_proposed_landmarks(gap, tmp_path, capsys):
    sc, path = gap
    eps = sc.navigation.collision_probability
    (c,), proposed = C.certify_paths(sc, {"A": path}, planner="belief")
    # the landmarks were proposed for the RAw-RRT* path (the belief planner found none as given) ...
    assert c.status == C.NEEDS_LANDMARKS and c.n_added == sc.detection.min_landmarks
    assert np.array_equal(c.proposed_for, path) and not c.given.certified
    # ... and the belief planner replanned on the scenario with them: a path of its own, certified there
    assert c.planner == "belief (RRBT), replanned" and "the replanned path certified" in c.reason
    assert not np.array_equal(c.path, path)
    assert np.allclose(c.path[0], path[0]) and np.allclose(c.path[-1], path[-1])
    assert len(proposed.world.landmarks) == len(sc.world.landmarks) + c.n_added
    prof, room = _recheck(C.with_landmarks(sc, c.added), c.path, c.k)     # recomputed from the belief
    assert (room > 0).all() and prof.collision_probability <= eps
    assert c.final.collision_probability == pytest.approx(prof.collision_probability, abs=1e-15)
    from scipy.stats import norm                                         # k of the replanned path's exposures
    assert c.k == pytest.approx(norm.ppf(1 - eps / c.exposures), rel=1e-9)
    d = c.to_dict()
    assert d["replanned"] and np.allclose(d["proposed_for_path"], path.round(4))
    assert "the landmarks were proposed for" in "\n".join(certify_report.report_lines([c]))


def test_replanning_that_fails_keeps_the_path(gap, monkeypatch):
    sc, path = gap
    first = C.certify_path(sc, "A", path)
    assert first.status == C.NEEDS_LANDMARKS
    # the belief planner on the scenario without the landmarks: it truly finds no path through the blind gap
    real = C.plan_belief_path
    monkeypatch.setattr(C, "plan_belief_path", lambda placed, raw, k, guides=(): real(sc, raw, k, guides=guides))
    kept = C.replan_with_landmarks(sc, first, path)
    assert kept is first and kept.proposed_for is None and np.array_equal(kept.path, path)
    assert "replanning with them: INFEASIBLE" in kept.reason and "the path kept" in kept.reason


def test_plan_command_replans_with_the_belief_planner(tmp_path, capsys):
    f = save_scenario(gap_world(), tmp_path / "gap.toml")
    out = tmp_path / "plan"
    assert cli.main(["plan", "--scenario", str(f), "--out", str(out), "--iterations", "1500",
                     "--planner", "belief"]) == 0
    assert "A: NEEDS LANDMARKS (3 landmark(s)); belief (RRBT), replanned path" in capsys.readouterr().out
    (c,) = json.loads((out / "certificate.json").read_text())["paths"]
    assert c["replanned"] and c["with_landmarks"]["certified"] and c["proposed_for_path"] != c["path"]
    proposed = load_scenario(out / "proposed_scenario.toml")
    again = C.certify_path(proposed, "A", np.asarray(c["path"]), propose=False)
    assert again.status == C.CERTIFIED


def test_a_path_that_looks_back_is_certified_along_the_controllers_runs():
    """World 23's P1, planned without the turn limit, drives 16 m from a
    blind start and doubles back 1.1 m to look at the landmarks behind it:
    the belief along the path turns the camera with the legs and credits
    that fix; the controllers aim lookahead metres ahead and never turn to
    it.  The path passes both checks on its own; along each method's
    nominal run the collision probability exceeds ε, so it is not certified
    as given, and the landmarks proposed where the runs fail certify it.
    With the turn limit the planned path is certified as given, runs
    included."""
    from safenav.generate import generate_scenario

    sc = generate_scenario(23)
    eps = sc.navigation.collision_probability
    raw = np.asarray(C.plan_or_none(sc, "P1").path)
    k, _ = C.risk_k(sc, raw)
    looks_back = np.asarray(C.plan_belief_path(sc, raw, k, max_turn=np.pi, turn_window=0.0).path)
    cert = C.certify_path(sc, "P1", looks_back, propose=False)
    c = cert.given
    for own in (c, c.expected):
        assert own.collision_probability <= eps and own.min_room > 0
    assert cert.status == C.CANNOT and cert.reason.startswith("along ")
    assert set(c.along) == {"chull", "centroid"}
    for method, run in c.along.items():
        assert not run.certified and run.collision_probability > eps
        np.testing.assert_array_equal(run.profile.positions, C.nominal_trajectory(sc, looks_back, method)[:, :2])
    assert cert.to_dict()["as_given"]["along_nominal"]["chull"]["collision_probability"] > eps
    assert "along chull's nominal run" in "\n".join(certify_report.report_lines([cert]))
    placed = C.certify_path(sc, "P1", looks_back)
    assert placed.status == C.NEEDS_LANDMARKS and placed.n_added > 0
    assert all(run.certified for run in placed.final.along.values())
    limited = C.certify_path(sc, "P1", C.plan_belief_path(sc, raw, k).path, propose=False)
    assert limited.status == C.CERTIFIED
    assert all(run.collision_probability <= eps for run in limited.given.along.values())


def test_the_runs_expected_belief_stratifies_the_deviation_along_the_path():
    """Along a method's nominal run the expected belief stratifies the
    deviation along the path too (NOMINAL_DEVIATION: the controller turns
    where the estimate is): its profile is propagate_belief_along's with
    deviation_along, 3³ strata at the start against the lateral rule's 3×3,
    and the certificate's own check (the robust camera) has no mixture."""
    from safenav.scenario import default_scenario

    sc = default_scenario()
    path = np.asarray(C.plan_or_none(sc, "P3").path)
    inputs = C.mission_inputs(sc, path)
    run = C.check_nominal(sc, path, 3.0, methods=("chull",), inputs=inputs)["chull"]
    x = C.nominal_trajectory(sc, path, "chull")
    kw = {key: v for key, v in inputs.items() if key != "speed"}
    along = propagate_belief_along(x, deviation_along=True, **kw)
    lateral = propagate_belief_along(x, deviation_along=False, **kw)
    np.testing.assert_array_equal(run.expected.profile.covariance, along.covariance)
    assert (np.asarray(along.strata_weight)[0] > 0).sum() == 27
    assert (np.asarray(lateral.strata_weight)[0] > 0).sum() == 9
    assert np.asarray(run.profile.strata_weight).size == 0

"""The guard's graded speed and its recoveries (docs/safety.md, "The guard").

* A blind gap — two boulders whose gap is narrower than the k-σ disc, no
  landmark in view anywhere near — made the guard hold until the step limit.
  Now a hold that cannot halve σ is stuck: the guard backs up along the track
  it drove (or spins, with no track) and then gives up with the outcome
  ``blocked`` and its reason, long before the step limit.  The old behaviour
  (a hold that never times out) is run beside it, so the check can fail.
* The graded speed law keeps the way ahead clear: the one-exposure collision
  probability Q((d − buffer)/σ) of the control sent stays within the budget's
  Q(k) = ε/N, with d the clearance of the BMM rollout computed here by brute
  force, while the method's own control would exceed it.
* The time penalty of our loop over the papers' loop on the default world
  stays small where it was largest (P2, SafeNav-Centroid: +26 % before).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

import safenav
from safenav import _core, runner
from safenav import guidance as gd
from safenav import navigation as nv
from safenav import planning as P
from safenav.motion import Bmm, BmmParams

#: Two boulders 50 m down an 80 m straight path; the free gap between them is
#: 1.2 m wide, so k·σ + buffer must stay under 0.6 m (σ < 0.08 m at k ≈ 4).
GAP = [(50.0, 1.6, 1.0), (50.0, -1.6, 1.0)]
#: Landmarks behind the start: none is ever in the camera's view going forward.
BLIND = [(-10.0, 5.0), (-10.0, -5.0), (-12.0, 0.0)]
#: Landmarks just ahead of the start: fixes for the first metres, then none.
AT_START = [(12.0, 6.0), (12.0, -6.0), (14.0, 7.0)]


def _gap_navigator(marks, *, recover: bool = True, record: bool = False):
    p = _core.NavigationProblem()
    p.path = np.array([(0.0, 0.0), (80.0, 0.0)])
    p.zones = _core.RiskZones()
    p.map = P.make_map(lower=(-20, -40), upper=(120, 40), circles=GAP)
    p.bmm = BmmParams()
    s = _core.NavigationSettings()
    s.replan = False
    s.record = record
    if not recover:
        s.guard.hold_timeout = 1e4   # the old guard: a hold never ends by itself
    se = _core.SensorSettings()
    se.landmarks = np.asarray(marks, float)
    return _core.Navigator(p, s, se)


def test_a_blind_gap_ends_blocked_with_its_reason_instead_of_holding_to_the_step_limit():
    seeds = list(range(4))
    old = _gap_navigator(BLIND, recover=False).run_many(seeds)
    assert set(nv.OUTCOMES[o] for o in old["outcome"]) == {"step_limit"}
    new_nav = _gap_navigator(BLIND)
    new = new_nav.run_many(seeds)
    assert set(nv.OUTCOMES[o] for o in new["outcome"]) == {"blocked"}
    # Early: travel to the gap, then max_recoveries stuck holds of hold_timeout and spins of 2π/m.
    g = new_nav.settings.guard
    bmm = new_nav.problem.bmm
    stuck = (g.max_recoveries + 1) * g.hold_timeout + g.max_recoveries * 2 * np.pi / bmm.max_heading_rate
    assert np.max(new["steps"]) < (50.0 / 2.0 + stuck + 10.0) / bmm.dt < new_nav.max_steps / 2
    assert (np.asarray(new["guard_recover"]) > 0).all()
    for reason in new["reason"]:
        assert reason.startswith("blocked at (") and "no landmark can be seen from here" in reason
        assert f"{g.max_recoveries} recoveries did not help" in reason
    assert (np.asarray(new["min_clearance"]) > 0).all()


def test_a_stuck_hold_backs_up_along_the_track_to_where_it_had_fixes():
    nav = _gap_navigator(AT_START, record=True)
    r = nav.run(0)
    assert r.outcome_name == "blocked" and r.guard_recover > 0 and r.metrics["min_clearance"] > 0
    x = np.asarray(r.truth)[:, 0]
    mouth = int(np.argmax(x > 45.0))                       # it reached the gap's mouth
    assert x[mouth] > 45.0
    back = mouth + int(np.argmin(x[mouth:]))
    assert x[back] < 45.0 - 3.0                            # and backed up along its way in
    # Backing up, the camera faced the landmarks again: a fix arrived (σ halved) where
    # none had since the start.
    fixed = ~np.isnan(np.asarray(r.measured)[:, 0])
    assert not fixed[int(np.argmax(x > 20.0)):mouth].any() and fixed[mouth:back + 2].any()
    sd = np.asarray(r.position_std)
    assert sd[back + 1] < 0.5 * sd[mouth]


def test_without_recoveries_the_old_hold_lasts_to_the_step_limit_or_drifts_into_the_gap():
    # The hold's truth random-walks with the BMM's process noise; holding for ever is no safe harbour.
    seeds = list(range(3))
    old = _gap_navigator(AT_START, recover=False).run_many(seeds)
    new = _gap_navigator(AT_START).run_many(seeds)
    assert np.mean(new["steps"]) < np.mean(old["steps"])
    assert set(nv.OUTCOMES[o] for o in new["outcome"]) == {"blocked"}
    assert (np.asarray(old["guard_hold"]) > 1000).all()


# --------------------------------------------------------------------------- the graded speed law


def _rollout_clearance(bmm, x, u, horizon, circle):
    """Brute force: the BMM arc of u held for `horizon`, then braking to a stop,
    sampled every step and along the stopping distance; distance to the circle."""
    cx, cy, r = circle
    pts = [np.asarray(x[:2])]
    xi = np.asarray(x, float)
    for _ in range(int(np.ceil(horizon / bmm.params.dt))):
        xi = bmm.predict(xi, u)
        pts.append(xi[:2].copy())
    stop = xi[:2] + xi[2] ** 2 / (2 * bmm.params.deceleration) * np.array([np.cos(xi[3]), np.sin(xi[3])])
    pts += list(np.linspace(xi[:2], stop, 50))
    pts = np.asarray(pts)
    return float(np.min(np.hypot(pts[:, 0] - cx, pts[:, 1] - cy)) - r)


def test_slowing_keeps_the_exposure_probability_within_the_budget():
    circle = (23.5, 0.3, 0.5)                          # 3 m ahead, just off the path
    p = _core.NavigationProblem()
    p.path = np.array([(0.0, 0.0), (60.0, 0.0)])
    p.zones = _core.RiskZones()
    p.map = P.make_map(lower=(-20, -40), upper=(120, 40), circles=[circle])
    p.bmm = BmmParams()
    s = _core.NavigationSettings()
    s.replan = False
    g = gd.Guidance(p, s, gd.localizer_settings(), np.zeros((0, 2)), [], 0)
    k, sigma = g.guard_k, 0.05
    x0 = np.array([20.0, 0.0, 2.0, 0.0])
    g.localizer.initialize(0.0, x0, np.diag([sigma ** 2, sigma ** 2, 0.01, 0.001]))
    c = g.command(0.0)
    assert gd.event_names(c.events) == ["guard_slow"] and 0.0 < c.speed < 2.0
    bmm = Bmm(p.bmm)
    buffer = s.guard.buffer
    d_sent = _rollout_clearance(bmm, x0, np.array([c.speed, c.heading_change]), s.guard.horizon, circle)
    d_method = _rollout_clearance(bmm, x0, np.array([2.0, c.heading_change]), s.guard.horizon, circle)
    budget = norm.sf(k)                                # ε/N: this exposure's share of the mission's budget
    assert norm.sf((d_sent - buffer) / c.position_std) <= budget
    assert norm.sf((d_method - buffer) / c.position_std) > budget
    assert c.clearance == pytest.approx(d_sent, abs=0.02)
    assert c.guard_margin >= 0


def test_dead_reckoning_does_not_slow_in_the_margin_band_and_fixes_do():
    circle = (24.0, 3.2, 0.5)                          # 2.7 m beside the path, 4 m ahead
    p = _core.NavigationProblem()
    p.path = np.array([(0.0, 0.0), (60.0, 0.0)])
    p.zones = _core.RiskZones()
    p.map = P.make_map(lower=(-20, -40), upper=(120, 40), circles=[circle])
    p.bmm = BmmParams()
    s = _core.NavigationSettings()
    s.replan = False
    s.guard.k = 3.0
    g = gd.Guidance(p, s, gd.localizer_settings(), np.zeros((0, 2)), [], 0)
    g.localizer.initialize(0.0, np.array([20.0, 0.0, 2.0, 0.0]), np.diag([0.3844, 0.3844, 0.01, 0.001]))
    first = g.command(0.0)                              # no measurement yet: dead reckoning
    assert 0.0 <= first.guard_margin < s.guard.slow_distance
    assert gd.event_names(first.events) == [] and first.speed == 2.0
    g.fix(0.0, 20.0, 0.0, 4.0 * np.eye(2))              # a weak fix: σ shrinks from 0.62 to 0.59 m
    fixed = g.command(0.0)
    assert fixed.position_std == pytest.approx(np.sqrt(0.3844 * 4.0 / 4.3844), rel=1e-6)
    assert gd.event_names(fixed.events) == ["guard_slow"] and 0.5 <= fixed.speed < 2.0
    assert fixed.guard_margin > first.guard_margin >= 0.0   # slower: a shorter way ahead


# --------------------------------------------------------------------------- the time penalty


def test_the_time_penalty_on_the_default_worlds_worst_cell_stays_small():
    sc = safenav.default_scenario()
    path = nv.plan_safe_path(sc, "P2", paper=True).path
    seeds = [int(s) for s in runner.trial_seeds(sc.seeds.trials, 1, 12)]
    steps = {}
    for loop in ("paper", "ours"):
        d = nv.make_navigator(sc, path, method="centroid", record=False, paper=loop == "paper").run_many(seeds)
        assert set(nv.OUTCOMES[o] for o in d["outcome"]) == {"arrived"}
        steps[loop] = float(np.mean(d["steps"]))
    assert steps["ours"] / steps["paper"] - 1 < 0.10   # +26 % before the graded speed law

"""The guard's k from the mission's collision-risk budget (docs/safety.md,
"The guard's k"): k = Φ⁻¹(1 − ε/N) for a budget ε over N exposures, checked
against SciPy's normal quantile; N counted along the path against a brute
force over circles; the scenario's ``collision_probability`` and ``guard_k``
(0 = from the budget, > 0 wins) through to the guidance that runs."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import norm

import safenav
from safenav import _core
from safenav import guidance as gd
from safenav import navigation as nv
from safenav import planning as P
from safenav.motion import BmmParams
from safenav.scenario import ScenarioError, load_scenario, save_scenario


@pytest.mark.parametrize("eps", [1e-12, 1e-9, 1e-6, 1e-4, 1e-2, 0.1, 0.3, 0.5, 0.9])
@pytest.mark.parametrize("n", [1.0, 2.0, 17.0, 1000.0, 1e6])
def test_k_is_the_normal_quantile_of_the_budget_per_exposure(eps, n):
    assert gd.guard_k_for_risk(eps, n) == pytest.approx(norm.isf(eps / n), rel=1e-12, abs=1e-12)


def test_the_union_bound_over_the_exposures_meets_the_budget():
    # N one-sided tails Q(k) add up to exactly ε: the budget is spent, not exceeded.
    for eps, n in ((1e-4, 300.0), (1e-6, 5000.0), (0.05, 3.0)):
        assert n * norm.sf(gd.guard_k_for_risk(eps, n)) == pytest.approx(eps, rel=1e-10)


def test_k_grows_as_the_budget_shrinks_and_the_exposures_grow():
    eps = np.logspace(-12, -1, 23)
    ks = [gd.guard_k_for_risk(e, 500.0) for e in eps]
    assert all(a > b for a, b in zip(ks, ks[1:]))
    ns = np.logspace(0, 7, 15)
    ks = [gd.guard_k_for_risk(1e-4, n) for n in ns]
    assert all(a < b for a, b in zip(ks, ks[1:]))
    assert gd.guard_k_for_risk(1e-4, 1.0) == pytest.approx(3.719016485, abs=1e-9)


@pytest.mark.parametrize("eps", [0.0, -1e-3, 1.0, 1.5, math.nan, math.inf])
def test_a_bad_budget_names_collision_probability(eps):
    with pytest.raises(ValueError, match="collision_probability"):
        gd.guard_k_for_risk(eps, 10.0)
    s = _core.NavigationSettings()
    if not math.isnan(eps):
        with pytest.raises(ValueError, match="collision_probability"):
            s.set_param("collision_probability", eps)
    s.collision_probability = eps
    with pytest.raises(ValueError, match="settings.collision_probability"):
        s.validate()


@pytest.mark.parametrize("n", [0.0, 0.5, -3.0, math.nan, math.inf])
def test_bad_exposures_are_refused(n):
    with pytest.raises(ValueError, match="exposures"):
        gd.guard_k_for_risk(1e-4, n)


# --------------------------------------------------------------------------- N along a path

CIRCLES = [(20.0, 6.0, 1.0), (45.0, -4.0, 2.0), (70.0, 30.0, 3.0)]


def _brute_near_steps(path_end, reach, step):
    s = np.arange(0.0, path_end + 1e-12, step)
    pts = np.c_[s, np.zeros_like(s)]
    d = np.min([np.hypot(pts[:, 0] - cx, pts[:, 1] - cy) - r for cx, cy, r in CIRCLES], axis=0)
    return int(np.count_nonzero(d <= reach))


@pytest.mark.parametrize("reach, step", [(8.25, 0.1), (3.0, 0.1), (5.0, 0.37), (2.5, 0.1)])
def test_exposures_count_the_steps_near_an_obstacle(reach, step):
    corridor = _core.Corridor(np.array([(0.0, 0.0), (100.0, 0.0)]), _core.RiskZones())
    checker = _core.ObstacleChecker(P.make_map(lower=(-20, -40), upper=(120, 40), circles=CIRCLES))
    near = _brute_near_steps(100.0, reach, step)
    assert near > 1
    # One exposure per step: the steps near an obstacle.  The walk skips open ground in
    # whole steps; the arc length accumulates in floating point, so a sample may fall on
    # the other side of the reach.
    assert abs(_core.path_exposures(corridor, checker, reach, step, step) - near) <= 1
    # One exposure per exposure_length: that near arc length over it, rounded up.
    for length in (2.0, 7.5):
        n = _core.path_exposures(corridor, checker, reach, length, step)
        assert math.ceil((near - 1) * step / length - 1e-9) <= n <= math.ceil((near + 1) * step / length)


def test_a_path_far_from_everything_has_one_exposure():
    corridor = _core.Corridor(np.array([(0.0, 0.0), (100.0, 0.0)]), _core.RiskZones())
    checker = _core.ObstacleChecker(P.make_map(lower=(-20, -40), upper=(120, 40), circles=[(50.0, 35.0, 1.0)]))
    assert _core.path_exposures(corridor, checker, 8.25, 2.0, 0.1) == 1.0
    with pytest.raises(ValueError, match="step"):
        _core.path_exposures(corridor, checker, 8.25, 2.0, 0.0)
    with pytest.raises(ValueError, match="exposure_length"):
        _core.path_exposures(corridor, checker, 8.25, 0.05, 0.1)
    with pytest.raises(ValueError, match="reach"):
        _core.path_exposures(corridor, checker, math.nan, 2.0, 0.1)


def _guidance(k=0.0, eps=1e-4):
    p = _core.NavigationProblem()
    p.path = np.array([(0.0, 0.0), (100.0, 0.0)])
    p.zones = _core.RiskZones()
    p.map = P.make_map(lower=(-20, -40), upper=(120, 40), circles=CIRCLES)
    p.bmm = BmmParams()
    s = _core.NavigationSettings()
    s.guard.k = k
    s.collision_probability = eps
    return gd.Guidance(p, s, gd.localizer_settings(), np.zeros((0, 2)), [], 0), p, s


def test_guidance_takes_k_from_the_budget_and_the_path_unless_k_is_given():
    g, p, s = _guidance()
    # N: the arc length within the corridor limit plus the buffer of an obstacle, in steps of v·Δt,
    # per guard horizon at cruise speed (2 m/s · 1 s).
    reach = p.zones.half_width + s.corridor_margin + s.guard.buffer
    assert g.guard_exposures == _core.path_exposures(_core.Corridor(p.path, p.zones),
                                                     _core.ObstacleChecker(p.map), reach, 2.0 * 1.0, 2.0 * 0.05)
    assert g.guard_exposures == math.ceil(_brute_near_steps(100.0, reach, 0.1) * 0.1 / 2.0 - 1e-9)
    assert g.guard_k == pytest.approx(norm.isf(1e-4 / g.guard_exposures), rel=1e-12)
    assert g.settings.guard.k == g.guard_k                       # the settings carry the k in use
    assert g.fresh(3).guard_k == g.guard_k
    assert _guidance(eps=1e-2)[0].guard_k < g.guard_k < _guidance(eps=1e-6)[0].guard_k
    assert _guidance(k=3.0)[0].guard_k == 3.0                   # an explicit k wins


# --------------------------------------------------------------------------- the scenario

def test_the_scenario_carries_the_budget_and_an_explicit_k(tmp_path):
    sc = safenav.default_scenario()
    assert sc.navigation.collision_probability == 1e-4 and sc.navigation.guard_k == 0.0
    sc2 = replace(sc, navigation=replace(sc.navigation, collision_probability=1e-3, guard_k=3.5))
    back = load_scenario(save_scenario(sc2, tmp_path / "s.toml"))
    assert back == sc2 and back.navigation.collision_probability == 1e-3 and back.navigation.guard_k == 3.5
    with pytest.raises(ScenarioError, match="collision_probability = 0.5"):
        replace(sc.navigation, collision_probability=0.5)
    with pytest.raises(ScenarioError, match="collision_probability = 0"):
        replace(sc.navigation, collision_probability=0.0)


def test_the_scenario_budget_reaches_the_guidance():
    sc = safenav.default_scenario()
    safe = nv.plan_safe_path(sc, "P3").path
    g = gd.make_guidance(sc, safe)
    assert g.guard_k == pytest.approx(norm.isf(1e-4 / g.guard_exposures), rel=1e-12)
    assert 1 < g.guard_exposures and 3.72 < g.guard_k < 5.5
    loose = gd.make_guidance(replace(sc, navigation=replace(sc.navigation, collision_probability=1e-2)), safe)
    assert loose.guard_exposures == g.guard_exposures and loose.guard_k < g.guard_k
    fixed = gd.make_guidance(replace(sc, navigation=replace(sc.navigation, guard_k=3.0)), safe)
    assert fixed.guard_k == 3.0

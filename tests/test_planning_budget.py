"""Every planning call honours its ``max_time`` whatever the input's scale:
the map, the central path and the end points from millimetres to 10¹² m,
and a central path far from the map (a hostile input that once made a replan
ignore its budget)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from safenav import planning as P

BUDGET = 0.3   # [s]
SLACK = 2.0    # [s] set-up, the last iteration and the result's checks


def _walled(scale: float):
    """A 40 × 20 field (times ``scale``) whose goal (32, 10) is walled in: no
    plan can reach it, so each run uses its whole budget."""
    box = [np.array([(28, 4), (36, 4), (36, 5), (28, 5)]), np.array([(28, 15), (36, 15), (36, 16), (28, 16)]),
           np.array([(28, 4), (29, 4), (29, 16), (28, 16)]), np.array([(35, 4), (36, 4), (36, 16), (35, 16)])]
    return P.make_map(upper=(40 * scale, 20 * scale), polygons=[b * scale for b in box])


def _timed(call):
    t = time.perf_counter()
    result = call()
    return result, time.perf_counter() - t


@pytest.mark.parametrize("informed", [False, True])
@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e7, 1e12])
def test_plan_and_replan_stop_at_max_time_at_any_scale(scale, informed):
    central = np.array([(2.0, 10.0), (32.0, 10.0)]) * scale
    prob = P.PlanningProblem(map=_walled(scale), start=central[0], goal=central[1], central_path=central)
    # The step settings have physical limits (range <= 1e6 m, resolution <= 1e3 m): at 1e7 m and up
    # a motion is checked in up to 10^10 steps, which the budget must still stop.
    kw = dict(max_iterations=10**6, max_time=BUDGET, range=min(4.0 * scale, 1e6), resolution=min(0.5 * scale, 1e3),
              beta=1.0, informed_sampling=informed)
    r, dt = _timed(lambda: P.plan(prob, **kw))
    assert r.status == P.PlanStatus.NO_PATH and dt < BUDGET + SLACK, (scale, dt)
    r, dt = _timed(lambda: P.replan(prob, central[0], goal=central[1], corridor_bias=0.5, **kw))
    assert r.status == P.PlanStatus.NO_PATH and dt < BUDGET + SLACK, (scale, dt)


@pytest.mark.parametrize("far", [1e7, 1e10, 1e15])
@pytest.mark.parametrize("corridor_bias", [0.0, 0.5])
def test_replan_with_a_central_path_far_from_the_map_keeps_its_budget(far, corridor_bias):
    central = np.array([(2.0, 10.0), (20.0, 15.0), (far, far)])
    prob = P.PlanningProblem(map=_walled(1.0), start=(2, 10), goal=(32, 10), central_path=central)
    r, dt = _timed(lambda: P.replan(prob, (2, 10), goal=(32, 10), max_iterations=10**6, max_time=BUDGET,
                                    corridor_bias=corridor_bias, range=4.0))
    assert r.status == P.PlanStatus.NO_PATH and dt < BUDGET + SLACK, (far, dt)


@pytest.mark.parametrize("scale", [1.0, 1e7, 1e12])
def test_plan_belief_stops_at_max_time_at_any_scale(scale):
    """The belief planner's max_time bounds its roadmap and its search.  The goal is walled in and
    the guide path (the central one) runs into it: at 10¹² m the guide is cut into 6·10¹² pieces of
    guide_spacing (more than an int holds), which only the budget stops.  A budget that has passed
    before the roadmap is built stops it at once, with the reason."""
    from test_belief import sensors

    central = np.array([(2.0, 10.0), (32.0, 10.0)]) * scale
    se = sensors(np.array([(10.0, 19.0), (20.0, 19.0)]) * scale, fov=np.deg2rad(85))
    kw = dict(sensors=se, guide_paths=[central], samples=2000, max_expansions=10**9, seed=1)
    r, dt = _timed(lambda: P.plan_belief(_walled(scale), central[0], central[1], max_time=BUDGET, **kw))
    assert not r.success and dt < BUDGET + SLACK, (scale, dt, r.detail)
    if scale == 1e12:
        assert r.status == P.BeliefPlanStatus.BUDGET and "max_time" in r.detail, r.detail
    r = P.plan_belief(_walled(scale), central[0], central[1], max_time=1e-9, **kw)
    assert r.status == P.BeliefPlanStatus.BUDGET and "max_time = 1e-09 s ran out building the roadmap" in r.detail

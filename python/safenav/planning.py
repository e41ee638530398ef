"""RAw-RRT*: risk-aware RRT* [SafeNav eqs. 15–19, SafeNav-ext Alg. 3], on OMPL.

The cost of a path is ``C_total = alpha * C_length + beta * C_risk`` (eqs. 16,
19).  ``C_length`` is the path length (eq. 15); ``C_risk`` is the weighted
risk score WRS (eq. 18) of the deviation from the central path (eq. 17),
integrated along the path (trapezoid rule on sub-steps of at most
``resolution`` metres), the way OMPL's ``StateCostIntegralObjective``
integrates a state cost along each motion.  ``beta = 0`` is plain RRT*.

Same ``seed`` and ``max_iterations`` give the same path (the budget counts
iterations, not seconds).

Example::

    from safenav import planning
    m = planning.make_map(upper=(50, 50), circles=[(25, 25, 5)])
    prob = planning.PlanningProblem(map=m, start=(5, 25), goal=(45, 25),
                                    central_path=[(5, 25), (45, 25)])
    res = planning.plan(prob, alpha=1.0, beta=1.0, max_iterations=2000, seed=1)
    res.status, res.path, res.cost.length, res.cost.risk, res.cost.total
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from . import _core
from .validation import as_array

CircleObstacle = _core.CircleObstacle
#: Repeated collision queries against one map: ``ObstacleChecker(map).segment_free(a, b)``.
ObstacleChecker = _core.ObstacleChecker
PlanningMap = _core.PlanningMap
PlanningProblem = _core.PlanningProblem
PlannerSettings = _core.PlannerSettings
PlanStatus = _core.PlanStatus
PlanResult = _core.PlanResult
PathCost = _core.PathCost

__all__ = [
    "CircleObstacle", "ObstacleChecker", "PlanningMap", "PlanningProblem", "PlannerSettings", "PlanStatus", "PlanResult", "PathCost",
    "make_map", "plan", "replan", "point_ahead", "point_is_free", "segment_is_free", "path_is_free", "path_cost",
]


def _pt(name, p) -> np.ndarray:
    return as_array(name, p, (2,))


def _settings(settings: PlannerSettings | None, kwargs: dict) -> PlannerSettings:
    if settings is not None and kwargs:
        raise ValueError(f"give either settings or keyword settings, not both (got {sorted(kwargs)})")
    return settings if settings is not None else PlannerSettings(**kwargs)


def make_map(lower=(0.0, 0.0), upper=(200.0, 200.0), circles: Iterable = (), polygons: Iterable = (),
             clearance: float = 0.0) -> PlanningMap:
    """A field with obstacles.  ``circles``: ``CircleObstacle`` or ``(cx, cy, r)``;
    ``polygons``: ``(N, 2)`` vertex arrays (simple polygons, N >= 3)."""
    cs = []
    for i, c in enumerate(circles):
        if isinstance(c, CircleObstacle):
            cs.append(c)
            continue
        a = as_array(f"circles[{i}]", c, (3,))
        cs.append(CircleObstacle(a[:2], float(a[2])))
    ps = [as_array(f"polygons[{i}]", p, (None, 2)) for i, p in enumerate(polygons)]
    return PlanningMap(lower=_pt("lower", lower), upper=_pt("upper", upper), circles=cs, polygons=ps,
                       clearance=float(clearance))


def map_from_world(world, clearance: float = 0.0) -> PlanningMap:
    """The planning map of a :class:`safenav.World`: its field and obstacles
    (hazards carry risk, not collision, and are not obstacles)."""
    lower, upper = world.field.bounds
    return make_map(lower, upper, circles=world.circle_array(), polygons=world.polygon_arrays(),
                    clearance=clearance)


def plan(problem: PlanningProblem, settings: PlannerSettings | None = None, **kwargs) -> PlanResult:
    """RAw-RRT* from ``problem.start`` to ``problem.goal``.  Settings as a
    ``PlannerSettings`` or as keywords (``alpha``, ``beta``, ``range``,
    ``goal_bias``, ``max_iterations``, ``max_time``, ``seed``, ``resolution``,
    ``smooth``, ``stay_in_corridor``, ``allow_approximate``, ``goal_tolerance``,
    ``corridor_bias``)."""
    return _core.plan(problem, _settings(settings, kwargs))


def replan(problem: PlanningProblem, position, lookahead: float | None = None, goal=None,
           settings: PlannerSettings | None = None, **kwargs) -> PlanResult:
    """Replan for [SafeNav-ext Alg. 4 l. 9] (= [SafeNav-conf Alg. 3 l. 7]): from ``position`` to the point
    ``lookahead`` metres ahead on the central path (slid forward past any
    obstacle), or to an explicit ``goal``."""
    s = _settings(settings, kwargs)
    pos = _pt("position", position)
    if (lookahead is None) == (goal is None):
        raise ValueError("give exactly one of lookahead and goal")
    if goal is not None:
        return _core.replan_to(problem, pos, _pt("goal", goal), s)
    return _core.replan(problem, pos, float(lookahead), s)


def point_ahead(path, position, distance: float) -> np.ndarray:
    """Point ``distance`` metres of arc length ahead of ``position``'s projection on ``path``."""
    return _core.point_ahead(as_array("path", path, (None, 2)), _pt("position", position), float(distance))


def point_is_free(map: PlanningMap, point) -> bool:
    return _core.point_is_free(map, _pt("point", point))


def segment_is_free(map: PlanningMap, a, b) -> bool:
    """Whether segment a–b stays inside the field and clear of every obstacle (exact test)."""
    return _core.segment_is_free(map, _pt("a", a), _pt("b", b))


def path_is_free(map: PlanningMap, path) -> bool:
    return _core.path_is_free(map, as_array("path", path, (None, 2)))


def path_cost(path, problem: PlanningProblem, settings: PlannerSettings | None = None, **kwargs) -> PathCost:
    """Length, risk and ``alpha * length + beta * risk`` of ``path`` (eq. 19)."""
    return _core.path_cost(as_array("path", path, (None, 2)), problem, _settings(settings, kwargs))

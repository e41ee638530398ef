"""Belief-aware planning (ours; the SafeNav papers plan blind to localization).

:func:`propagate_belief` predicts how the localization covariance will evolve
along a path, with the filter's own models (LQG-MP, van den Berg et al. 2011):
each step the EKF's predict ``P = F P F^T + G Sigma_eps G^T`` [SafeNav eq. 11]
and its Joseph-form update [SafeNav eqs. 12–14] with every measurement the
sensors are expected to make (maximum-likelihood observations): a LanBLoc fix
when ``min_landmarks`` are in view (``FixModel.PROFILE``), or a range to each
landmark in view (``FixModel.RANGES``), and the IMU.  "In view" is
``SensorSettings.landmarks_in_view``: range, field of view, occlusion.  It
returns the sigma profile and the path's collision probability, each stage
conditioned on no collision before (Patil, van den Berg & Alterovitz 2012).

:func:`plan_belief` searches a probabilistic roadmap over beliefs
(cost, covariance) with RRBT's partial-order pruning (Bry & Roy 2011) under
the chance constraint ``clearance >= k_sigma * sigma + vehicle_radius +
margin`` at every stage.  RAw-RRT* (:func:`safenav.planning.plan`) stays the
paper's planner and the default.  See docs/belief_planning.md.

Example::

    from safenav import planning
    res = planning.plan_belief(m, start=(5, 20), goal=(55, 20), sensors=se, k_sigma=3.0)
    res.path, res.sigma, res.collision_probability
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _core
from .validation import as_array

BeliefSettings = _core.BeliefSettings
BeliefPlannerSettings = _core.BeliefPlannerSettings
BeliefProblem = _core.BeliefProblem
BeliefProfile = _core.BeliefProfile
BeliefPlanStatus = _core.BeliefPlanStatus
BeliefPlanResult = _core.BeliefPlanResult
start_covariance = _core.start_covariance
#: Monte Carlo of the profile's linear error model and half-planes (the reference of Patil's estimate).
collision_monte_carlo = _core.collision_monte_carlo

__all__ = ["BeliefSettings", "BeliefPlannerSettings", "BeliefProblem", "BeliefProfile", "BeliefPlanStatus",
           "BeliefPlanResult", "BeliefPlan", "start_covariance", "collision_monte_carlo", "propagate_belief",
           "plan_belief"]

# Keyword names of plan_belief / propagate_belief -> declared parameter names.
_BELIEF_KEYS = {"speed": "speed", "step": "step", "bearing_std": "bearing_std",
                "vehicle_radius": "inflation.vehicle_radius", "margin": "inflation.margin"}


def _belief_settings(kwargs: dict, settings=None) -> BeliefSettings:
    s = settings if settings is not None else BeliefSettings()
    for key, value in kwargs.items():
        if key not in _BELIEF_KEYS:
            raise TypeError(f"unknown belief setting {key!r} (have: {sorted(_BELIEF_KEYS)})")
        s.set_param(_BELIEF_KEYS[key], float(value))
    s.validate()
    return s


def _planner_settings(kwargs: dict, settings=None) -> BeliefPlannerSettings:
    s = settings if settings is not None else BeliefPlannerSettings()
    for key, value in kwargs.items():
        if key == "seed":
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise ValueError(f"seed = {value!r}: must be an integer >= 0")
            s.seed = int(value)
        elif key in _BELIEF_KEYS:
            s.set_param("belief." + _BELIEF_KEYS[key], float(value))
        else:
            if key not in {p.name for p in BeliefPlannerSettings.params()}:
                raise TypeError(f"unknown planner setting {key!r}")
            s.set_param(key, value.item() if isinstance(value, np.generic) else value)
    s.validate()
    return s


def _start_cov(start_cov, sensors, map, start, toward) -> np.ndarray:
    """The given start covariance, or the navigation loop's prior at ``start``
    heading toward ``toward`` (:func:`start_covariance`)."""
    if start_cov is None:
        d = np.asarray(toward, dtype=float) - start
        return start_covariance(sensors, map, start, float(np.arctan2(d[1], d[0])))
    return as_array("start_cov", start_cov, (4, 4))


def propagate_belief(path, *, sensors, map, bmm=None, start_cov=None, settings: BeliefSettings | None = None,
                     **kwargs) -> BeliefProfile:
    """The belief along ``path`` ((N, 2), start first) at ``speed``:
    ``.sigma`` (sqrt of the largest eigenvalue of P_xy per stage), ``.cov_xy``,
    ``.covariance`` (4x4 per stage), ``.landmarks`` in view,
    ``.collision_probability`` (Patil et al.), ``.union_bound``.

    ``sensors``: a ``SensorSettings``; ``map``: a ``PlanningMap`` (obstacles
    occlude and are what the vehicle may hit); ``bmm``: ``BmmParams``
    (default: the core's); ``start_cov``: 4x4 (default: the navigation loop's
    prior at the start, heading along the first leg: :func:`start_covariance`).
    Keywords: ``speed``, ``step`` (belief step [s], 0 = the BMM's dt),
    ``bearing_std``, ``vehicle_radius``, ``margin``."""
    p = as_array("path", path, (None, 2))
    bmm = bmm if bmm is not None else _core.BmmParams()
    s = _belief_settings(kwargs, settings)
    k = int(np.argmax(np.any(p[1:] != p[0], axis=1))) + 1 if len(p) > 1 else 0
    P0 = _start_cov(start_cov, sensors, map, p[0], p[min(k, len(p) - 1)])
    return _core.propagate_belief(p, bmm, sensors, map, P0, s)


@dataclass(frozen=True)
class BeliefPlan:
    """A belief-aware plan: ``path`` ((N, 2); empty unless ``success``), its
    ``sigma`` profile and predicted ``collision_probability``, the
    ``status`` with its ``detail``, the full ``profile`` and the core ``result``."""
    status: BeliefPlanStatus
    success: bool
    detail: str
    path: np.ndarray
    sigma: np.ndarray
    collision_probability: float
    profile: BeliefProfile | None
    result: BeliefPlanResult


def plan_belief(map, start, goal, *, sensors, bmm=None, start_cov=None, guide_paths=(),
                settings: BeliefPlannerSettings | None = None, **kwargs) -> BeliefPlan:
    """Belief-aware roadmap search from ``start`` to ``goal`` (see the module
    docstring).  Keywords: ``k_sigma`` (default 3), ``alpha``,
    ``sigma_weight``, ``samples``, ``neighbours``, ``max_edge``,
    ``guide_spacing``, ``seed``, ``max_beliefs``, ``dominance_tolerance``,
    ``max_expansions``, and the belief's ``speed``, ``step``, ``bearing_std``,
    ``vehicle_radius``, ``margin``.  ``guide_paths``: polylines whose vertices
    and edges join the roadmap (a RAw-RRT* path, say).  ``start_cov``
    defaults to the navigation loop's prior heading toward the goal
    (:func:`start_covariance`).  An infeasible problem
    returns ``success = False`` with the status (INFEASIBLE, NO_PATH, BUDGET)
    and why in ``detail``."""
    pb = BeliefProblem()
    pb.map = map
    pb.start = as_array("start", start, (2,))
    pb.goal = as_array("goal", goal, (2,))
    pb.bmm = bmm if bmm is not None else _core.BmmParams()
    pb.sensors = sensors
    pb.start_cov = _start_cov(start_cov, sensors, map, pb.start, pb.goal)
    pb.guide_paths = [as_array(f"guide_paths[{i}]", g, (None, 2)) for i, g in enumerate(guide_paths)]
    res = _core.plan_belief(pb, _planner_settings(kwargs, settings))
    prof = res.profile if res.success else None
    return BeliefPlan(status=res.status, success=res.success, detail=res.detail, path=np.asarray(res.path),
                      sigma=np.asarray(prof.sigma) if prof else np.zeros(0),
                      collision_probability=float(prof.collision_probability) if prof else float("nan"),
                      profile=prof, result=res)


"""SafeNav navigation: SafeNav-CHull (Algorithm 1), SafeNav-Centroid
(Algorithm 2) and the safe path navigation loop with RAw-RRT* replanning
(Algorithm 4 of the extended paper; Algorithm 3 of the conference version).

The trial loop runs in the C++ core (:class:`Navigator`), which drives the
online :class:`~safenav.guidance.Guidance` that a vehicle program would tick:
each step guidance chooses a control from the filter's estimate, checks the
path ahead for obstacles and replans a detour when it is blocked; the
simulator moves the true vehicle
(BMM with process noise and terrain), measures (LanBLoc position fix when at
least ``min_landmarks`` landmarks are within range and the camera's field of
view, plus IMU speed and heading) and updates the EKF or PF.  A trial ends at
the destination or with an explicit outcome: ``collision``,
``left_corridor``, ``step_limit``, ``lost_localization``, ``no_path`` or
``blocked`` (the guard gave up on a hold it could not end, after backing up
along its track or spinning; the reason says why).

Metrics [SafeNav-ext eqs. 20–23] compare the *estimated* trajectory with the safe
path it was told to follow, the paper's "ground truth trajectory".  That path
has no time stamps, so ext eq. 21's point-wise pairing Ŷ(t)-Y(t) is undefined;
we pair each estimate with its nearest point of the safe path (``path_ade`` =
mean cross-track distance; our reading).  Pairing by equal arc-length
fractions was tried and rejected: a 1 % longer trajectory then shows a metre
of "error" mid-way that is only a phase shift.  ``goal_fde`` is the distance
of the final estimate to the destination, % error the path-length error
(ext eq. 23).  ``truth_ade``/``truth_fde`` compare the estimate with the true
vehicle instead (localization error).  Each name says what it compares
against; :func:`safenav.metrics.ade` takes its reference as an argument.

Example::

    import safenav
    from safenav import navigation
    sc = safenav.default_scenario()
    safe = navigation.plan_safe_path(sc, "P1")
    nav = navigation.make_navigator(sc, safe.path, method="centroid", filter="ekf")
    trial = nav.run(seed=1)
    trial.outcome_name, trial.metrics["path_ade"], trial.estimate[:5]
"""

from __future__ import annotations

import numpy as np

from . import _core
from .validation import as_array, choice, integer
from .geometry import PathSegments
from .guidance import (FILTERS, METHODS, GuardSettings, NavigationMethod, NavigationProblem, NavigationSettings,
                       navigation_setup)
from .measurement import PositionNoise
from .planning import PlanningProblem, PlannerSettings, map_from_world, plan

Navigator = _core.Navigator
SensorSettings = _core.SensorSettings
TrialOutcome = _core.TrialOutcome
ChullAction = _core.ChullAction
TrialResult = _core.TrialResult
LandmarkFaults = _core.LandmarkFaults
FixModel = _core.FixModel

__all__ = [
    "Navigator", "NavigationMethod", "NavigationProblem", "NavigationSettings", "SensorSettings",
    "PositionNoise", "TrialOutcome", "ChullAction", "TrialResult", "GuardSettings", "LandmarkFaults", "FixModel", "SOURCES", "METHODS", "FILTERS",
    "OUTCOMES", "position_source", "with_faults", "plan_safe_path", "navigation_setup", "make_navigator", "chull_control", "centroid_control",
]

#: Outcome codes (``TrialOutcome`` values) to names, in code order, as the core names them.
OUTCOMES = tuple(_core.outcome_name(TrialOutcome(code)) for code in range(len(TrialOutcome.__members__)))


#: The named position sources (:class:`PositionNoise`, declared once in the
#: core): LanBLoc with the paper's RMSE, and the paper's three comparison
#: methods as *emulations*, error profiles of our choosing (``emulated`` is
#: set and the label says so; DESIGN.md decision 8).  Read-only use: take a
#: fresh copy to change with :func:`position_source`.
SOURCES: dict[str, PositionNoise] = {name: PositionNoise.named(name) for name in PositionNoise.names()}


def position_source(name: str) -> PositionNoise:
    """A fresh copy of the named :data:`SOURCES` profile; a clear error for an unknown one."""
    if name not in SOURCES:
        raise ValueError(f"source = {name!r}: unknown position source (have: {sorted(SOURCES)}; "
                         f"the camera loop is passed as a callback to Navigator.run)")
    return PositionNoise.named(name)


def with_faults(scenario, dropout: float = 0.0, outlier: float = 0.0, misassociation: float = 0.0):
    """``scenario`` with landmark-level faults (ours): each landmark observation
    is missed, an outlier (±``noise.outlier_magnitude``) or another landmark's id
    with these probabilities.  Fixes then come from single landmark ranges
    through LanBLoc's trilateration (``noise.fix_model = 'ranges'``), the only
    model with observations to corrupt.  See :class:`safenav.LandmarkFaults`."""
    from dataclasses import replace

    return replace(scenario, noise=replace(scenario.noise, fix_model="ranges", dropout_probability=float(dropout),
                                           outlier_probability=float(outlier),
                                           misassociation_probability=float(misassociation)))


def plan_safe_path(scenario, path_type: str, *, seed: int | None = None, iterations: int | None = None,
                   paper: bool = False):
    """Plan the safe path of a path type with RAw-RRT* [SafeNav-ext Alg. 3]: from the
    start cluster's centroid to the destination's, around the obstacles (kept
    ``navigation.planning_clearance`` away; hazards of risk >= ``planner.forbidden_risk``
    are obstacles too), with the ground-truth polyline through the
    clusters as the central path of the risk term, and (ours) the hazard term
    ``planner.hazard_weight`` (5 by default).  ``paper``: the papers' path,
    whose cost has no hazard term (hazard_weight 0).  Returns the
    :class:`~safenav.planning.PlanResult`; raises ``RuntimeError`` when no path
    is found within the budget."""
    nav = scenario.navigation
    gt = scenario.path_polyline(path_type)
    world_map = map_from_world(scenario.world, clearance=nav.planning_clearance,
                               forbidden_risk=scenario.planner.forbidden_risk)
    problem = PlanningProblem(map=world_map, start=gt[0], goal=gt[-1], central_path=gt, zones=scenario.risk_zones())
    settings = scenario.planner.apply(PlannerSettings(
        max_iterations=int(iterations or nav.plan_iterations), corridor_bias=nav.corridor_bias, smooth=True,
        seed=int(scenario.seeds.planner if seed is None else seed)))
    if paper:
        settings.hazard_weight = 0.0
    result = plan(problem, settings)
    if not result.success:
        raise RuntimeError(f"path type {path_type}: RAw-RRT* found no safe path ({result.status}, "
                           f"{result.iterations} iterations); raise navigation.plan_iterations")
    return result


def make_navigator(scenario, safe_path, *, method: str = "centroid", filter: str = "ekf",
                   source: str = "lanbloc", n_particles: int = 500, position_every: int = 1,
                   replan: bool = True, record: bool = True, world_map=None, max_steps: int | None = None,
                   planner_seed: int | None = None, paper: bool = False) -> Navigator:
    """A :class:`Navigator` for ``safe_path`` in ``scenario``'s world.

    ``method``: ``"chull"`` (Algorithm 1) or ``"centroid"`` (Algorithm 2);
    ``filter``: ``"ekf"`` or ``"pf"``; ``source``: a :data:`SOURCES` name.
    ``world_map`` overrides the true obstacles (a ``PlanningMap``), e.g. to
    add obstacles the safe path was not planned around.  ``paper``: the
    papers' loop whatever the scenario says — no guard, no gate, no
    occlusion (obstacles hide no landmark, as in the papers)."""
    problem, s = navigation_setup(scenario, safe_path, method=method, world_map=world_map, max_steps=max_steps,
                                  replan=replan, planner_seed=planner_seed, paper=paper)
    s.filter.type = choice("filter", filter, FILTERS)
    s.filter.n_particles = integer("n_particles", n_particles)
    s.record = bool(record)

    se = SensorSettings()
    se.position = position_source(source)
    se.landmarks = scenario.world.landmark_array()[:, :2]
    se.landmark_ids = [lm.id for lm in scenario.world.landmarks]   # the localizer names them as the world does
    se.field_of_view = np.deg2rad(scenario.camera.field_of_view_deg)
    scenario.detection.apply(se)
    if paper:  # the papers' loop reproduces the trials run before occlusion existed, bit for bit
        se.occlusion = False
    se.position_every = integer("position_every", position_every)
    scenario.noise.apply(se)
    if source == "lanbloc":
        se.position.std = np.asarray(scenario.noise.lanbloc_std, dtype=float)
    else:  # an emulated baseline is its error profile: no landmark ranges to corrupt
        se.fix_model = _core.FixModel.PROFILE
        se.faults = _core.LandmarkFaults()
    return Navigator(problem, s, se)


def centroid_control(segments, estimate, cruise_speed: float) -> np.ndarray:
    """Algorithm 2's control (v, Δθ) toward the nearest sub-segment centroid ahead."""
    seg = segments.core if isinstance(segments, PathSegments) else segments
    return _core.centroid_control(seg, as_array("estimate", estimate, (4,)), float(cruise_speed))


def chull_control(segments, bmm, estimate, cruise_speed: float, lookahead: float, step_back_speed: float,
                  obstacles=None):
    """Algorithm 1's decision: ``ChullDecision`` with ``control``, ``segment``,
    ``action`` (a ``ChullAction``: KEEP, CORRECTIVE or STEP_BACK) and ``predicted``.
    ``obstacles`` (an ``ObstacleChecker``) shortens the look-ahead while the
    chord to it crosses an obstacle."""
    seg = segments.core if isinstance(segments, PathSegments) else segments
    return _core.chull_control(seg, bmm, as_array("estimate", estimate, (4,)), float(cruise_speed),
                               float(lookahead), float(step_back_speed), obstacles)

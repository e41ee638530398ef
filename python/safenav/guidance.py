"""The online API: a vehicle's own loop ticks :class:`Localizer` (LanBLoc-BMM,
[SafeNav eqs. 10–14] over the BMM of eqs. 3–9) and :class:`Guidance`
(SafeNav-CHull [SafeNav Alg. 1] or SafeNav-Centroid [SafeNav Alg. 2] with the
obstacle check and RAw-RRT* detours of [SafeNav-ext Alg. 4]) with timestamped
inputs, and asks for its control.  Both live in the C++ core; the simulator
(:class:`~safenav.navigation.Navigator`) drives the same :class:`Guidance`,
so there is one navigation loop.

Inputs (each returns an :class:`InputResult` with ``status`` — applied,
rejected by its χ² gate, late, buffered before initialization — and the NIS):

* ``motion(t, speed, heading_change)`` or ``odometry(t, distance, heading_change)``
  over the interval since the previous motion input (the step length comes
  from the timestamps);
* ``observe(t, id, range=…, bearing=…, range_std=…, bearing_std=…)`` — one
  landmark, gated on its own (on by default: ``LocalizerSettings().filter.gate_probability`` = 0.99);
* ``fix(t, x, y, R)`` — a LanBLoc position fix; ``speed_heading(t, v, θ, σ_v, σ_θ)`` — the IMU.

A measurement older than the filter's time by at most
``LocalizerSettings.max_delay`` (0.5 s) is applied at its own time (the
inputs since are applied again after it: the estimate equals that of the
inputs in time order); an older one is *late* and is not applied.  One ahead
of the filter is applied after predicting to its time with the last motion
input.  Without :meth:`Localizer.initialize` the localizer starts from the
data (ranges to ≥ 3 landmarks and the motion of the first metres).

Example::

    import numpy as np, safenav
    from safenav import guidance, navigation
    sc = safenav.default_scenario()
    safe = navigation.plan_safe_path(sc, "P1").path
    g = guidance.make_guidance(sc, safe, method="centroid")
    g.localizer.initialize(0.0, np.r_[safe[0], 0.0, 0.0], np.diag([0.1, 0.1, 0.1, 0.1]) ** 2)
    cmd = g.command(0.0)            # cmd.speed, cmd.heading_change, cmd.status, cmd.events
    g.motion(0.05, cmd.speed, cmd.heading_change)
    # each tick: the vehicle's own measurements, e.g. a range of the world's
    # landmark of id 3 (a gross one is rejected by its gate: the result's status says so)
    r = g.observe(0.05, 3, range=measured_range, range_std=0.1)
"""

from __future__ import annotations

import numpy as np

from . import _core
from .planning import map_from_world
from .validation import as_array, as_seed, choice, integer

Localizer = _core.Localizer
LocalizerSettings = _core.LocalizerSettings
Guidance = _core.Guidance
NavigationMethod = _core.NavigationMethod
NavigationProblem = _core.NavigationProblem
NavigationSettings = _core.NavigationSettings
GuardSettings = _core.GuardSettings
Command = _core.Command
InputResult = _core.InputResult
InputStatus = _core.InputStatus
GuidanceStatus = _core.GuidanceStatus
guard_k_for_risk = _core.guard_k_for_risk

#: Event flags of :attr:`Command.events`, by name.
EVENTS = {
    "detour_planned": _core.EVENT_DETOUR_PLANNED,
    "path_spliced": _core.EVENT_PATH_SPLICED,
    "no_path": _core.EVENT_NO_PATH,
    "lost_localization": _core.EVENT_LOST_LOCALIZATION,
    "arrived": _core.EVENT_ARRIVED,
    "guard_slow": _core.EVENT_GUARD_SLOW,
    "guard_steer": _core.EVENT_GUARD_STEER,
    "guard_hold": _core.EVENT_GUARD_HOLD,
    "stale_input": _core.EVENT_STALE_INPUT,
    "guard_recover": _core.EVENT_GUARD_RECOVER,
    "blocked": _core.EVENT_BLOCKED,
}

__all__ = ["Localizer", "LocalizerSettings", "Guidance", "Command", "InputResult", "InputStatus", "GuidanceStatus",
           "NavigationMethod", "NavigationProblem", "NavigationSettings", "GuardSettings", "METHODS", "FILTERS",
           "EVENTS", "AUGMENTED", "event_names", "guard_k_for_risk", "localizer_settings", "navigation_setup", "make_guidance"]

METHODS = {"chull": NavigationMethod.CHULL, "centroid": NavigationMethod.CENTROID}
FILTERS = {"ekf": _core.FilterType.EKF, "pf": _core.FilterType.PF}


def event_names(events: int) -> list[str]:
    """The names of the flags set in ``events`` (a :attr:`Command.events`)."""
    return [name for name, bit in EVENTS.items() if int(events) & bit]


#: The optional augmented states, by name (``AugmentedStates`` flags; ours, for real ranges).
AUGMENTED = ("range_scale", "heading_rate_bias", "range_bias")


def localizer_settings(*, filter: str = "ekf", bmm=None, gate: float | None = None, n_particles: int = 1000,
                       seed: int = 0, augment=()) -> LocalizerSettings:
    """:class:`LocalizerSettings` for ``filter`` ("ekf" or "pf"); ``gate`` is the
    χ² gate probability of every update (default 0.99; 0 = off); ``augment``
    names augmented states to switch on (:data:`AUGMENTED`: a range scale k,
    a heading-rate bias β, per-landmark range biases b_j; safenav/augmented.hpp)."""
    s = LocalizerSettings()
    s.filter.type = choice("filter", filter, FILTERS)
    s.filter.n_particles = integer("n_particles", n_particles)
    s.filter.seed = as_seed("seed", seed)
    if gate is not None:
        s.set_param("gate_probability", float(gate))
    if bmm is not None:
        s.bmm = bmm
    for name in augment:
        choice("augment", name, dict.fromkeys(AUGMENTED))
        setattr(s.augment, name, True)
    return s


def navigation_setup(scenario, safe_path, *, method: str = "centroid", world_map=None, max_steps: int | None = None,
                     replan: bool = True, planner_seed: int | None = None, paper: bool = False):
    """The ``NavigationProblem`` and ``NavigationSettings`` of ``safe_path`` in
    ``scenario``'s world (shared by :func:`make_navigator` and
    :func:`make_guidance`).  The guard and the gate follow
    ``scenario.navigation`` (on by default); ``paper=True`` turns both off."""
    path = as_array("safe_path", safe_path, (None, 2))
    nav = scenario.navigation
    problem = NavigationProblem()
    problem.path = path
    problem.zones = scenario.risk_zones()
    problem.map = world_map if world_map is not None else map_from_world(
        scenario.world, clearance=nav.planning_clearance, forbidden_risk=scenario.planner.forbidden_risk)
    problem.bmm = scenario.bmm_params()

    s = nav.apply(NavigationSettings())
    s.guard.enabled = nav.guard == "on" and not paper
    s.guard.look_with_camera(float(np.deg2rad(scenario.camera.field_of_view_deg)),  # it looks with the camera
                             float(scenario.detection.max_range_m), int(scenario.detection.min_landmarks),
                             bool(scenario.detection.occlusion) and not paper)
    if paper:
        s.filter.gate_probability = 0.0
    s.method = choice("method", method, METHODS)
    if max_steps is not None:
        s.max_steps = integer("max_steps", max_steps, 0)  # 0: from the path
    s.replan = bool(replan)
    scenario.planner.apply(s.planner)
    s.planner.seed = as_seed("planner_seed", planner_seed or 0)
    return problem, s


def make_guidance(scenario, safe_path, *, method: str = "centroid", filter: str = "ekf", n_particles: int = 500,
                  gate: float | None = None, seed: int = 0, world_map=None) -> Guidance:
    """A :class:`Guidance` along ``safe_path`` in ``scenario``'s world: its
    obstacles (detours), its landmarks (observations name them by the world's
    landmark ids, as the simulator's localizer does) and the scenario's BMM
    and navigation settings (those of :func:`~safenav.navigation.make_navigator`)."""
    problem, settings = navigation_setup(scenario, as_array("safe_path", safe_path, (None, 2)), method=method,
                                         world_map=world_map)
    ls = localizer_settings(filter=filter, bmm=problem.bmm, gate=gate, n_particles=n_particles)
    landmarks = np.ascontiguousarray(scenario.world.landmark_array()[:, :2], dtype=float)
    ids = [int(lm.id) for lm in scenario.world.landmarks]
    return Guidance(problem, settings, ls, landmarks, ids, as_seed("seed", seed))

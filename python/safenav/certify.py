"""Certified missions: check each planned path against the mission's risk
budget, and propose the fewest landmarks that make an uncertified one pass.

A path is **certified** when, with the belief the navigation loop is
predicted to have along it (:func:`safenav.belief.propagate_belief`: the
EKF's predict [SafeNav eq. 11] and update [SafeNav eqs. 12–14] with the
fixes the sensors will make, LQG-MP), both hold, for the belief seen with
the robust camera (:func:`safenav.belief.robust_sight`, the planner's) and
for the expected one (the vehicle's own camera), that is for the worse of
the two:

* the path-level collision probability (Patil, van den Berg & Alterovitz
  2012, ``BeliefProfile.collision_probability``) is at most
  ε = ``navigation.collision_probability``;
* at every stage, clearance − vehicle_radius − margin > k·σ_a, with σ_a the
  position σ toward the nearest obstacle (``BeliefProfile.sigma_toward``,
  the direction of the half-plane bound in docs/safety.md) and
  k = Φ⁻¹(1 − ε/N) (``guard_k_for_risk``), N the path's exposures
  (``path_exposures``, as the guard counts them);

and, along each method's nominal run (:func:`check_nominal`: the belief
along ``Navigator.nominal_trajectory()``, the trajectory the controller
drives, which cuts corners and turns the camera as it turns the vehicle),
the collision probability with either camera is at most ε as well.

Where a path fails, landmarks are proposed along the stretches where it
fails: each run of failing stages (or of stages that carry more than ε/n of
the collision probability) without a fix in view throughout.  On each stretch the
placement paper's cover (:func:`safenav.placement.place_along_path`, the
integer program, with occlusion) keeps a fix's worth of landmarks in view.
The landmarks are added, the belief re-propagated and the path re-checked, a
few rounds at most.  With the belief planner the path is then replanned on
the scenario with the landmarks and the replanned path certified
(:func:`replan_with_landmarks`); where that fails the path is kept.  See
docs/belief_planning.md, "Certified missions".
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from . import console

__all__ = ["PathCertificate", "Check", "NOMINAL_DEVIATION", "mission_inputs", "risk_k", "check_profile",
           "check_nominal", "nominal_trajectory", "blind_stretches", "placement_camera", "cover_stretch",
           "propose_landmarks", "certify_path", "certify_paths", "with_landmarks",
           "plan_or_none", "plan_belief_path", "replan_with_landmarks", "proposed_scenario"]

#: The guidance methods [SafeNav Algs. 1–2] whose nominal trajectories a certificate also checks.
METHODS = ("chull", "centroid")
#: The expected belief along a method's nominal run stratifies the deviation
#: along the path too (``deviation_along``): the controller turns where the
#: estimate is, so the vehicles whose estimate runs ahead turn early
#: (docs/belief_planning.md, "Along the path, with 10 000 trials").  Along a
#: path's legs the turns are instant and the lateral strata are kept.
NOMINAL_DEVIATION = {"deviation_along": True}

#: Statuses of a path's certificate.
CERTIFIED, NEEDS_LANDMARKS, CANNOT = "certified", "needs landmarks", "cannot be certified"


def mission_inputs(scenario, path) -> dict:
    """The keyword arguments of ``propagate_belief`` for ``path`` in
    ``scenario``: its planning ``map`` (hazards of risk ≥ the planner's
    ``forbidden_risk`` are keep-out areas), ``bmm``, the ``sensors`` of its
    navigation loop (as :func:`safenav.navigation.make_navigator` builds
    them), the cruise ``speed``, ``vehicle_radius``, ``margin`` and the
    filter's ``gate_probability``."""
    from . import navigation as nv
    from . import planning as P

    n = scenario.navigation
    navigator = nv.make_navigator(scenario, np.asarray(path, dtype=float), record=False)
    return {"map": P.map_from_world(scenario.world, forbidden_risk=scenario.planner.forbidden_risk),
            "bmm": scenario.bmm_params(), "sensors": navigator.sensors, "speed": float(n.cruise_speed),
            "vehicle_radius": float(n.vehicle_radius), "margin": float(n.clearance_margin),
            "gate_probability": float(n.gate_probability)}


def risk_k(scenario, path) -> tuple[float, float]:
    """(k, N): k = Φ⁻¹(1 − ε/N) of the budget ε = ``navigation.collision_probability``
    and the exposures N of ``path``, counted as the guard counts them
    (docs/safety.md, "The guard's k")."""
    from .guidance import guard_k_for_risk, make_guidance

    n_exp = float(make_guidance(scenario, np.asarray(path, dtype=float)).guard_exposures)
    return float(guard_k_for_risk(scenario.navigation.collision_probability, n_exp)), n_exp


def fix_needs(sensors) -> int:
    """Landmarks in view that give a fix: ``min_landmarks``, at least 3 for
    ``FixModel.RANGES`` (as ``propagate_belief`` counts them)."""
    from . import _core

    m = int(sensors.min_landmarks)
    return max(3, m) if sensors.fix_model == _core.FixModel.RANGES else m


@dataclass
class Check:
    """One path's belief against the certificate's two conditions."""
    certified: bool
    collision_probability: float      #: Patil et al.
    union_bound: float
    sigma_max: float                  #: max √λ_max(P_xy) [m]
    sigma_max_s: float                #: where [m of arc length]
    sigma_max_xy: tuple
    min_room: float                   #: min over stages of clearance − r − margin − k·σ_a [m]
    min_room_s: float
    min_room_xy: tuple
    room: np.ndarray                  #: per stage: clearance − r − margin − k·σ_a [m]
    failing: np.ndarray               #: stages where clearance − r − margin ≤ k·σ_a
    risky: np.ndarray                 #: failing, or p_k > ε / stages
    profile: object = None
    epsilon: float = float("nan")     #: the ε it was checked against
    #: the check of the expected belief (the vehicle's own camera) beside this one (the robust camera's)
    expected: "Check | None" = None
    #: {method: the same checks along that method's nominal trajectory} (:func:`check_nominal`)
    along: dict = field(default_factory=dict)

    def summary(self) -> dict:
        x, y = self.sigma_max_xy
        out = {"certified": self.certified, "collision_probability": self.collision_probability,
               "union_bound": self.union_bound, "sigma_max_m": self.sigma_max,
               "sigma_max_at": {"s_m": self.sigma_max_s, "x": x, "y": y},
               "min_room_m": _finite(self.min_room), "min_room_at": {"s_m": self.min_room_s, "x": self.min_room_xy[0],
                                                             "y": self.min_room_xy[1]},
               "failing_stages": int(self.failing.sum()), "stages": int(len(self.failing))}
        if self.expected is not None:
            out["expected"] = self.expected.summary()
        if self.along:
            out["along_nominal"] = {m: c.summary() for m, c in self.along.items()}
        return out


def _finite(v: float) -> float | None:
    """``v``, or None where it is not finite (JSON has no inf or NaN)."""
    return float(v) if np.isfinite(v) else None


def _arc(points: np.ndarray) -> np.ndarray:
    return np.r_[0.0, np.cumsum(np.hypot(*np.diff(points, axis=0).T))]


def check_profile(prof, k: float, epsilon: float, vehicle_radius: float, margin: float) -> Check:
    """The certificate's two conditions on a ``BeliefProfile``: P(collision) ≤ ε,
    and clearance − vehicle_radius − margin > k·σ_a at every stage."""
    pos = np.asarray(prof.positions)
    s = _arc(pos)
    sigma = np.asarray(prof.sigma)
    room = np.asarray(prof.clearance) - vehicle_radius - margin - k * np.asarray(prof.sigma_toward)
    room = np.where(np.isfinite(room), room, np.inf)
    failing = room <= 0.0
    risky = failing | (np.asarray(prof.stage_probability) > epsilon / len(sigma))
    i, j = int(np.argmax(sigma)), int(np.argmin(room))
    pc = float(prof.collision_probability)
    c = Check(certified=False, collision_probability=pc, epsilon=float(epsilon),
              union_bound=float(prof.union_bound), sigma_max=float(sigma[i]), sigma_max_s=float(s[i]),
              sigma_max_xy=(float(pos[i, 0]), float(pos[i, 1])), min_room=float(room[j]),
              min_room_s=float(s[j]), min_room_xy=(float(pos[j, 0]), float(pos[j, 1])), room=room, failing=failing,
              risky=risky, profile=prof)
    c.certified = _meets(c)
    return c


def blind_stretches(prof, risky: np.ndarray, needs: int, arc=None) -> list[tuple[float, float]]:
    """Arc-length stretches [s0, s1] to cover with landmarks: each run of
    ``risky`` stages that has a stage without a fix in view (fewer than
    ``needs`` landmarks), overlapping ones merged.  A run with a fix in view
    throughout gives none: more landmarks would not add a fix there.
    ``arc``: the stages' arc positions (default: along the profile's own
    positions)."""
    s = _arc(np.asarray(prof.positions)) if arc is None else np.asarray(arc, dtype=float)
    seen = np.asarray(prof.landmarks) >= needs
    out: list[list[float]] = []
    idx = np.flatnonzero(risky)
    for run in (np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1) if len(idx) else []):
        i0, i1 = int(run[0]), int(run[-1])
        if seen[i0:i1 + 1].all():
            continue
        if out and s[i0] <= out[-1][1]:
            out[-1][1] = max(out[-1][1], float(s[i1]))
        else:
            out.append([float(s[i0]), float(s[i1])])
    return [(a, b) for a, b in out]


def _distinct(points: np.ndarray) -> np.ndarray:
    """The polyline without points that repeat the one before (within 1e-9 m)."""
    keep = np.r_[True, np.hypot(*np.diff(points, axis=0).T) > 1e-9]
    return points[keep]


def _cut(path: np.ndarray, s0: float, s1: float, min_length: float = 1.0) -> np.ndarray:
    """The piece of the polyline ``path`` between arc lengths s0 and s1
    (widened to ``min_length`` within the path)."""
    s = _arc(path)
    if s1 - s0 < min_length:
        mid = 0.5 * (s0 + s1)
        s0, s1 = max(0.0, mid - 0.5 * min_length), min(s[-1], mid + 0.5 * min_length)
    at = lambda t: np.array([np.interp(t, s, path[:, 0]), np.interp(t, s, path[:, 1])])  # noqa: E731
    inner = path[(s > s0) & (s < s1)]
    return np.vstack([at(s0), *inner, at(s1)])


def placement_camera(scenario, settings=None):
    """The camera the placement covers with, the robust camera the planner
    and the certificate see with: the vehicle's, narrowed by
    ``sight_fov_margin`` (25°, at least 10° left) and shortened to
    ``sight_range_fraction`` (90 %) of the detection range, for heading and
    cross-track deviations (``BeliefPlannerSettings().belief``, or
    ``settings``; also :func:`safenav.experiments.run.placed_scenario`);
    landmarks keep the planning clearance from the path."""
    import math

    from . import placement as P
    from .belief import BeliefPlannerSettings

    s = settings if settings is not None else BeliefPlannerSettings().belief
    return P.CameraParams(range=s.sight_range_fraction * scenario.detection.max_range_m,
                          angle_deg=max(10.0, scenario.camera.field_of_view_deg - math.degrees(s.sight_fov_margin)),
                          clearance=scenario.navigation.planning_clearance)


def cover_stretch(scenario, route, needs: int, *, spacing: float = 2.0, path=None):
    """The fewest landmarks that keep ``needs`` in view along ``route`` (a
    polyline): the placement paper's cover as an integer program
    (:func:`safenav.placement.place_along_path`, ``method = 'optimal'``,
    exact over the candidates), with :func:`placement_camera`; the world's
    obstacles hide landmarks and no candidate lies inside one.  Candidates on
    a grid of ``spacing`` within the camera's range of ``route``, and farther
    than the camera's clearance p from ``path`` (the whole path ``route`` is
    part of; default ``route``), so that no landmark stands on the path
    beyond the stretch.  Returns the ``PlacementResult`` (best effort where
    no candidate covers a piece)."""
    from . import _core
    from . import placement as P

    world, cam = scenario.world, placement_camera(scenario)
    route = _distinct(np.asarray(route, dtype=float))
    whole = route if path is None else _distinct(np.asarray(path, dtype=float))
    cand = P.candidate_grid(route.min(axis=0), route.max(axis=0), spacing, margin=cam.range)
    cand = cand[(_core.distance_to_route(route, cand) <= cam.range)
                & (_core.distance_to_route(whole, cand) > cam.clearance)]
    return P.place_along_path(route, cam, world=world, candidates=cand, k=needs, method="optimal",
                              allow_uncovered=True, occlusion=bool(world.obstacles))


def propose_landmarks(scenario, path, stretches, needs: int, *, spacing: float = 2.0) -> np.ndarray:
    """(L, 2) new landmark positions: :func:`cover_stretch` on each stretch
    (s0, s1) of ``path``, without repeats or landmarks the scenario has."""
    found: list = []
    for s0, s1 in stretches:
        found.extend(cover_stretch(scenario, _cut(np.asarray(path, dtype=float), s0, s1), needs,
                                   spacing=spacing, path=path).landmarks.tolist())
    have = {tuple(np.round(lm.xy, 6)) for lm in scenario.world.landmarks}
    out, seen = [], set()
    for xy in found:
        key = tuple(np.round(xy, 6))
        if key not in have and key not in seen:
            seen.add(key)
            out.append(xy)
    return np.asarray(out, dtype=float).reshape(-1, 2)


def with_landmarks(scenario, positions, *, name: str | None = None):
    """``scenario`` with landmarks at ``positions`` ((L, 2)) added: class
    ``placed``, one new cluster, ids after the largest one."""
    from .world import Landmark

    w = scenario.world
    next_id = max((lm.id for lm in w.landmarks), default=-1) + 1
    cluster = max(w.cluster_ids, default=-1) + 1
    added = tuple(Landmark(next_id + i, (float(x), float(y)), "placed", cluster)
                  for i, (x, y) in enumerate(np.asarray(positions, dtype=float).reshape(-1, 2)))
    return replace(scenario, world=replace(w, landmarks=w.landmarks + added), name=name or scenario.name)


@dataclass
class PathCertificate:
    """The certificate of one path type."""
    name: str
    status: str                       #: CERTIFIED, NEEDS_LANDMARKS or CANNOT
    reason: str
    planner: str
    path: np.ndarray
    k: float
    exposures: float
    epsilon: float
    given: Check | None = None        #: with the scenario's landmarks
    final: Check | None = None        #: with the proposed landmarks added (NEEDS_LANDMARKS)
    added: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    rounds: int = 0
    #: the path the landmarks were proposed for, when ``path`` was replanned with them (else None)
    proposed_for: np.ndarray | None = None

    @property
    def n_added(self) -> int:
        return int(len(self.added))

    def to_dict(self) -> dict:
        return {"path_type": self.name, "status": self.status, "reason": self.reason, "planner": self.planner,
                "length_m": float(_arc(self.path)[-1]) if len(self.path) else 0.0,
                "epsilon": self.epsilon, "k": _finite(self.k), "exposures": _finite(self.exposures),
                "as_given": self.given.summary() if self.given else None,
                "with_landmarks": self.final.summary() if self.final else None,
                "landmarks_added": self.n_added, "landmarks": self.added.round(4).tolist(), "rounds": self.rounds,
                "path": np.asarray(self.path).round(4).tolist(), "replanned": self.proposed_for is not None,
                "proposed_for_path": (None if self.proposed_for is None else
                                      np.asarray(self.proposed_for).round(4).tolist())}


def _evaluate(scenario, path, k: float, step: float) -> Check:
    """The certificate's check of ``path``: the robust camera's belief
    (:func:`safenav.belief.robust_sight`), with the expected belief's check
    (the vehicle's own camera) in ``.expected`` and each method's nominal
    run in ``.along`` (:func:`check_nominal`).  Certified when both checks of
    the path pass and the collision probability along every method's run,
    with either camera, is at most ε.  The robust camera sees a subset of
    what the vehicle's sees, so its covariance is the larger at every stage
    (the Riccati recursion is monotone) and its check decides in practice;
    the expected one is the σ profile the vehicle will get."""
    from .belief import propagate_belief, robust_sight

    kw = mission_inputs(scenario, path)
    eps, r, m = scenario.navigation.collision_probability, kw["vehicle_radius"], kw["margin"]
    robust = check_profile(propagate_belief(path, step=step, **robust_sight(), **kw), k, eps, r, m)
    robust.expected = check_profile(propagate_belief(path, step=step, **kw), k, eps, r, m)
    robust.along = check_nominal(scenario, path, k, step, inputs=kw)
    robust.certified = _passes(robust) and all(_within(a) for a in robust.along.values())
    return robust


def _meets(c: Check) -> bool:
    """The certificate's two conditions on one belief: P(collision) ≤ ε, and room at every stage."""
    return bool(c.collision_probability <= c.epsilon and not c.failing.any())


def _passes(c: Check) -> bool:
    """Both conditions on the path itself, for both cameras (``c`` the robust camera's check)."""
    return _meets(c) and _meets(c.expected)


def _within(c: Check) -> bool:
    """A method's run: the collision probability with either camera is at most ε."""
    return c.collision_probability <= c.epsilon and c.expected.collision_probability <= c.epsilon


def _deciding(c: Check, path: np.ndarray) -> tuple[Check, str, np.ndarray | None]:
    """The check that makes ``c`` fail: the path's own, else the method's
    run with the largest collision probability; with a label for the reason
    and, for a run, its stages' arc positions along ``path`` (None: the
    path's own stages)."""
    from .belief import arc_position

    if _passes(c):
        method, run = max(((m, a) for m, a in c.along.items() if not _within(a)),
                          key=lambda ma: ma[1].collision_probability)
        return run, f"along {method}'s nominal run: ", arc_position(path, np.asarray(run.profile.positions))
    return c, "", None


def nominal_trajectory(scenario, path, method: str) -> np.ndarray:
    """(N, 4): the states of a vehicle that ``method`` drives along ``path``
    in ``scenario`` without noise (``Navigator.nominal_trajectory``: the
    method's control on the state itself, no guard)."""
    from . import navigation as nv

    navigator = nv.make_navigator(scenario, np.asarray(path, dtype=float), method=method, record=False)
    return np.asarray(navigator.nominal_trajectory())


def check_nominal(scenario, path, k: float, step: float = 0.0, methods=METHODS, inputs=None) -> dict:
    """{method: the certificate's checks (robust camera, with ``.expected``)
    of the belief along ``method``'s nominal trajectory}
    (:func:`safenav.belief.propagate_belief_along`).  The controllers do not
    drive the path's legs: they aim ``lookahead`` metres ahead and cut
    corners, and the camera turns as they turn the vehicle.  A run's
    ``certified`` is its collision probability, with either camera, at most
    ε, which the certificate requires; its room is reported, not required
    (docs/belief_planning.md, "Along the controllers' runs").  ``inputs``:
    :func:`mission_inputs` of ``path``, when the caller has them."""
    from .belief import propagate_belief_along, robust_sight

    kw = mission_inputs(scenario, path) if inputs is None else inputs
    eps, r, m = scenario.navigation.collision_probability, kw["vehicle_radius"], kw["margin"]
    along = {key: v for key, v in kw.items() if key != "speed"}
    out = {}
    for method in methods:
        x = nominal_trajectory(scenario, path, method)
        c = check_profile(propagate_belief_along(x, step=step, **robust_sight(), **along), k, eps, r, m)
        c.expected = check_profile(propagate_belief_along(x, step=step, **NOMINAL_DEVIATION, **along), k, eps, r, m)
        c.certified = _within(c)
        out[method] = c
    return out


def _floor(c: Check, needs: int) -> float:
    """The least σ toward the nearest obstacle at a stage with a fix in view
    on this path (what fixes give here), or 0 when no stage has one."""
    fix = np.asarray(c.profile.landmarks) >= needs
    return float(np.asarray(c.profile.sigma_toward)[fix].min()) if fix.any() else 0.0


def _hopeless(c: Check, k: float, needs: int) -> int | None:
    """A failing stage that landmarks cannot fix: its room beyond vehicle radius
    + margin is below k times what fixes give on this path (:func:`_floor`).
    The worst such stage, or None."""
    free = c.room + k * np.asarray(c.profile.sigma_toward)
    bad = c.failing & (free <= k * _floor(c, needs))
    return int(np.flatnonzero(bad)[np.argmin(c.room[bad])]) if bad.any() else None


def _why(c: Check, k: float, epsilon: float, needs: int, rounds: int, j: int | None = None) -> str:
    """Why a check fails, in words (at stage ``j``, default the one with the least room)."""
    if not c.failing.any():
        return (f"predicted collision probability {c.collision_probability:.3g} > ε = {epsilon:g}" +
                (f" after {rounds} round(s) of placement" if rounds > 0 else
                 "; landmark proposals are off" if rounds < 0 else "; no stretch without a fix to cover"))
    prof = c.profile
    j = int(np.argmin(c.room)) if j is None else j
    pos, s = np.asarray(prof.positions), _arc(np.asarray(prof.positions))
    cl, sig = float(np.asarray(prof.clearance)[j]), float(np.asarray(prof.sigma_toward)[j])
    free = float(c.room[j]) + k * sig                    # clearance − vehicle radius − margin
    lms = int(np.asarray(prof.landmarks)[j])
    where = "the start" if j == 0 else f"s = {s[j]:.1f} m"
    head = f"at {where} ({pos[j, 0]:.2f}, {pos[j, 1]:.2f}): "
    if free <= 0:
        return head + (f"the clearance {cl:.3g} m is within vehicle radius + margin of an obstacle "
                       f"(the path passes a gap narrower than the vehicle needs)")
    need = f"the clearance {cl:.3g} m leaves room for σ ≤ {free / k:.3g} m (k = {k:.3g} for ε = {epsilon:g})"
    floor = _floor(c, needs)
    if floor > 0 and free <= k * floor:
        what = ("the start lies inside an obstacle's k-σ zone: σ at the start is too large even with a fix"
                if j == 0 else "the path runs too close to an obstacle for the σ that fixes give "
                "(a path that keeps farther is needed: --planner belief plans for it)")
        return head + f"{need}, but fixes give σ ≥ {floor:.3g} m on this path; {what}"
    if lms >= needs:
        return head + (f"{need}, but σ = {sig:.3g} m with a fix in view: the fixes since the last blind stretch "
                       f"have not brought σ down that far")
    return head + (f"{need}, but σ = {sig:.3g} m with {lms} landmark(s) in view; " +
                   (f"{rounds} round(s) of placement did not give a fix there" if rounds > 0 else
                    "no candidate landmark location covers it" if rounds == 0 else "landmark proposals are off"))


def certify_path(scenario, name: str, path, *, planner: str = "RAw-RRT*", propose: bool = True,
                 rounds: int = 3, spacing: float = 2.0, step: float = 0.0) -> PathCertificate:
    """Certify ``path`` (the planned path of path type ``name``) in
    ``scenario``; where it fails, propose landmarks (up to ``rounds``
    rounds of :func:`propose_landmarks`, re-propagating after each)."""
    from .validation import as_array

    path = as_array("path", path, (None, 2))
    if isinstance(rounds, bool) or not isinstance(rounds, (int, np.integer)) or rounds < 0:
        raise ValueError(f"rounds = {rounds!r}: must be an integer >= 0")
    if not (isinstance(spacing, (int, float, np.floating)) and np.isfinite(spacing) and spacing > 0):
        raise ValueError(f"spacing = {spacing!r}: must be a finite number of metres > 0")
    eps = float(scenario.navigation.collision_probability)
    k, n_exp = risk_k(scenario, path)
    cert = PathCertificate(name=name, status=CERTIFIED, reason="", planner=planner, path=path, k=k,
                           exposures=n_exp, epsilon=eps)
    cert.given = c = _evaluate(scenario, path, k, step)
    if c.certified:
        cert.reason = "certified with the scenario's landmarks"
        return cert
    needs = fix_needs(mission_inputs(scenario, path)["sensors"])
    current, added = scenario, np.zeros((0, 2))
    for _ in range(rounds if propose else 0):
        f, label, arc = _deciding(c, path)
        j = _hopeless(f, k, needs)
        if j is not None:
            cert.status, cert.final, cert.added = CANNOT, (c if cert.rounds else None), added
            cert.reason = label + _why(f, k, eps, needs, cert.rounds, j)
            return cert
        stretches = blind_stretches(f.profile, f.risky, needs, arc)
        new = propose_landmarks(current, path, stretches, needs, spacing=spacing) if stretches else np.zeros((0, 2))
        if not len(new):
            break
        cert.rounds += 1
        added = np.vstack([added, new])
        current = with_landmarks(current, new)
        c = _evaluate(current, path, k, step)
        if c.certified:
            cert.status, cert.final, cert.added = NEEDS_LANDMARKS, c, added
            cert.reason = f"certified with {len(added)} landmark(s) added in {cert.rounds} round(s)"
            return cert
    cert.status, cert.final, cert.added = CANNOT, (c if cert.rounds else None), added
    f, label, _ = _deciding(c, path)
    cert.reason = label + _why(f, k, eps, needs, cert.rounds if propose else -1)
    return cert


def plan_or_none(scenario, name: str, iterations: int | None = None):
    """The RAw-RRT* plan of path type ``name``
    (:func:`safenav.navigation.plan_safe_path`), or None when it finds no path
    (reported, on standard error, and then in the certificate)."""
    from . import navigation as nv

    try:
        return nv.plan_safe_path(scenario, name, iterations=iterations)
    except RuntimeError as exc:
        console.info(str(exc))
        return None


def plan_belief_path(scenario, raw_path, k: float, *, guides=(), **settings):
    """The belief-aware plan (:func:`safenav.belief.plan_belief`, RRBT) from
    the RAw-RRT* path's start to its goal at k, with that path (and the
    polylines ``guides``) as guide paths in the roadmap; ``settings`` go to
    ``plan_belief`` (``BeliefPlannerSettings`` fields).  Returns the
    ``BeliefPlan``."""
    from .belief import plan_belief

    raw_path = np.asarray(raw_path, dtype=float)
    kw = mission_inputs(scenario, raw_path)
    kw = {"turn_window": float(scenario.navigation.lookahead), **kw, **settings}  # the controllers' lookahead
    return plan_belief(kw.pop("map"), raw_path[0], raw_path[-1],
                       guide_paths=[raw_path, *(np.asarray(g, dtype=float) for g in guides)], k_sigma=max(k, 0.0),
                       seed=int(scenario.seeds.planner), **kw)


def replan_with_landmarks(scenario, cert: PathCertificate, raw_path, *, step: float = 0.0) -> PathCertificate:
    """Replanning after landmarks are proposed: the belief planner
    (:func:`plan_belief_path`, at the k of ``raw_path``) on ``scenario`` with
    ``cert.added``, guided by ``raw_path`` and the path the landmarks were
    proposed for (so the roadmap holds that path), and the replanned path
    certified with them (no further landmarks).  Returns the certificate of
    the replanned path (``proposed_for`` = the old path, ``given`` = the old
    path's check as given) when it is certified, else ``cert`` with the
    reason extended: the old path is kept."""
    placed = with_landmarks(scenario, cert.added)
    k, _ = risk_k(scenario, raw_path)
    bp = plan_belief_path(placed, raw_path, k, guides=[cert.path])
    if not bp.success:
        cert.reason += f"; replanning with them: {bp.status.name} ({bp.detail}), the path kept"
        return cert
    again = certify_path(placed, cert.name, bp.path, planner="belief (RRBT), replanned", propose=False, step=step)
    if again.status != CERTIFIED:
        cert.reason += f"; the path replanned with them is not certified ({again.reason}), the path kept"
        return cert
    return replace(again, status=NEEDS_LANDMARKS, given=cert.given, final=again.given, added=cert.added,
                   rounds=cert.rounds, proposed_for=cert.path,
                   reason=f"{cert.reason}; replanned with them (belief planner), the replanned path certified")


def certify_paths(scenario, raw_paths: dict, *, planner: str = "raw", **kwargs) -> tuple[list, object]:
    """Certify each path type of ``raw_paths`` ({name: RAw-RRT* path, or None
    when it found none}).  ``planner``: ``"raw"`` certifies those paths;
    ``"belief"`` plans each with :func:`plan_belief_path` first and falls
    back to the RAw-RRT* path (for landmarks) when the belief planner finds
    no path that meets k; where landmarks are proposed, it replans with them
    (:func:`replan_with_landmarks`).  Returns (certificates, the proposed scenario with
    every path's landmarks added, or None when none were needed)."""
    certs = []
    for name, raw in raw_paths.items():
        if raw is None:
            certs.append(PathCertificate(name=name, status=CANNOT, reason="no path: RAw-RRT* found none",
                                         planner="RAw-RRT*", path=np.zeros((0, 2)), k=float("nan"),
                                         exposures=float("nan"),
                                         epsilon=float(scenario.navigation.collision_probability)))
            continue
        path, label, note = np.asarray(raw, dtype=float), "RAw-RRT*", ""
        if planner == "belief":
            k, _ = risk_k(scenario, path)
            bp = plan_belief_path(scenario, path, k)
            if bp.success:
                path, label = np.asarray(bp.path), "belief (RRBT)"
            else:
                note = f"belief planner: {bp.status.name} ({bp.detail}); the RAw-RRT* path instead. "
        cert = certify_path(scenario, name, path, planner=label, **kwargs)
        cert.reason = note + cert.reason
        if planner == "belief" and cert.status == NEEDS_LANDMARKS:
            cert = replan_with_landmarks(scenario, cert, np.asarray(raw, dtype=float), step=kwargs.get("step", 0.0))
        certs.append(cert)
    return certs, proposed_scenario(scenario, certs)


def proposed_scenario(scenario, certs: list):
    """``scenario`` with the landmarks of every certificate that needs them
    added (once each), named ``<name>+landmarks``; None when none needs any."""
    added = [xy for c in certs if c.status == NEEDS_LANDMARKS for xy in c.added.tolist()]
    if not added:
        return None
    uniq = np.unique(np.round(np.asarray(added), 6), axis=0)
    return with_landmarks(scenario, uniq, name=f"{scenario.name}+landmarks")

"""Belief-aware planning (ours; the SafeNav papers plan blind to localization).

:func:`propagate_belief` predicts how the localization covariance will evolve
along a path, with the filter's own models (LQG-MP, van den Berg et al. 2011):
each step the EKF's predict ``P = F P F^T + G Sigma_eps G^T`` [SafeNav eq. 11]
and its Joseph-form update [SafeNav eqs. 12–14] with every measurement the
sensors are expected to make (maximum-likelihood observations): a LanBLoc fix
when ``min_landmarks`` are in view (``FixModel.PROFILE``), or a range to each
landmark in view (``FixModel.RANGES``), and the IMU.  "In view" is
``SensorSettings.landmarks_in_view``: range, field of view, occlusion; by
default with the vehicle's own camera (the expected belief), and with a
narrower one in the planner and the certificate (:func:`robust_sight`).  It
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

import warnings
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
           "propagate_belief_along", "plan_belief", "robust_sight", "arc_position", "SigmaCalibration",
           "sigma_calibration", "calibration_edges", "binned_trials", "pool_calibrations", "clopper_pearson"]

# Keyword names of plan_belief / propagate_belief -> declared parameter names.
_BELIEF_KEYS = {"speed": "speed", "step": "step", "bearing_std": "bearing_std",
                "sight_fov_margin": "sight_fov_margin", "sight_range_fraction": "sight_range_fraction",
                "deviation_mixture": "deviation_mixture", "deviation_nodes": "deviation_nodes",
                "deviation_along": "deviation_along", "deviation_split": "deviation_split",
                "deviation_free_strata": "deviation_free_strata",
                "gate_probability": "gate_probability",
                "vehicle_radius": "inflation.vehicle_radius",
                "margin": "inflation.margin"}


def _belief_settings(kwargs: dict, settings=None) -> BeliefSettings:
    s = settings if settings is not None else BeliefSettings()
    for key, value in kwargs.items():
        if key not in _BELIEF_KEYS:
            raise TypeError(f"unknown belief setting {key!r} (have: {sorted(_BELIEF_KEYS)})")
        s.set_param(_BELIEF_KEYS[key], value if isinstance(value, (bool, np.bool_)) else float(value))
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


def _start_cov(start_cov, sensors, map, start, toward, gate_probability: float) -> np.ndarray:
    """The given start covariance, or the navigation loop's prior at ``start``
    heading toward ``toward`` with its gate (:func:`start_covariance`)."""
    if start_cov is None:
        d = np.asarray(toward, dtype=float) - start
        return start_covariance(sensors, map, start, float(np.arctan2(d[1], d[0])), gate_probability)
    return as_array("start_cov", start_cov, (4, 4))


def robust_sight() -> dict:
    """The robust camera, as keywords of :func:`propagate_belief`: the
    ``sight_fov_margin`` and ``sight_range_fraction`` of the planner's belief
    (``BeliefPlannerSettings().belief``: the field of view less 25°, 90 % of
    the detection range, no deviation mixture).  The planner's chance
    constraint and the mission certificate see with it; :func:`propagate_belief`'s default is the
    vehicle's own camera, the expected belief (docs/belief_planning.md,
    "Calibration")."""
    b = BeliefPlannerSettings().belief
    return {"sight_fov_margin": float(b.sight_fov_margin), "sight_range_fraction": float(b.sight_range_fraction),
            "deviation_mixture": bool(b.deviation_mixture)}


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
    ``bearing_std``, ``vehicle_radius``, ``margin``, ``sight_fov_margin``
    and ``sight_range_fraction`` (default 0 and 1: the vehicle's own camera,
    the expected belief; :func:`robust_sight` gives the planner's and the
    certificate's narrower one), ``deviation_mixture`` (default on: the
    expected belief over the vehicle's deviation from the path, its error
    stratified at 3×3 cells of the deviation, or 5×5 or 7×7 with ``deviation_nodes``;
    ``BeliefSettings.deviation_mixture``), ``deviation_along`` (stratify along
    the path too: n³ strata), ``deviation_split`` (default on: a cell is cut
    where the view changes, and a blind stratum along its heading where the
    step's heading noise shows it a fix; off: the Gauss–Hermite nodes),
    ``deviation_free_strata`` (the strata it may hold beyond the rule's,
    1 000: room for every stratum on the missions measured).  With the mixture,
    ``.strata_weight`` (each stratum's weight per stage, (N, S)),
    ``.strata_positions`` and ``.strata_position_cov`` (the mean, (N, 2S),
    and covariance, (N, 3S) as xx, xy, yy, of its vehicles' true positions
    per stage) and ``.strata_msq`` (its mean square position error, (N, S))
    say where its vehicles are and how far off: :func:`sigma_calibration`
    bins them at their own arcs."""
    p = as_array("path", path, (None, 2))
    bmm = bmm if bmm is not None else _core.BmmParams()
    s = _belief_settings(kwargs, settings)
    k = int(np.argmax(np.any(p[1:] != p[0], axis=1))) + 1 if len(p) > 1 else 0
    P0 = _start_cov(start_cov, sensors, map, p[0], p[min(k, len(p) - 1)], s.gate_probability)
    return _core.propagate_belief(p, bmm, sensors, map, P0, s)


def propagate_belief_along(states, *, sensors, map, bmm=None, start_cov=None,
                           settings: BeliefSettings | None = None, **kwargs) -> BeliefProfile:
    """The belief along a trajectory of ``states`` ((N, 4): x, y, v, theta at
    the BMM's dt, start first), e.g. ``Navigator.nominal_trajectory()``: the
    method's own noise-free run, LQG-MP's nominal.  As
    :func:`propagate_belief`, but each step is linearized at the
    trajectory's state and sees along its heading, so the camera turns as
    the controller turns the vehicle.  ``start_cov`` defaults to the loop's
    prior at the first state's position and heading."""
    x = as_array("states", states, (None, 4))
    bmm = bmm if bmm is not None else _core.BmmParams()
    s = _belief_settings(kwargs, settings)
    if len(x) < 2:
        raise ValueError(f"states has {len(x)} rows: a trajectory needs >= 2")
    if start_cov is None:
        P0 = start_covariance(sensors, map, x[0, :2], float(x[0, 3]), s.gate_probability)
    else:
        P0 = as_array("start_cov", start_cov, (4, 4))
    return _core.propagate_belief_along(x, bmm, sensors, map, P0, s)


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
    ``max_expansions``, ``max_time`` (a wall-clock budget [s] of the
    roadmap and the search; 0, the default, is none), ``max_turn`` and
    ``turn_window`` (no more than
    ``max_turn``, default 90°, of turning at a vertex or in all over any
    ``turn_window`` metres, default 5), and the belief's ``speed``,
    ``step``, ``bearing_std``, ``vehicle_radius``, ``margin``.
    ``guide_paths``: polylines whose vertices and edges join the roadmap
    (a RAw-RRT* path, say).  ``start_cov`` defaults to the navigation
    loop's prior heading toward the goal
    (:func:`start_covariance`).  An infeasible problem
    returns ``success = False`` with the status (INFEASIBLE, NO_PATH, BUDGET)
    and why in ``detail``."""
    pb = BeliefProblem()
    pb.map = map
    pb.start = as_array("start", start, (2,))
    pb.goal = as_array("goal", goal, (2,))
    pb.bmm = bmm if bmm is not None else _core.BmmParams()
    pb.sensors = sensors
    ps = _planner_settings(kwargs, settings)
    pb.start_cov = _start_cov(start_cov, sensors, map, pb.start, pb.goal, ps.belief.gate_probability)
    pb.guide_paths = [as_array(f"guide_paths[{i}]", g, (None, 2)) for i, g in enumerate(guide_paths)]
    res = _core.plan_belief(pb, ps)
    prof = res.profile if res.success else None
    return BeliefPlan(status=res.status, success=res.success, detail=res.detail, path=np.asarray(res.path),
                      sigma=np.asarray(prof.sigma) if prof else np.zeros(0),
                      collision_probability=float(prof.collision_probability) if prof else float("nan"),
                      profile=prof, result=res)



# --------------------------------------------------------------------------- calibration against Monte Carlo

def _nearest_legs(q, a, d, dd, legs):
    """(leg, t, squared distance) of the nearest of the legs ``legs[m]``
    (rows ascending) to ``q[m]``: t in [0, 1] along the leg; ties go to the
    earlier leg."""
    al, dl = a[legs], d[legs]
    t = np.clip(np.einsum("mij,mij->mi", q[:, None, :] - al, dl) / dd[legs], 0.0, 1.0)
    gap = q[:, None, :] - (al + t[..., None] * dl)
    sq = np.einsum("mij,mij->mi", gap, gap)
    col = np.argmin(sq, axis=1)
    rows = np.arange(len(q))
    return legs[rows, col], t[rows, col], sq[rows, col]


def arc_position(path, points, *, all_legs: bool = False) -> np.ndarray:
    """The arc length along the polyline ``path`` ((N, 2)) of the nearest
    point of ``path`` to each of ``points`` ((M, 2)); ties go to the earlier
    leg.  ``all_legs`` searches every leg of a long polyline too (the
    reference the pruned search below equals; bench/bench_arc_position.py).

    A long polyline (a nominal run has a leg per step) is searched among the
    legs whose midpoints are nearest (scipy's cKDTree), and exactly: a leg
    j at midpoint distance r_j is no nearer than r_j − L_max/2, so when
    the k-th nearest midpoint's r_k − L_max/2 exceeds the best candidate's
    distance, no other leg can be nearer or tie; points where it does not
    are searched among all legs.  The result is the all-legs search's."""
    p = as_array("path", path, (None, 2))
    q = as_array("points", points, (None, 2))
    a, d = p[:-1], np.diff(p, axis=0)                                    # legs: a + t·d, t in [0, 1]
    s0 = np.r_[0.0, np.cumsum(np.hypot(*d.T))]
    if len(d) == 0:
        return np.zeros(len(q))
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    every = lambda m: np.broadcast_to(np.arange(len(d)), (m, len(d)))  # noqa: E731  (all legs, for m points)
    k = 16
    if all_legs or len(d) <= 4 * k:
        leg, t, _ = _nearest_legs(q, a, d, dd, every(len(q)))
        return s0[leg] + t * np.sqrt(dd[leg])
    from scipy.spatial import cKDTree

    r, cand = cKDTree(a + 0.5 * d).query(q, k=k)
    leg, t, sq = _nearest_legs(q, a, d, dd, np.sort(cand, axis=1))
    half = 0.5 * float(np.sqrt(dd.max()))
    # complete: every other leg is farther than the best candidate (margin for rounding)
    ok = r[:, -1] - half > np.sqrt(sq) * (1.0 + 1e-9) + 1e-12
    bad = np.flatnonzero(~ok)
    step = max(1, (1 << 22) // len(d))                                  # all legs, a few million entries at a time
    for i in range(0, len(bad), step):
        j = bad[i:i + step]
        leg[j], t[j], _ = _nearest_legs(q[j], a, d, dd, every(len(j)))
    return s0[leg] + t * np.sqrt(dd[leg])


@dataclass(frozen=True)
class SigmaCalibration:
    """The predicted position error along a path against Monte Carlo, per
    arc-length bin [``edges[i]``, ``edges[i + 1]``): ``predicted`` =
    sqrt(mean over the bin's stages of trace P_xy) (the RMS position error
    the belief predicts; with the deviation mixture's strata, the mean over
    the strata whose vehicles are in the bin, each weighted by its share),
    ``observed`` = sqrt(mean over the bin's recorded
    steps of |x̂_xy − x_xy|²) (NaN where none), ``samples`` (steps) and
    ``trials`` (trials with a step in the bin).  ``worst_share`` is the
    largest share of a bin's squared error that one trial holds, and
    ``observed_without_worst`` the RMS error without that trial (NaN where
    no other trial reached the bin): a bin whose RMS is one trial's is a rare
    event's, which a few dozen trials cannot resolve.  ``observed_low`` and
    ``observed_high`` bound ``observed`` by the percentile bootstrap over
    trials (95 %, 400 resamples, a fixed seed): how far the Monte Carlo
    itself may be off.  An event that no recorded trial met moves neither:
    where a bin's prediction rests on rare strata, more trials
    (:func:`pool_calibrations`) are the check.  ``trial_sq`` and
    ``trial_steps`` are each trial's squared-error sum and step count per
    bin (rows: trials), from which the rest is computed."""
    edges: np.ndarray
    predicted: np.ndarray
    observed: np.ndarray
    samples: np.ndarray
    trials: np.ndarray
    worst_share: np.ndarray
    observed_without_worst: np.ndarray
    observed_low: np.ndarray
    observed_high: np.ndarray
    trial_sq: np.ndarray
    trial_steps: np.ndarray

    @property
    def ratio(self) -> np.ndarray:
        """observed / predicted per bin (NaN where a bin has no sample or no prediction)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.predicted > 0, self.observed / self.predicted, np.nan)


#: The unscented rule of N(0, I_2) that a stratum's vehicles are spread by (the core's, in
#: `locate`, belief_strata.hpp): the centre with weight 1/3 and ±√3 along each axis with 1/6 each.
_SPREAD_NODES = np.sqrt(3.0) * np.array([[0.0, 0.0], [1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
_SPREAD_WEIGHTS = np.array([1.0, 0.5, 0.5, 0.5, 0.5]) / 3.0


def _spread_points(mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """(S, 5, 2): the rule's points of N(mean_i, cov_i) per stratum; cov as (S, 3) xx, xy, yy."""
    c = np.empty((len(mean), 2, 2))
    c[:, 0, 0], c[:, 0, 1], c[:, 1, 0], c[:, 1, 1] = cov[:, 0], cov[:, 1], cov[:, 1], cov[:, 2]
    lam, vec = np.linalg.eigh(c)
    root = vec * np.sqrt(np.maximum(lam, 0.0))[:, None, :]            # root @ rootᵀ = cov
    return mean[:, None, :] + np.einsum("sij,nj->sni", root, _SPREAD_NODES)


def _predicted_per_bin(profile, path, edges):
    """The belief's Σ trace P_xy per bin and the weight it was summed with.
    Without strata each stage goes to the bin of its own arc (weight 1).
    With the deviation mixture's strata each stratum of each stage goes to
    the bins of the arcs where its vehicles are, with its weight: the same
    binning as the driven vehicles' (their true position), so a stratum
    ahead of the nominal pose counts where it is, not where the nominal is.
    A stratum's vehicles lie around its mean position (``strata_positions``)
    as its position spread says (``strata_position_cov``, the unscented
    transform of its error through where its vehicles see from): each of the
    rule's five points takes its share of the stratum's weight, so a stratum
    that straddles a bin's edge counts on both sides, as its vehicles do."""
    n_bins = len(edges) - 1
    w = np.asarray(getattr(profile, "strata_weight", np.zeros(0)), dtype=float)
    if w.size == 0:
        cov = np.asarray(profile.cov_xy, dtype=float)
        b = np.clip(np.searchsorted(edges, arc_position(path, path), side="right") - 1, 0, n_bins - 1)
        return np.bincount(b, cov[:, 0] + cov[:, 3], n_bins), np.bincount(b, minlength=n_bins).astype(float)
    held = w.ravel() > 0.0                                           # slots no stratum holds weigh nothing
    pos = np.asarray(profile.strata_positions, dtype=float).reshape(-1, 2)[held]
    spread = np.asarray(profile.strata_position_cov, dtype=float).reshape(-1, 3)[held]
    points = _spread_points(pos, spread).reshape(-1, 2)
    msq = np.repeat(np.asarray(profile.strata_msq, dtype=float).ravel()[held], len(_SPREAD_WEIGHTS))
    ww = (w.ravel()[held][:, None] * _SPREAD_WEIGHTS).ravel()
    b = np.clip(np.searchsorted(edges, arc_position(path, points), side="right") - 1, 0, n_bins - 1)
    return np.bincount(b, ww * msq, n_bins), np.bincount(b, ww, n_bins)


def sigma_calibration(profile, truths, estimates, *, bin_m: float = 10.0) -> SigmaCalibration:
    """Bin a ``BeliefProfile`` (the prediction) and recorded trials (``truths``
    and ``estimates``: one (T_i, >= 2) array per trial, x and y first) by arc
    length along the profile's path: each stage (or each stratum of it, at
    its own position: ``_predicted_per_bin``) and each true position goes
    to the bin of its :func:`arc_position` (the estimate is paired with the
    truth of its step).  See :class:`SigmaCalibration`."""
    path = np.asarray(profile.positions, dtype=float)
    edges = calibration_edges(path, bin_m)
    tr, n_stage = _predicted_per_bin(profile, path, edges)
    per_sq, per_n = binned_trials(path, edges, truths, estimates)
    with np.errstate(divide="ignore", invalid="ignore"):
        pred = np.where(n_stage > 0, np.sqrt(tr / n_stage), np.nan)
    return _calibration(edges, pred, per_sq, per_n)


def calibration_edges(path, bin_m: float) -> np.ndarray:
    """The arc-length bins' edges of :func:`sigma_calibration` along ``path`` ((N, 2))."""
    if not (np.isfinite(bin_m) and bin_m > 0):
        raise ValueError(f"bin_m = {bin_m!r}: must be a finite number of metres > 0")
    length = float(np.sum(np.hypot(*np.diff(np.asarray(path, dtype=float), axis=0).T)))
    return np.arange(0.0, length + bin_m, bin_m)


def binned_trials(path, edges, truths, estimates) -> tuple[np.ndarray, np.ndarray]:
    """Each trial's squared position error summed per arc-length bin of
    ``path`` (each true position at its :func:`arc_position`, the estimate
    paired with the truth of its step), and its step count per bin (rows:
    trials): the Monte Carlo side of :func:`sigma_calibration`."""
    if len(truths) != len(estimates):
        raise ValueError(f"truths has {len(truths)} trials but estimates has {len(estimates)}")
    path = np.asarray(path, dtype=float)
    n_bins = len(edges) - 1
    per_sq, per_n = np.zeros((len(truths), n_bins)), np.zeros((len(truths), n_bins), dtype=int)
    for i, (x, xh) in enumerate(zip(truths, estimates)):
        x, xh = np.asarray(x, dtype=float)[:, :2], np.asarray(xh, dtype=float)[:, :2]
        if x.shape != xh.shape:
            raise ValueError(f"trial {i}: truth {x.shape} and estimate {xh.shape} differ in shape")
        b = np.clip(np.searchsorted(edges, arc_position(path, x), side="right") - 1, 0, n_bins - 1)
        per_sq[i] = np.bincount(b, np.sum((xh - x) ** 2, axis=1), n_bins)
        per_n[i] = np.bincount(b, minlength=n_bins)
    return per_sq, per_n


def pool_calibrations(calibrations) -> SigmaCalibration:
    """One :class:`SigmaCalibration` of the trials of several, of the same
    prediction and bins (e.g. batches of recorded trials, so that many
    trials need not be held at once): the same as one call of
    :func:`sigma_calibration` with all their trials, in order."""
    cals = list(calibrations)
    if not cals:
        raise ValueError("pool_calibrations: no calibrations to pool")
    first = cals[0]
    for i, c in enumerate(cals[1:], 1):
        if not (np.array_equal(c.edges, first.edges) and np.array_equal(c.predicted, first.predicted, equal_nan=True)):
            raise ValueError(f"pool_calibrations: calibration {i} has other bins or another prediction than "
                             f"calibration 0 ({len(c.edges) - 1} bins against {len(first.edges) - 1})")
    return _calibration(first.edges, first.predicted, np.concatenate([c.trial_sq for c in cals]),
                        np.concatenate([c.trial_steps for c in cals]))


def _calibration(edges, pred, per_sq, per_n) -> SigmaCalibration:
    """The calibration from each trial's squared-error sums and step counts per bin (rows: trials)."""
    n_bins = len(edges) - 1
    sq, n, hit = np.zeros(n_bins), np.zeros(n_bins, dtype=int), np.zeros(n_bins, dtype=int)
    worst_sq, worst_n = np.zeros(n_bins), np.zeros(n_bins, dtype=int)
    for trial_sq, trial_n in zip(per_sq, per_n):  # in trial order: the sums do not depend on the batches
        sq += trial_sq
        n += trial_n
        hit += trial_n > 0
        worse = trial_sq > worst_sq
        worst_sq, worst_n = np.where(worse, trial_sq, worst_sq), np.where(worse, trial_n, worst_n)
    with np.errstate(divide="ignore", invalid="ignore"):
        obs = np.where(n > 0, np.sqrt(sq / n), np.nan)
        share = np.where(sq > 0, worst_sq / sq, np.nan)
        rest = np.where(n > worst_n, np.sqrt(np.maximum(sq - worst_sq, 0.0) / (n - worst_n)), np.nan)
    low, high = _bootstrap_rms(per_sq, per_n)
    return SigmaCalibration(edges=edges, predicted=pred, observed=obs, samples=n, trials=hit, worst_share=share,
                            observed_without_worst=rest, observed_low=low, observed_high=high, trial_sq=per_sq,
                            trial_steps=per_n)


def _bootstrap_rms(per_sq: np.ndarray, per_n: np.ndarray, resamples: int = 400, confidence: float = 0.95):
    """The percentile bootstrap of each bin's RMS over trials (rows of the
    per-trial squared-error sums and step counts): trials drawn with
    replacement, a fixed seed, so the same trials give the same bounds."""
    n_bins = per_sq.shape[1]
    if len(per_sq) == 0:
        return np.full(n_bins, np.nan), np.full(n_bins, np.nan)
    counts = np.random.default_rng(0).multinomial(len(per_sq), np.full(len(per_sq), 1.0 / len(per_sq)), resamples)
    with np.errstate(divide="ignore", invalid="ignore"):
        rms = np.sqrt((counts @ per_sq) / (counts @ per_n))
    tail = 50.0 * (1.0 - confidence)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a bin no resample reached: NaN
        return np.nanpercentile(rms, tail, axis=0), np.nanpercentile(rms, 100.0 - tail, axis=0)


def clopper_pearson(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """One-sided Clopper–Pearson bounds (lower, upper) on a binomial rate
    from ``k`` events in ``n`` trials: each holds at ``confidence``
    (Clopper & Pearson 1934; the exact binomial bound through the beta
    quantile: upper = B⁻¹(c; k + 1, n − k), lower = B⁻¹(1 − c; k, n − k + 1))."""
    from scipy import stats

    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n = {n!r}: must be an integer >= 1")
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k <= n:
        raise ValueError(f"k = {k!r}: must be an integer in [0, n = {n}]")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence = {confidence!r}: must lie in (0, 1)")
    upper = 1.0 if k == n else float(stats.beta.ppf(confidence, k + 1, n - k))
    lower = 0.0 if k == 0 else float(stats.beta.ppf(1 - confidence, k, n - k + 1))
    return lower, upper

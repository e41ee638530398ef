"""The landmark placement paper's evaluation: [Placement Table I] on fresh
random instances and the [Placement §III-A] simulation (a ground robot with bearings to
the placed landmarks and the extended information filter)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..validation import as_array, as_positive_int, as_seed
from ..filters import filter_trajectory
from ..motion import Bmm, BmmParams, wrap_angle
from .algorithm import (PAPER_AREA, PAPER_SPACING, CameraParams, camera_params, candidate_grid, check_route,
                        place_along_route, place_optimal)
from .tour import plan_tour, tour_length

#: [Placement Table I]: (targets, landmarks) for its nine random instances.
PAPER_TABLE_ONE = ((5, 21), (5, 22), (5, 12), (6, 24), (6, 22), (7, 20), (7, 31), (7, 21), (7, 12))


def random_instance(n_targets: int, rng: np.random.Generator, area=PAPER_AREA) -> np.ndarray:
    """Targets drawn uniformly in the ``area`` (the paper: a 4 × 8 grid)."""
    return rng.uniform((0.0, 0.0), area, size=(as_positive_int("n_targets", n_targets), 2))


def table_one(seed: int = 0, *, camera: CameraParams | None = None, k: int = 2, margin: float | None = None,
              optimal: bool = True, time_limit: float = 120.0, sizes: Sequence[int] | None = None):
    """[Placement Table I] on fresh random instances.

    Nine instances with 5, 5, 5, 6, 6, 7, 7, 7, 7 targets uniform in 4 × 8,
    candidates on a 0.5 grid over the area widened by ``margin`` (default R:
    the paper does not say how far its grid reached, and inside the area
    alone many instances cannot be covered near the edge ends), field of view
    50°, R = 2 m, p = 0.05 m, the route an open tour from the first to the
    last target.  Columns: ``greedy_paper`` ([Placement Alg. 1] verbatim, union over
    edges), ``greedy`` (plus non-coincidence), ``greedy_reuse``,
    ``greedy_corners``, ``optimal`` and ``optimal_corners`` (ILP) and the
    paper's count.  The instances are random, so compare distributions, not
    rows.
    """
    import pandas as pd

    cam = camera or CameraParams()
    margin = cam.range if margin is None else float(margin)
    rng = np.random.default_rng(as_seed("seed", seed))
    cand = candidate_grid((0.0, 0.0), PAPER_AREA, PAPER_SPACING, margin=margin)
    sizes = [n for n, _ in PAPER_TABLE_ONE] if sizes is None else list(sizes)
    rows = []
    for i, n in enumerate(sizes):
        targets = random_instance(n, rng)
        route = targets[plan_tour(targets, seed=i)]
        row = {"instance": i + 1, "targets": n, "route_length": tour_length(route)}
        kw = dict(k=k, allow_uncovered=True)
        g0 = place_along_route(route, cand, cam, distinct_bearings=False, **kw)
        g = place_along_route(route, cand, cam, **kw)
        gr = place_along_route(route, cand, cam, reuse=True, **kw)
        gc = place_along_route(route, cand, cam, corners=True, **kw)
        row.update(greedy_paper=g0.count, greedy=g.count, greedy_reuse=gr.count, greedy_corners=gc.count,
                   greedy_ms=1e3 * g.seconds, covered=g.covered and gc.covered)
        if optimal:
            o = place_optimal(route, cand, cam, time_limit=time_limit, **kw)
            oc = place_optimal(route, cand, cam, corners=True, time_limit=time_limit, **kw)
            row.update(optimal=o.count, optimal_corners=oc.count, optimal_s=o.seconds, optimal_corners_s=oc.seconds,
                       proven=bool(o.optimal and oc.optimal))
        row["paper"] = PAPER_TABLE_ONE[i][1] if i < len(PAPER_TABLE_ONE) and PAPER_TABLE_ONE[i][0] == n else None
        rows.append(row)
    return pd.DataFrame(rows)


# ---------------------------------------------------------------------------
# Simulation [Placement §III-A]: ground robot, bearings, extended information filter
# ---------------------------------------------------------------------------

@dataclass
class SimulationResult:
    """True and estimated trajectories of :func:`simulate`."""

    t: np.ndarray            #: (N+1,) time [s]
    truth: np.ndarray        #: (N+1, 4) true (x, y, v, θ)
    estimate: np.ndarray     #: (N+1, 4) EIF estimate
    covariance: np.ndarray   #: (N+1, 4, 4)
    n_in_view: np.ndarray    #: (N+1,) landmarks in view after each step (0 at t=0)
    turning: np.ndarray      #: (N+1,) True while the robot turns in place
    landmarks: np.ndarray    #: (L, 2)
    route: np.ndarray

    @property
    def errors(self) -> np.ndarray:
        """(N+1, 3) estimate − truth in x, y and heading (wrapped)."""
        e = self.estimate[:, [0, 1, 3]] - self.truth[:, [0, 1, 3]]
        e[:, 2] = wrap_angle(e[:, 2])
        return e

    @property
    def sigmas(self) -> np.ndarray:
        """(N+1, 3) standard deviations of x, y and heading."""
        return np.sqrt(self.covariance[:, [0, 1, 3], [0, 1, 3]])

    def inside_3sigma(self) -> dict:
        """Fraction of the time each error is within its ±3σ bound."""
        inside = np.abs(self.errors) <= 3 * self.sigmas
        return {name: float(inside[:, i].mean()) for i, name in enumerate(("x", "y", "heading"))}

    def gap_fraction(self, k: int = 2) -> float:
        """Fraction of the time steps with fewer than ``k`` landmarks in view."""
        return float((self.n_in_view[1:] < k).mean())


def simulate(route, landmarks, camera: CameraParams | dict | None = None, *, speed: float = 0.2, dt: float = 0.1,
             bearing_std: float = 0.01, heading_gain: float = 2.0, seed: int = 0,
             prior_std=(0.05, 0.05, 0.01, 0.03), max_steps: int = 200_000) -> SimulationResult:
    """[Placement §III-A]: a ground robot drives the route at ``speed`` (0.2 m/s) with
    a heading controller and an extended information filter estimates its
    position and heading from bearings to the landmarks in view.

    The robot follows the BMM (:class:`safenav.Bmm`) with small process noise.
    Its controller (run on the true state, so that the robot follows the
    route) turns in place at every waypoint until it faces the next one, then
    drives at ``speed`` with heading change ``heading_gain · e · Δt`` for the
    heading error ``e``.  Each step a bearing ``wrap(atan2(ℓ − p) − θ) + v``,
    ``v ~ N(0, bearing_std²)``, is measured to every landmark within R and
    ±α/2 of the true pose.  The EIF (``filter_trajectory(filter="eif")``,
    one C++ call) gets the same controls and the bearings.

    The robot's loop stays in Python: its controls come from a waypoint
    controller closed on the true state, and the core's batch runners take
    their controls in advance (``Bmm.simulate``, ``run_filter``) or steer by
    SafeNav's corridor (``Navigator``).  The filter itself is one core call.
    """
    cam = camera_params(camera)
    r = check_route(route)
    lm = as_array("landmarks", landmarks, (None, 2))
    if lm.shape[0] == 0:
        raise ValueError("landmarks must hold at least one landmark, got 0")
    _check_simulation(speed, dt, bearing_std, heading_gain, prior_std, max_steps)
    params = BmmParams()
    params.dt = float(dt)
    params.max_speed = max(1.0, 2 * speed)
    params.max_heading_rate = 1.5
    params.speed_noise, params.heading_noise, params.position_noise = 0.002, 0.002, 0.001
    rng = np.random.default_rng(as_seed("seed", seed))
    truth, u, turning = _drive(r, Bmm(params), speed, heading_gain, rng, max_steps)
    # bearings to landmarks in view of the true pose
    rel = lm[None, :, :] - truth[1:, None, :2]
    dist = np.hypot(rel[..., 0], rel[..., 1])
    brg = wrap_angle(np.arctan2(rel[..., 1], rel[..., 0]) - truth[1:, 3, None])
    seen = (dist <= cam.range) & (dist > 0)
    if cam.fov == "sector":
        seen &= np.abs(brg) <= cam.angle / 2
    z = np.where(seen, wrap_angle(brg + bearing_std * rng.standard_normal(brg.shape)), np.nan)
    P0 = np.diag(np.square(prior_std))
    x0 = truth[0] + rng.standard_normal(4) * np.asarray(prior_std)
    res = filter_trajectory(u, x0, P0, params=params, filter="eif", bearings=z, bearing_std=bearing_std,
                            landmarks=lm)
    return SimulationResult(t=np.arange(len(u) + 1) * dt, truth=truth, estimate=res.states,
                            covariance=res.covariances, n_in_view=np.concatenate([[0], seen.sum(axis=1)]),
                            turning=np.array(turning), landmarks=lm, route=r)


def _check_simulation(speed, dt, bearing_std, heading_gain, prior_std, max_steps) -> None:
    """:func:`simulate`'s scalar arguments, each named in its error."""
    for name, v in (("speed", speed), ("dt", dt), ("bearing_std", bearing_std), ("heading_gain", heading_gain)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) \
                or not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} = {v!r} must be finite and > 0")
    try:
        prior = np.asarray(prior_std, dtype=float).ravel() if np.ndim(prior_std) == 1 else np.zeros(0)
    except (TypeError, ValueError):
        prior = np.zeros(0)
    if prior.shape != (4,) or not (np.isfinite(prior).all() and (prior > 0).all()):
        raise ValueError(f"prior_std = {prior_std!r} must be 4 finite values > 0 (x, y, v, theta)")
    as_positive_int("max_steps", max_steps)


def _drive(r: np.ndarray, bmm: Bmm, speed: float, heading_gain: float, rng, max_steps: int):
    """[Placement §III-A]'s robot on route ``r``: the noisy BMM under the
    waypoint controller of :func:`simulate`, closed on the true state.
    Returns the true states (steps + 1), the controls and the turning flags."""
    params = bmm.params
    dt = params.dt
    sig_eps = np.array([params.position_noise, params.position_noise, params.speed_noise, params.heading_noise])
    x = np.array([r[0, 0], r[0, 1], 0.0, math.atan2(*(r[1] - r[0])[::-1])])
    states, controls, turning = [x], [], [False]
    wp = 1
    lim = params.max_heading_rate * dt
    while wp < len(r) and len(controls) < max_steps:
        to = r[wp] - x[:2]
        dist = math.hypot(*to)
        if dist <= 0.75 * speed * dt:  # arrived (within one step)
            wp += 1
            continue
        err = float(wrap_angle(math.atan2(to[1], to[0]) - x[3]))
        turn = abs(err) > max(lim, 0.02)
        if turn:
            u = (0.0, err)
        else:
            u = (min(speed, dist / dt), heading_gain * err * dt if dist > speed * dt else err)
        x = bmm.transition(x, u, rng.standard_normal(4) * sig_eps)
        states.append(x)
        controls.append(u)
        turning.append(turn)
    return np.array(states), np.array(controls, dtype=float), turning


def corner_gap_demo(seed: int = 3, n_targets: int = 6, *, camera: CameraParams | None = None, sim_seed: int = 0):
    """Corner coverage closes the gap: the same random instance placed
    without and with ``corners``, each driven by :func:`simulate`.  Returns a
    dict of the two placements and simulations and, for each, the fraction of
    the turning time with fewer than 2 landmarks in view."""
    cam = camera or CameraParams()
    rng = np.random.default_rng(seed)
    targets = random_instance(n_targets, rng)
    route = targets[plan_tour(targets)]
    cand = candidate_grid((0, 0), PAPER_AREA, PAPER_SPACING, margin=cam.range)
    out = {}
    for corners in (False, True):
        pl = place_along_route(route, cand, cam, corners=corners)
        sim = simulate(route, pl.landmarks, cam, seed=sim_seed)
        turning = sim.turning[1:]
        blind = float((sim.n_in_view[1:][turning] < 2).mean()) if turning.any() else 0.0
        out["corners" if corners else "plain"] = {"placement": pl, "simulation": sim, "turn_gap": blind,
                                                  "gap": sim.gap_fraction(2), "inside_3sigma": sim.inside_3sigma()}
    return out


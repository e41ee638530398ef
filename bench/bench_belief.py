"""Benchmark belief-aware planning on the built-in default scenario (the
paper's 200 x 200 m real-imitated world, path types P1-P3).

For each path type it prints:
  * the RAw-RRT* safe path (the paper's planner, as the experiments plan it):
    its predicted sigma profile (sqrt(lambda_max(P_xy)): max, mean, final),
    the share of stages with a LanBLoc fix in view, the predicted path
    collision probability (Patil et al.) of the vehicle's disc and the union
    bound, and that of a point (the simulator counts a collision when the
    point vehicle enters an obstacle), each beside a Monte Carlo of the
    same linear error model (the reference Patil's estimate approximates);
  * the belief-aware plan (k = 3, the RAw-RRT* path as a guide path in the
    roadmap): planning time (target <= 2 s per path on one core), length,
    sigma profile, collision probability;
  * the predicted sigma against a Monte Carlo of the navigation loop
    (Navigator: the true vehicle, the simulated sensors and the EKF
    localizer) following the RAw-RRT* path: per arc-length bin, the predicted
    sigma beside the filter's own (mean over the trials' steps), and the
    predicted RMS position error sqrt(trace P_xy) beside the actual one; the
    same on the belief-aware path, summarised.

Run:
    python bench/bench_belief.py [--trials 40] [--k 3.0] [--samples 600]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import safenav
from safenav import navigation as nav
from safenav import planning as P


def scenario_inputs(scenario, path_type: str | None = None, *, source: str = "lanbloc") -> dict:
    """Keyword arguments for ``plan_belief`` and ``propagate_belief``
    from a scenario: its planning ``map`` (hazards of risk >= the planner's
    ``forbidden_risk`` are keep-out areas), ``bmm``, the ``sensors`` of its
    navigation loop (as ``safenav.navigation.make_navigator`` builds
    them), the cruise ``speed`` and the ``vehicle_radius`` and ``margin``."""
    name = path_type if path_type is not None else scenario.path_types[0].name
    navigator = nav.make_navigator(scenario, scenario.path_polyline(name), source=source, record=False)
    n = scenario.navigation
    return {"map": P.map_from_world(scenario.world, forbidden_risk=scenario.planner.forbidden_risk),
            "bmm": scenario.bmm_params(), "sensors": navigator.sensors, "speed": float(n.cruise_speed),
            "vehicle_radius": float(n.vehicle_radius), "margin": float(n.clearance_margin)}


def arc_length(path: np.ndarray) -> np.ndarray:
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))]


def project(path: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Arc length of each point's nearest point on the polyline."""
    s0 = arc_length(path)
    a, b = path[:-1], path[1:]
    ab = b - a
    L2 = np.maximum((ab ** 2).sum(1), 1e-300)
    t = np.clip(((pts[:, None, :] - a[None]) * ab[None]).sum(2) / L2[None], 0.0, 1.0)
    d2 = ((a[None] + t[..., None] * ab[None] - pts[:, None, :]) ** 2).sum(2)
    j = d2.argmin(1)
    return s0[j] + t[np.arange(len(pts)), j] * np.sqrt(L2[j])


def summary(prof, in_view_min: int) -> str:
    s = np.asarray(prof.sigma)
    fix = (np.asarray(prof.landmarks) >= in_view_min).mean()
    return (f"sigma max {s.max():.3f} mean {s.mean():.3f} final {s[-1]:.3f} m, fix in view {100 * fix:.0f} %, "
            f"P(collision) {prof.collision_probability:.2e} (union bound {prof.union_bound:.2e})")


def monte_carlo(scenario, path: np.ndarray, prof, trials: int, bins: int = 8):
    """Per arc-length bin: the predicted sigma (sqrt(lambda_max(P_xy))) beside the
    filter's own, and the predicted RMS error sqrt(trace P_xy) beside the actual."""
    navigator = nav.make_navigator(scenario, path)
    cov = np.asarray(prof.cov_xy)
    pred_s = arc_length(np.asarray(prof.positions))
    pred_rms = np.sqrt(cov[:, 0] + cov[:, 3])
    pred_sig = np.asarray(prof.sigma)
    edges = np.linspace(0.0, pred_s[-1], bins + 1)
    err2 = [[] for _ in range(bins)]
    rep = [[] for _ in range(bins)]
    outcomes = {}
    t0 = time.perf_counter()
    for seed in range(trials):
        r = navigator.run(seed)
        outcomes[r.outcome_name] = outcomes.get(r.outcome_name, 0) + 1
        truth, est = np.asarray(r.truth), np.asarray(r.estimate)
        s = project(path, truth[:, :2])
        k = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, bins - 1)
        e2 = ((est[:, :2] - truth[:, :2]) ** 2).sum(1)
        std = np.asarray(r.position_std)
        for b in range(bins):
            err2[b].extend(e2[k == b])
            rep[b].extend(std[k == b])
    wall = time.perf_counter() - t0
    rows = []
    for b in range(bins):
        m = (pred_s >= edges[b]) & (pred_s <= edges[b + 1])
        rows.append((edges[b], edges[b + 1], pred_sig[m].mean(), np.mean(rep[b]) if rep[b] else np.nan,
                     pred_rms[m].mean(), np.sqrt(np.mean(err2[b])) if err2[b] else np.nan))
    return rows, outcomes, wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=40)
    ap.add_argument("--k", type=float, default=3.0)
    ap.add_argument("--samples", type=int, default=600)
    args = ap.parse_args()
    sc = safenav.default_scenario()
    print(f"scenario {sc.name}: {len(sc.world.landmarks)} landmarks, k = {args.k}, "
          f"{args.samples} roadmap samples, {args.trials} Monte Carlo trials per path\n")
    for pt in sc.path_types:
        inputs = scenario_inputs(sc, pt.name)
        min_lm = inputs["sensors"].min_landmarks
        t0 = time.perf_counter()
        raw = nav.plan_safe_path(sc, pt.name)
        t_raw = time.perf_counter() - t0
        path = np.asarray(raw.path)
        t0 = time.perf_counter()
        prof = P.propagate_belief(path, **inputs)
        t_prop = time.perf_counter() - t0
        print(f"{pt.name}  RAw-RRT*: {t_raw:.2f} s, length {raw.cost.length:.1f} m; belief {t_prop * 1e3:.1f} ms "
              f"({len(prof.sigma)} steps of {inputs['bmm'].dt} s)")
        print(f"    {summary(prof, min_lm)}")
        point = P.propagate_belief(path, **{**inputs, "vehicle_radius": 0.0})
        print(f"    Monte Carlo of the same linear error model: {P.collision_monte_carlo(prof, 10000):.2e}; "
              f"a point vehicle (the simulator's collision test): {point.collision_probability:.2e}, "
              f"Monte Carlo {P.collision_monte_carlo(point, 10000):.2e}")
        res = P.plan_belief(start=path[0], goal=path[-1], guide_paths=[path], k_sigma=args.k, samples=args.samples,
                            **inputs)
        r = res.result
        line = (f"    belief-aware: {res.status.name} in {r.planning_time:.2f} s ({r.vertices} vertices, "
                f"{r.edges} edges, {r.expansions} expansions, {r.beliefs} beliefs)")
        if res.success:
            line += f", length {res.profile.length:.1f} m\n    {summary(res.profile, min_lm)}"
        else:
            line += f": {res.detail}"
        print(line)
        if args.trials > 0:
            rows, outcomes, wall = monte_carlo(sc, path, prof, args.trials)
            print(f"    Monte Carlo of the navigation loop on the RAw-RRT* path ({args.trials} trials, "
                  f"{wall:.1f} s, outcomes {outcomes}):")
            print("      arc length [m]   sigma: predicted  filter   |  RMS error: predicted  actual   [m]")
            for lo, hi, ps, fs, pr, ac in rows:
                print(f"      {lo:6.1f}-{hi:6.1f}         {ps:8.4f}  {fs:8.4f}   |             {pr:8.4f}  {ac:8.4f}")
            if res.success:
                rows, outcomes, wall = monte_carlo(sc, np.asarray(res.path), res.profile, args.trials)
                r = np.array([row[2:] for row in rows], dtype=float)
                print(f"    ... and on the belief-aware path ({wall:.1f} s, outcomes {outcomes}): mean over the bins "
                      f"of sigma predicted {np.nanmean(r[:, 0]):.3f} / filter {np.nanmean(r[:, 1]):.3f} m, RMS "
                      f"error predicted {np.nanmean(r[:, 2]):.3f} / actual {np.nanmean(r[:, 3]):.3f} m")
        print()


if __name__ == "__main__":
    main()

"""Consistency of the particle filter against the EKF in the navigation loop.

On the default scenario: path types × method (CHull, Centroid) × setting ×
filter (EKF, PF), the default loop (guard on, gate on), N trials per cell with
the runner's seeds (trial_seeds(seeds.trials, path index, N)), the same seeds
for every filter and setting.  Settings:

* ``clean``: LanBLoc fixes as the scenario has them, occlusion off;
* ``faulty``: the faults of bench_safety.py (fixes from single-landmark
  ranges, 20 % dropout, 5 % outliers, 1 % misassociation), occlusion off;
* ``occluded``: clean measurements, obstacles hide landmarks (the scenario's
  default).

Per cell: collisions, arrivals, the mean 4-state NEES over all recorded steps
(a consistent filter gives about 4: chi-square with 4 dof), the share of
steps with the truth outside the 3σ ellipse, and the time per step.

    python bench/bench_pf_consistency.py [--trials 100] [--paths P1,P2,P3] [--particles 500]
                                         [--methods chull,centroid] [--settings clean,faulty,occluded]
"""
from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

import safenav
from safenav import navigation as nv
from safenav.runner import trial_seeds

FAULTS = dict(fix_model="ranges", dropout_probability=0.2, outlier_probability=0.05,
              misassociation_probability=0.01)


def setting(base, name: str):
    """The scenario of one measurement setting."""
    no_occl = dataclasses.replace(base.detection, occlusion=False)
    if name == "clean":
        return dataclasses.replace(base, detection=no_occl)
    if name == "faulty":
        return dataclasses.replace(base, detection=no_occl, noise=dataclasses.replace(base.noise, **FAULTS))
    if name == "occluded":
        return dataclasses.replace(base, detection=dataclasses.replace(base.detection, occlusion=True))
    raise ValueError(f"setting {name!r} is not one of clean, faulty, occluded")


def make_navigator(sc, safe, method: str, filt: str, particles: int, bandwidth_scale: float):
    """nv.make_navigator with the PF's FilterOptions.bandwidth_scale set (make_navigator has no argument for it)."""
    n = nv.make_navigator(sc, safe, method=method, filter=filt, n_particles=particles, record=False)
    if filt == "pf" and bandwidth_scale != 1.0:
        s = n.settings
        s.filter.bandwidth_scale = bandwidth_scale
        n = nv.Navigator(n.problem, s, n.sensors)
    return n


def run_cell(sc, safe, seeds, method: str, filt: str, particles: int, bandwidth_scale: float = 1.0) -> dict:
    n = make_navigator(sc, safe, method, filt, particles, bandwidth_scale)
    t0 = time.perf_counter()
    d = n.run_many(seeds)
    wall = time.perf_counter() - t0
    out = np.asarray(d["outcome"])
    steps = np.asarray(d["steps"], dtype=float)
    rows = steps + 1
    nees = np.asarray(d["nees"], dtype=float)
    ok = np.isfinite(nees)
    return dict(collisions=int((out == nv.OUTCOMES.index("collision")).sum()),
                arrived=int((out == nv.OUTCOMES.index("arrived")).sum()),
                nees=float(np.sum(nees[ok] * rows[ok]) / np.sum(rows[ok])) if ok.any() else np.nan,
                nees_median_trial=float(np.median(nees[ok])) if ok.any() else np.nan,
                out3s=float(np.mean(d["outside_3sigma"])),
                us_step=1e6 * wall / max(steps.sum(), 1.0))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--paths", default="P1,P2,P3")
    ap.add_argument("--methods", default="chull,centroid")
    ap.add_argument("--settings", default="clean,faulty,occluded")
    ap.add_argument("--filters", default="ekf,pf")
    ap.add_argument("--particles", type=int, default=500)
    ap.add_argument("--bandwidth-scale", type=float, default=1.0,
                    help="the PF's FilterOptions.bandwidth_scale (0: the plain SIR filter)")
    args = ap.parse_args()
    base = safenav.default_scenario()
    print(f"{args.trials} trials per cell, PF with {args.particles} particles, bandwidth_scale "
          f"{args.bandwidth_scale:g}; NEES = mean 4-state NEES over all "
          f"recorded steps (chi-square 4 dof: 4); out3s = share of steps outside 3 sigma")
    print(f"{'path':<4} {'method':<9} {'setting':<9} {'filter':<6} {'coll':>4} {'arr':>4} {'NEES':>9} "
          f"{'med/trial':>9} {'out3s':>6} {'us/step':>8}")
    total = {}
    for path_name in args.paths.split(","):
        safe = nv.plan_safe_path(base, path_name).path
        idx = [p.name for p in base.path_types].index(path_name)
        seeds = [int(s) for s in trial_seeds(base.seeds.trials, idx, args.trials)]
        for method in args.methods.split(","):
            for name in args.settings.split(","):
                sc = setting(base, name)
                for filt in args.filters.split(","):
                    r = run_cell(sc, safe, seeds, method, filt, args.particles, args.bandwidth_scale)
                    t = total.setdefault((name, filt), [0, 0, []])
                    t[0] += r["collisions"]
                    t[1] += args.trials
                    t[2].append(r["nees"])
                    print(f"{path_name:<4} {method:<9} {name:<9} {filt:<6} {r['collisions']:4d} {r['arrived']:4d} "
                          f"{r['nees']:9.3g} {r['nees_median_trial']:9.3g} {r['out3s']:6.3f} {r['us_step']:8.1f}",
                          flush=True)
    print("\nsummary (collisions / trials; NEES: mean over cells of the cell means)")
    for (name, filt), (c, n, nees) in total.items():
        print(f"  {name:<9} {filt:<4} collisions {c:4d} / {n:<5d} NEES {np.mean(nees):.3g}")


if __name__ == "__main__":
    main()

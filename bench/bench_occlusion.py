"""Occlusion on vs off (SensorSettings.occlusion, scenario detection.occlusion)
on the default scenario: P1–P3, SafeNav-CHull and -Centroid, the default loop
(guard and gate on, EKF, the LanBLoc measurement-level profile), N trials per
cell with the runner's seeds (trial_seeds(seeds.trials, path index, N)).

Per cell and setting: collisions, arrivals, fix rate (accepted fixes per
step), landmarks in view of the truth per fix step (a step with a fix; with
occlusion on, counted with World.visible_from — the same query as the
camera), truth ADE, and the time per step (run_many's wall time / steps).

    python bench/bench_occlusion.py [--trials 200]
"""
from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

import safenav
from safenav import _core
from safenav import navigation as nv
from safenav.runner import trial_seeds


def in_view_counts(world, sensors, truth, occlusion):
    """Landmarks in view of each truth row (range, FOV, and with occlusion the line of sight)."""
    L = sensors.landmarks
    d = L[None, :, :] - truth[:, None, :2]
    d2 = (d ** 2).sum(axis=2)
    ok = d2 <= sensors.max_range ** 2
    if sensors.field_of_view < 2 * np.pi:
        c, s = np.cos(truth[:, 3]), np.sin(truth[:, 3])
        along = c[:, None] * d[:, :, 0] + s[:, None] * d[:, :, 1]
        ok &= ~((d2 > 0) & (along < np.cos(0.5 * sensors.field_of_view) * np.sqrt(d2)))
    if occlusion:
        for j in range(len(L)):        # line of sight is symmetric: one batch query per landmark
            rows = np.flatnonzero(ok[:, j])
            if len(rows):
                ok[rows, j] = world.visible_from(L[j], truth[rows, :2])
    return ok.sum(axis=1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--paths", default="P1,P2,P3")
    args = ap.parse_args()
    base = safenav.default_scenario()
    print(f"{'cell':<14} {'occl':<4} {'coll':>4} {'arr':>4} {'fix/step':>8} {'lm/fix':>6} {'ADE':>7} "
          f"{'us/step':>8} {'steps':>8}")
    for path_name in args.paths.split(","):
        safe = nv.plan_safe_path(base, path_name).path
        idx = [p.name for p in base.path_types].index(path_name)
        seeds = [int(s) for s in trial_seeds(base.seeds.trials, idx, args.trials)]
        for method in ("chull", "centroid"):
            for occl in (True, False):
                sc = dataclasses.replace(base, detection=dataclasses.replace(base.detection, occlusion=occl))
                n = nv.make_navigator(sc, safe, method=method, record=False)
                t0 = time.perf_counter()
                d = n.run_many(seeds)
                wall = time.perf_counter() - t0
                out = np.asarray(d["outcome"])
                steps = np.asarray(d["steps"])
                coll = int((out == int(_core.TrialOutcome.COLLISION)).sum())
                arr = int((out == int(_core.TrialOutcome.ARRIVED)).sum())
                fix_rate = np.sum(d["position_fixes"]) / steps.sum()
                ade = float(np.mean(d["truth_ade"]))
                us = 1e6 * wall / steps.sum()
                # landmarks in view per fix step: recorded runs (same seeds, same trials)
                nr = nv.make_navigator(sc, safe, method=method, record=True)
                per_fix = []
                for s in seeds:
                    r = nr.run(s)
                    truth = np.asarray(r.truth)
                    fixed = ~np.isnan(np.asarray(r.measured)[:, 0])
                    fixed[0] = False             # row 0 is the prior, not a fix step
                    if fixed.any():
                        per_fix.append(in_view_counts(sc.world, n.sensors, truth[fixed], occl))
                lm = float(np.concatenate(per_fix).mean()) if per_fix else float("nan")
                print(f"{path_name + ' ' + method:<14} {'on' if occl else 'off':<4} {coll:>4} {arr:>4} "
                      f"{fix_rate:>8.4f} {lm:>6.2f} {ade:>7.4f} {us:>8.2f} {steps.sum():>8}", flush=True)


if __name__ == "__main__":
    main()

#!/usr/bin/env python
"""The camera loop before and after windows from the estimate, on the same trials.

Run from the repository root::

    python bench/bench_lanbloc_loop.py                 # 2 trials per path type, a frame every 10 steps
    python bench/bench_lanbloc_loop.py --trials 5 --every 20 --paths P1 P3

Per path type of the default scenario (centroid method, EKF, the scenario camera at its own
resolution), the same trial seeds (the sweep's seed rule) run twice:

* **before**: :class:`safenav.vision.CameraLoopSource`, a position callback that renders the
  markers' true footprints and runs the Python region pipeline there (the windows come from
  the truth);
* **after**: :class:`safenav.vision.camera_loop.CameraFrames` through ``Navigator.run_frames``:
  the localizer plans windows from its own prediction, the renderer draws those regions (ground
  and background included), the core's front end searches them and the fix goes through the
  localizer's gate.  Each of its frames is also rendered whole and searched without a prediction
  (``compare_whole_frame``): fixes, markers missed by the windows, false detections, the windows'
  fix error and NEES against the truth, and the front end's time per frame.

Prints per path: arrivals, the median fix error (fixes against the true position), the
trials' mean NEES and share outside 3σ, and seconds per trial.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import safenav
from safenav import navigation as nv
from safenav import runner
from safenav.vision import CameraLoopSource
from safenav.vision.camera_loop import CameraFrames


def _fix_errors(r) -> np.ndarray:
    m = np.asarray(r.measured)
    ok = np.isfinite(m).all(axis=1)
    ok[0] = False   # row 0 is the prior, not a camera fix
    return np.hypot(*(m[ok] - np.asarray(r.truth)[ok, :2]).T)


def _row(label, results, seconds) -> str:
    err = np.concatenate([_fix_errors(r) for r in results]) if results else np.array([])
    arrived = sum(r.success for r in results)
    return (f"  {label:7s} arrived {arrived}/{len(results)}  fixes {sum(r.position_fixes for r in results):4d}  "
            f"dropouts {sum(r.dropouts for r in results):4d}  rejected {sum(r.rejected for r in results):3d}  "
            f"median fix error {np.median(err) if len(err) else float('nan'):.3f} m  "
            f"NEES {np.mean([r.metrics['nees'] for r in results]):.2f}  "
            f"outside 3σ {np.mean([r.metrics['outside_3sigma'] for r in results]):.3f}  "
            f"{seconds / max(len(results), 1):.1f} s/trial")


def main(trials: int, every: int, paths, seed: int) -> None:
    sc = safenav.default_scenario()
    sweep = runner.Sweep(sc, trials=trials, seed=seed)
    total = {k: 0 for k in ("frames", "fixes_windows", "fixes_whole", "markers_windows", "markers_whole", "missed",
                            "false_windows", "false_whole")}
    samples = {k: [] for k in ("error", "nees", "range", "s_windows", "s_whole", "s_compare")}
    for name in paths:
        path = np.asarray(nv.plan_safe_path(sc, name).path)
        nav = nv.make_navigator(sc, path, method="centroid", position_every=every, record=True)
        seeds = runner.trial_seeds(seed, sweep.path_index(name), trials)
        before, after = [], []
        t0 = time.perf_counter()
        for s in seeds:
            before.append(nav.run(int(s), position=CameraLoopSource.from_scenario(sc, seed=int(s) % 2**32)))
        t1 = time.perf_counter()
        compare = 0.0
        for s in seeds:
            src = CameraFrames.from_scenario(sc, seed=int(s) % 2**32, compare_whole_frame=True)
            after.append(src.run(nav, int(s)))
            for k in total:
                total[k] += src.comparison[k]
            for k in samples:
                samples[k] += src.samples[k]
            compare += sum(src.samples["s_compare"])
        t2 = time.perf_counter()
        print(f"{name}: {trials} trials, a frame every {every} steps")
        print(_row("before", before, t1 - t0))
        print(_row("after", after, t2 - t1 - compare))
    c = total
    print(f"windows from the estimate vs whole frame, same {c['frames']} frames: fixes {c['fixes_windows']} vs "
          f"{c['fixes_whole']} ({100 * (c['fixes_windows'] / max(c['fixes_whole'], 1) - 1):+.1f} %), markers "
          f"{c['markers_windows']} vs {c['markers_whole']}, missed by the windows {c['missed']}, false detections "
          f"{c['false_windows']} vs {c['false_whole']}")
    e, n, rg = (np.asarray(samples[k]) for k in ("error", "nees", "range"))
    near = rg <= 20.0
    if len(e):
        print(f"windows' fixes: median error {np.median(e):.3f} m (all), {np.median(e[near]) if near.any() else np.nan:.3f}"
              f" m (landmarks within 20 m, {near.sum()} fixes); NEES mean {n.mean():.2f}, median {np.median(n):.2f} "
              f"(2 for a calibrated 2-D fix)")
    for k, label in (("s_windows", "windows"), ("s_whole", "whole frame")):
        v = np.asarray(samples[k]) * 1e3
        if len(v):
            print(f"front end ms per frame, {label}: median {np.median(v):.1f}, p95 {np.percentile(v, 95):.1f}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=2)
    ap.add_argument("--every", type=int, default=10)
    ap.add_argument("--paths", nargs="+", default=["P1", "P2", "P3"])
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    main(a.trials, a.every, a.paths, a.seed)

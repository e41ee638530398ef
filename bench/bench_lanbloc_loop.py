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
  the localizer plans windows from its own prediction, the front end draws what it reads of those
  regions (ground and background included) and searches them, and the fix goes through the
  localizer's gate.  Each of its frames is also rendered whole and searched without a prediction
  (``compare_whole_frame``): fixes, markers missed by the windows, false detections, the windows'
  fix error and NEES against the truth, and the front end's time per frame.  On that whole
  rendering the plan's windows are searched at the pyramid levels and at full resolution
  (``detect_side_px = 0``), and the Python region pipeline runs on the same pixels: markers found
  and missed, fix and corner differences, and the median time per frame of each.  And the plan's
  windows rendered at full resolution are searched beside the same windows drawn on demand at the
  detection levels, as the loop draws them: fixes, markers, the fixes' difference and the time per
  frame of each.

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


def main(trials: int, every: int, paths, seed: int, settings: dict | None = None) -> None:
    sc = safenav.default_scenario()
    sweep = runner.Sweep(sc, trials=trials, seed=seed)
    total: dict = {}
    samples: dict = {}
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
            src = CameraFrames.from_scenario(sc, seed=int(s) % 2**32, compare_whole_frame=True, **(settings or {}))
            after.append(src.run(nav, int(s)))
            for k, v in src.comparison.items():
                total[k] = total.get(k, 0) + v
            for k, v in src.samples.items():
                samples[k] = samples.get(k, []) + v
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
              f" m (landmarks within 20 m, {near.sum()} fixes); NEES mean {n.mean():.2f} (calibrated: 2 ± "
              f"{1.96 * 2 / np.sqrt(len(n)):.2f}), median {np.median(n):.2f} (1.39), beyond the χ² 95 / 99 / 99.9 % "
              f"quantiles {100 * np.mean(n > 5.99):.1f} / {100 * np.mean(n > 9.21):.1f} / {100 * np.mean(n > 13.82):.2f} %"
              f", max {n.max():.1f}")
    for k, label in (("s_windows", "windows"), ("s_whole", "whole frame")):
        v = np.asarray(samples[k]) * 1e3
        if len(v):
            print(f"front end ms per frame, {label}: median {np.median(v):.1f}, p95 {np.percentile(v, 95):.1f}")
    _levels(c, samples)
    _drawn(c, samples)


def _drawn(c: dict, samples: dict) -> None:
    """The plan's windows drawn on demand at the detection levels (the loop's pixels) against the same
    windows rendered at full resolution, and the time per frame of each."""
    if not samples.get("s_drawn"):
        return
    _compared("drawn on demand vs full-resolution windows", c, samples, ("drawn", "drawn"),
              ("windows", "full resolution"), "drawn_diff", ("error_drawn", "error"))
    t = {k: 1e3 * np.median(samples[k]) for k in ("s_drawn", "s_render_regions", "s_windows")}
    print(f"  median ms per frame: drawn and searched {t['s_drawn']:.2f}; rendered at full resolution "
          f"{t['s_render_regions']:.2f} + searched {t['s_windows']:.2f}")


def _compared(title: str, c: dict, samples: dict, a: tuple, b: tuple, diff: str, errors: tuple) -> None:
    """Fixes and markers of detector ``a`` = (key, label) against ``b`` on the same frames (``c``'s
    ``fixes_<key>`` and ``markers_<key>``, and ``missed_<a key>``, ``extra_<a key>``: found only by
    ``b``, only by ``a``), the two fixes' distance (``samples[diff]``) and each one's error."""
    (ka, la), (kb, lb) = a, b
    print(f"{title}, same {c['frames']} frames: fixes {c['fixes_' + ka]} vs {c['fixes_' + kb]}, markers "
          f"{c['markers_' + ka]} vs {c['markers_' + kb]} (found only by {lb} {c['missed_' + ka]}, only by {la} "
          f"{c['extra_' + ka]})")
    print(f"  |fix {la} - fix {lb}|: {_q(samples[diff], 'm')}")
    print(f"  fix error vs truth: {la} {_q(samples[errors[0]], 'm')}; {lb} {_q(samples[errors[1]], 'm')}")


def _q(v, unit: str) -> str:
    v = np.asarray(v)
    return (f"median {np.median(v):.3g} {unit}, p95 {np.percentile(v, 95):.3g}, max {v.max():.3g} (n = {len(v)})"
            if len(v) else "none")


def _levels(c: dict, samples: dict) -> None:
    """The plan's windows at the pyramid levels against full resolution and beside the Python region
    pipeline, on the same whole renderings."""
    if not samples.get("s_pyramid"):
        return
    _compared("pyramid levels vs full resolution in the same windows", c, samples, ("pyramid", "pyramid"),
              ("full_res", "full resolution"), "fix_diff", ("error_pyramid", "error_full_res"))
    print(f"  corner difference (both images): {_q(samples['corner_diff'], 'px')}")
    t = {k: 1e3 * np.median(samples[k]) for k in ("s_pyramid", "s_full_res", "s_python")}
    print(f"  median ms per frame: C++ pyramid {t['s_pyramid']:.2f}, C++ full resolution {t['s_full_res']:.2f}, "
          f"Python region pipeline {t['s_python']:.2f} (regions from the truth); Python / C++ pyramid "
          f"{t['s_python'] / t['s_pyramid']:.1f}x, full / pyramid {t['s_full_res'] / t['s_pyramid']:.1f}x")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=2)
    ap.add_argument("--every", type=int, default=10)
    ap.add_argument("--paths", nargs="+", default=["P1", "P2", "P3"])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--detect-side-px", type=float, default=None,
                    help="the front end's detect_side_px (default: its own; 0 = full resolution)")
    a = ap.parse_args()
    main(a.trials, a.every, a.paths, a.seed,
         {} if a.detect_side_px is None else {"detect_side_px": a.detect_side_px})

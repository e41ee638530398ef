"""Benchmark of ``safenav experiment all`` (the paper's evidence, end to end).

1. Wall time of every experiment at the paper's 1000 trials per cell on this
   machine, with LanBLoc at the measurement level (the camera-loop variants
   timed apart).
2. The camera-in-the-loop variants (LanBLoc rendered, detected, ranged by SGBM
   and trilaterated) at ``--camera-trials`` per cell, and the wall time that
   1000 trials per cell would take, extrapolated linearly (trials are
   independent and equally long on average).
3. The paper's PF rows: its PF took 185-199 s per trial on the real-imitated
   set (Table II) and 9.6-10.1 s on the synthetic set (Table I); ours, median
   per trial, beside them.

The run also writes the full report (``<out>/report.html``) and every table
and figure: this is how the README's numbers were made.

    python bench/bench_experiments.py [--trials 1000] [--camera-trials 20] [--out out/bench_experiments]
"""

from __future__ import annotations

import argparse
import os
import time

import pandas as pd

from safenav import experiments as ex


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=1000)
    ap.add_argument("--camera-trials", type=int, default=20)
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--out", default="out/bench_experiments")
    args = ap.parse_args()

    opts = ex.ExperimentOptions(trials=args.trials, camera_trials=args.camera_trials,
                                       particles=args.particles, workers=args.workers, out=args.out)
    t0 = time.perf_counter()
    results = ex.run_experiments(["all"], opts, show=lambda *a: None)
    report = ex.write_report(results, opts)
    total = time.perf_counter() - t0
    cores = args.workers or os.cpu_count()

    print(f"safenav experiment all: {args.trials} trials per cell, {args.camera_trials} camera-loop trials per "
          f"cell, PF {args.particles} particles, {cores} workers")
    print(f"{'experiment':<16}{'wall s':>10}{'of which camera s':>20}{'measurement-level s':>22}")
    cam_total = 0.0
    for r in results:
        cam_total += r.camera_s
        print(f"{r.name:<16}{r.wall_s:>10.1f}{r.camera_s:>20.1f}{r.wall_s - r.camera_s:>22.1f}")
    print(f"{'total':<16}{total:>10.1f}{cam_total:>20.1f}{total - cam_total:>22.1f}  (report written: {report})")
    if args.camera_trials:
        scale = args.trials / args.camera_trials
        print(f"camera loop at {args.trials} trials per cell (extrapolated x{scale:g} from {args.camera_trials}): "
              f"{cam_total * scale / 3600:.1f} h; whole `experiment all` with it: "
              f"{(total - cam_total + cam_total * scale) / 3600:.1f} h")

    syn = pd.read_parquet(opts.out / "synthetic" / "trials.parquet")
    real = pd.read_parquet(opts.out / "real-imitated" / "trials.parquet")
    print("\nPF rows: median time per trial, ours beside the paper's")
    print(f"{'method':<28}{'set':<15}{'ours ms':>10}{'paper ms':>12}{'paper / ours':>14}")
    for src in ex.PAPER_SOURCES:
        label = ex.source_label(src)
        for name, df, paper, col in (("synthetic", syn, ex.PAPER_TABLE1, "ms_per_trial"),
                                     ("real-imitated", real, ex.PAPER_TABLE2, "time_ms")):
            ours = df[(df["source"] == src) & (df["filter"] == "pf")][col].median()
            p = paper[(src, "pf")][3]
            print(f"{label:<28}{name:<15}{ours:>10.2f}{p:>12.0f}{p / ours:>14.0f}")
    steps = real[real["filter"] == "pf"]["steps"].median()
    us = real[real["filter"] == "pf"]["time_per_step_us"].median()
    print(f"(real-imitated PF: {steps:.0f} steps per trial, {us:.1f} µs per step, {args.particles} particles)")
    held = [c for r in results for c in r.claims]
    print(f"\nthe paper's claims: {sum(c.holds is True for c in held)} hold, {sum(c.holds is False for c in held)} "
          f"do not, {sum(c.holds is None for c in held)} not comparable (see the report)")


if __name__ == "__main__":
    main()

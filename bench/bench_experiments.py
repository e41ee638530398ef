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

``--camera-only`` runs the camera-in-the-loop cells alone (the three that ``experiment all``
runs: SafeNav-Centroid with the EKF and with the PF, SafeNav-CHull with the EKF, a frame every
``--camera-every`` steps, on every path type) at ``--camera-trials`` per cell, and prints the
time per trial per cell and the wall time that 1000 trials per cell would take on
``--workers`` processes, extrapolated linearly from these trials::

    python bench/bench_experiments.py --camera-only --camera-trials 4 --workers 2
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
    ap.add_argument("--camera-only", action="store_true")
    ap.add_argument("--camera-every", type=int, default=ex.ExperimentOptions.camera_position_every)
    args = ap.parse_args()
    if args.camera_only:
        camera_only(args)
        return

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


# Trials per chunk of work, as `safenav experiment` runs its camera cells (experiments/run.py).
CAMERA_CHUNK = 10


def camera_only(args) -> None:
    """The camera-loop cells of ``experiment all`` alone, timed per trial, and the extrapolation."""
    import safenav
    from safenav import runner

    sc = safenav.default_scenario()
    workers = args.workers or os.cpu_count()
    safe = runner.plan_safe_paths(sc)
    frames = []
    t0 = time.perf_counter()
    for methods, filters in ((("centroid",), ("ekf", "pf")), (("chull",), ("ekf",))):
        sweep = runner.Sweep(sc, methods=methods, filters=filters, sources=("lanbloc-camera",),
                             trials=args.camera_trials, n_particles=args.particles,
                             position_every=args.camera_every, chunk=CAMERA_CHUNK)
        frames.append(runner.run_sweep(sweep, workers=workers, safe_paths=safe))
    wall = time.perf_counter() - t0
    raw = pd.concat(frames, ignore_index=True)
    cells = raw.groupby(["path_type", "method", "filter"], sort=False)
    print(f"camera loop, {args.camera_trials} trials per cell, a frame every {args.camera_every} steps, "
          f"{workers} worker processes: {len(raw)} trials in {wall:.1f} s")
    print(f"{'path':<6}{'method':<10}{'filter':<8}{'median s/trial':>16}{'mean s/trial':>14}{'arrived':>12}"
          f"{'fixes/trial':>13}")
    for (p, m, f), g in cells:
        arrived = f"{int(g['success'].sum())}/{len(g)}"
        print(f"{p:<6}{m:<10}{f:<8}{g['time_ms'].median() / 1e3:>16.2f}{g['time_ms'].mean() / 1e3:>14.2f}"
              f"{arrived:>12}{g['position_fixes'].mean():>13.1f}")
    n_cells = cells.ngroups
    mean_s = raw["time_ms"].mean() / 1e3
    print(f"mean {mean_s:.2f} s per trial (in the worker), wall {wall / len(raw):.2f} s per trial on {workers} "
          f"workers; 1000 trials per cell ({n_cells} cells): {wall / len(raw) * 1000 * n_cells / 60:.0f} min "
          f"extrapolated from the wall time, {mean_s * 1000 * n_cells / workers / 60:.0f} min from the mean trial "
          f"time (target: 30 min on 2 cores)")


if __name__ == "__main__":
    main()

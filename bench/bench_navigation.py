"""Navigation benchmark (SafeNav V-D, Tables IV-V of the extended paper).

1. Time per trial and per step of SafeNav-CHull and SafeNav-Centroid
   (LanBLoc-BMM(EKF), C++ loop) on each path type of the default scenario,
   beside the paper's times per trial (CHull 15.25 ms, Centroid 16.88 ms on
   average, Python on an i7-11th gen; trial length not stated).
2. Beside a plain-Python/NumPy implementation of the same Centroid loop (BMM,
   EKF with position and IMU updates, nearest centroid ahead) run in this
   process on the same path: the ratio per step, medians of repeats.
3. Wall time of a whole sweep: TRIALS trials × 3 path types × 2 methods on all
   local cores, and the accuracy table beside the paper's.

    python bench/bench_navigation.py [--trials 1000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np

import safenav
from safenav import navigation as nv
from safenav import runner
from safenav.experiments import navigation_table, percent_error_table


def python_centroid_trial(path, centroids, centroid_s, bmm, lanbloc_std, imu_std, n_steps, seed):
    """The Centroid loop in plain Python + NumPy (what a Python implementation
    like the paper's does per step): BMM truth, EKF predict/update, control."""
    rng = np.random.default_rng(seed)
    dt, a, d, vmax, m = bmm.dt, bmm.acceleration, bmm.deceleration, bmm.max_speed, bmm.max_heading_rate
    seg = np.diff(path, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    cum = np.r_[0.0, np.cumsum(seg_len)]

    def arc(p):
        t = np.clip(np.einsum("ij,ij->i", p - path[:-1], seg) / seg_len**2, 0, 1)
        foot = path[:-1] + t[:, None] * seg
        i = np.argmin(np.linalg.norm(foot - p, axis=1))
        return cum[i] + t[i] * seg_len[i]

    def f(x, u):
        v = min(x[2] + a * dt, u[0], vmax) if u[0] > x[2] else max(x[2] - d * dt, u[0], 0.0)
        th = x[3] + np.clip(u[1], -m * dt, m * dt)
        return np.array([x[0] + v * dt * math.cos(th), x[1] + v * dt * math.sin(th), v, th])

    def F(x, u):
        v1 = f(x, u)[2]
        th = x[3] + np.clip(u[1], -m * dt, m * dt)
        J = np.eye(4)
        J[0, 3], J[1, 3] = -v1 * dt * math.sin(th), v1 * dt * math.cos(th)
        return J

    Q = np.diag([bmm.position_noise**2] * 2 + [bmm.speed_noise**2, bmm.heading_noise**2])
    R = np.diag(np.r_[np.square(lanbloc_std), np.square(imu_std)])
    H = np.eye(4)
    t = path[1] - path[0]
    x = np.array([*path[0], 0.0, math.atan2(t[1], t[0])])
    xe, P = x.copy(), np.diag([0.01, 0.01, 0.01, 0.01])
    for _ in range(n_steps):
        s = arc(xe[:2])
        ahead = centroid_s > s
        c = centroids[ahead][np.argmin(np.linalg.norm(centroids[ahead] - xe[:2], axis=1))] if ahead.any() else path[-1]
        dth = (math.atan2(c[1] - xe[1], c[0] - xe[0]) - xe[3] + math.pi) % (2 * math.pi) - math.pi
        u = np.array([2.0, dth])
        x = f(x, u) + rng.normal(0, np.sqrt(np.diag(Q)))
        Fk = F(xe, u)
        xe = f(xe, u)
        P = Fk @ P @ Fk.T + Q
        z = np.r_[x[:2] + rng.normal(0, lanbloc_std), x[2:] + rng.normal(0, imu_std)]
        y = z - H @ xe
        y[3] = (y[3] + math.pi) % (2 * math.pi) - math.pi
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        xe = xe + K @ y
        IKH = np.eye(4) - K @ H
        P = IKH @ P @ IKH.T + K @ R @ K.T
    return xe


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    sc = safenav.default_scenario()
    t0 = time.perf_counter()
    safe = runner.plan_safe_paths(sc)
    print(f"planning the 3 safe paths (RAw-RRT*, {sc.navigation.plan_iterations} iterations each): "
          f"{time.perf_counter() - t0:.2f} s")

    print("\n1-2. time per trial (median of 20 trials x repeats), C++ loop, LanBLoc-BMM(EKF)")
    print(f"{'path':5} {'method':9} {'steps':>6} {'ms/trial':>9} {'µs/step':>8} {'paper ms':>9} "
          f"{'Python µs/step':>15} {'ratio':>7}")
    paper = {"chull": 15.25, "centroid": 16.88}
    for name, path in safe.items():
        for method in ("chull", "centroid"):
            navigator = nv.make_navigator(sc, path, method=method, record=False)
            seeds = [int(s) for s in runner.trial_seeds(0, 0, 20)]
            per_trial, per_step, steps = [], [], 0
            for _ in range(args.repeats):
                t = time.perf_counter()
                d = navigator.run_many(seeds)
                el = time.perf_counter() - t
                steps = float(np.mean(d["steps"]))
                per_trial.append(el / len(seeds) * 1e3)
                per_step.append(el / d["steps"].sum() * 1e6)
            py = ""
            if method == "centroid":
                segs = navigator.segments
                n = 200
                times = []
                for r in range(max(1, args.repeats // 2)):
                    t = time.perf_counter()
                    python_centroid_trial(np.asarray(path), np.asarray(segs.centroids),
                                          np.asarray(segs.centroid_arc_lengths), sc.bmm_params(),
                                          np.asarray(sc.noise.lanbloc_std),
                                          np.array([sc.noise.imu_speed_std, sc.noise.imu_heading_std]), n, r)
                    times.append((time.perf_counter() - t) / n * 1e6)
                py_step = float(np.median(times))
                py = f"{py_step:15.1f} {py_step / np.median(per_step):6.0f}x"
            print(f"{name:5} {method:9} {steps:6.0f} {np.median(per_trial):9.3f} {np.median(per_step):8.2f} "
                  f"{paper[method]:9.2f} {py}")

    print(f"\n3. sweep: {args.trials} trials x 3 path types x 2 methods, {os.cpu_count()} cores")
    sweep = runner.Sweep(sc, trials=args.trials, seed=0)
    t = time.perf_counter()
    raw = runner.run_sweep(sweep, safe_paths=safe)
    wall = time.perf_counter() - t
    print(f"wall time {wall:.2f} s for {len(raw)} trials ({raw.steps.sum():.3g} steps); "
          f"success {raw.success.mean():.3f}; outcomes {raw.outcome.value_counts().to_dict()}")
    summary = runner.summarize(raw)
    fmt = lambda v: f"{v:.3g}"  # noqa: E731
    print(percent_error_table(summary).to_string(index=False, float_format=fmt))
    print(navigation_table(summary).to_string(index=False, float_format=fmt))


if __name__ == "__main__":
    main()

"""Benchmark: ``safenav replay`` on real-like logs beside a plain unicycle EKF.

For each seed, :func:`safenav.reallike.reallike_log` makes a log (commanded
v, ω at 67 Hz with scale, bias and noise; a forward camera's range+bearing
rows; truth).  Then

1. the online localizer (``safenav replay``'s default preset, started from the
   data alone; its motion model is the unicycle form, ``bmm.unicycle``) replays it: the start time after the first sighting of any
   landmark and of a second one, and the causal RMSE against the truth;
2. a plain 3-state unicycle EKF (x, y, θ) in numpy, written here and not in
   the library, runs on the same rows with the generator's *true* noise:
   the commanded (v, ω) propagate it, with process noise from the speed and
   turn noise plus the variance of the scale errors and the turn bias
   (treated as white), and each range+bearing row updates it with the row's
   σ.  It is started at the localizer's start time from the true pose with a
   small prior (a head start the localizer does not get), and scored on the
   same truth rows.

   The last RMSE column is the same replay with the paper's eq. 3 (speed in
   [0, v_max], reached at a·Δt per step) in place of the unicycle form.

    python bench/bench_reallike.py [--seeds 0 1 2] [--reverse-share 0.5 --duration 90]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from safenav import replay as rp
from safenav.reallike import RealLikeConfig, first_sighting, reallike_log


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def unicycle_ekf(log, cfg: RealLikeConfig, t0: float, x0: np.ndarray) -> np.ndarray:
    """(t, x, y) after each motion row from t0 on: predict with the commanded
    (v, ω) (heading first, then position), update with each range+bearing row."""
    ev = log.events[log.events["t"] > t0]
    lm = log.landmarks
    x = x0.astype(float).copy()
    P = np.diag([0.05, 0.05, 0.02]) ** 2
    t_prev = t0
    out = []
    for row in ev.itertuples(index=False):
        if row.kind == "motion":
            dt = row.t - t_prev
            t_prev = row.t
            v, w = row.speed, row.heading_change / dt if dt > 0 else 0.0
            moving = v != 0.0 or w != 0.0
            var_v = (cfg.speed_scale_std * v) ** 2 + (cfg.speed_noise ** 2 if moving else 0.0)
            var_w = (cfg.turn_scale_std * w) ** 2 + ((cfg.turn_bias_std ** 2 + cfg.turn_noise ** 2) if moving else 0.0)
            th = x[2] + w * dt
            c, s = math.cos(th), math.sin(th)
            F = np.array([[1, 0, -v * dt * s], [0, 1, v * dt * c], [0, 0, 1]])
            G = np.array([[dt * c, -v * dt * dt * s], [dt * s, v * dt * dt * c], [0, dt]])
            x = np.array([x[0] + v * dt * c, x[1] + v * dt * s, wrap(th)])
            P = F @ P @ F.T + G @ np.diag([var_v, var_w]) @ G.T
            out.append((row.t, x[0], x[1]))
        elif row.kind == "range_bearing":
            ax, ay = lm[int(row.landmark)]
            dx, dy = ax - x[0], ay - x[1]
            q = dx * dx + dy * dy
            r = math.sqrt(q)
            H = np.array([[-dx / r, -dy / r, 0], [dy / q, -dx / q, -1]])
            y = np.array([row.range - r, wrap(row.bearing - (math.atan2(dy, dx) - x[2]))])
            S = H @ P @ H.T + np.diag([row.range_std ** 2, row.bearing_std ** 2])
            K = P @ H.T @ np.linalg.inv(S)
            x = x + K @ y
            x[2] = wrap(x[2])
            P = (np.eye(3) - K @ H) @ P
    return np.array(out)


def rmse_at_truth(est: np.ndarray, truth, t_from: float) -> float:
    """Causal RMSE: each truth row from t_from on against the latest estimate at or before it."""
    tt = truth[truth["t"] >= t_from]
    j = np.searchsorted(est[:, 0], tt["t"].to_numpy() + 1e-9, side="right") - 1
    ok = j >= 0
    e = est[j[ok], 1:3] - tt[["x", "y"]].to_numpy()[ok]
    return float(np.sqrt((e ** 2).sum(axis=1).mean()))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--reverse-share", type=float, default=0.0, help="RealLikeConfig.reverse_share (backing up)")
    ap.add_argument("--duration", type=float, default=RealLikeConfig.duration, help="[s] length of each run")
    args = ap.parse_args()
    cfg = RealLikeConfig(reverse_share=args.reverse_share, duration=args.duration)
    eq3 = rp.preset_settings("default")
    eq3.bmm.unicycle = False          # the paper's eq. 3: speed in [0, v_max], a·Δt per step
    print(f"{'seed':>4} {'1st sight':>9} {'2nd lm':>7} {'start':>7} {'start-2nd':>9} {'replay RMSE':>11} "
          f"{'NEES':>5} {'EKF RMSE':>9} {'eq. 3 RMSE':>10} {'replay s':>8}")
    for seed in args.seeds:
        log = reallike_log(seed, cfg)
        t1, t2 = first_sighting(log), first_sighting(log, distinct=2)
        clock = time.perf_counter()
        res = rp.replay(log)
        wall = time.perf_counter() - clock
        if not res.estimated:
            print(f"{seed:>4} {t1:9.2f} {t2:7.2f} never started: {res.reason}")
            continue
        tr = log.truth
        th = np.unwrap(tr["heading"].to_numpy())
        x0 = np.array([np.interp(res.t_start, tr["t"], tr["x"]), np.interp(res.t_start, tr["t"], tr["y"]),
                       wrap(np.interp(res.t_start, tr["t"], th))])
        ekf = unicycle_ekf(log, cfg, res.t_start, x0)
        m = res.metrics
        paper = rp.replay(log, settings=eq3).metrics.get("truth_rmse", float("nan"))
        print(f"{seed:>4} {t1:9.2f} {t2:7.2f} {res.t_start:7.2f} {res.t_start - t2:9.2f} "
              f"{m['truth_rmse']:9.3f} m {m['nees']:5.2f} {rmse_at_truth(ekf, tr, res.t_start):7.3f} m "
              f"{paper:8.3f} m {wall:8.2f}")


if __name__ == "__main__":
    main()

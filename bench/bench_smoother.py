"""Benchmark: the fixed-lag smoothers (RTS and iterated) beside the causal
filter on Plaza1 and Plaza2 (gtsam's copies; ``plaza`` preset, started from
the data; odometry along the arc by default, ``--odometry-heading end`` for
the heading after the step).

For each file and lag it prints the causal RMSE, the smoothed RMSE (label
"fixed-lag L s") against the targets (a GTSAM fixed-lag smoother with a 2 s
lag: 0.30 m on Plaza1, 0.27 m on Plaza2; ours: ≤ 0.25 m on Plaza1, ≤ 0.27 m on
Plaza2 with lag 2 s) and the smoother's cost per input: the replay time with
the lag minus the replay time without it (median of ``--repeats``; the Python
loop's cost is the same in both and cancels), over the log's inputs.  Plaza1
was used to tune the ``plaza`` preset; Plaza2 is held out.

    python bench/bench_smoother.py [--lags 0 1 2 4] [--smoothers rts iterated] [--iterations 1] [--repeats 5]
                                   [--odometry-heading mid|end]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_late import timed_replay  # noqa: E402  (the one timing loop of the replay benchmarks)

from safenav import replay as rp  # noqa: E402

TARGETS = {"Plaza1_.mat": 0.25, "Plaza2_.mat": 0.27}   # RMSE with a 2 s lag [m]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lags", type=float, nargs="+", default=[0.0, 1.0, 2.0, 4.0])
    ap.add_argument("--smoothers", nargs="+", choices=["rts", "iterated"], default=["rts", "iterated"])
    ap.add_argument("--iterations", type=int, nargs="+", default=[1],
                    help="Gauss-Newton passes per output of the iterated smoother (each a row)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--odometry-heading", choices=rp.ODOMETRY_HEADINGS, default=rp.PLAZA_ODOMETRY_HEADING,
                    help="where an odometry row's heading change happens (docs/replay.md, 'Odometry along the arc')")
    args = ap.parse_args()
    import gtsam

    data = Path(gtsam.__file__).parent / "Data"
    for name, target in TARGETS.items():
        path = data / name
        if not path.exists():
            print(f"{name}: not in this gtsam wheel")
            continue
        log = rp.load(path, range_std=rp.PLAZA_RANGE_STD)
        settings = rp.preset_settings("plaza")
        n = len(log.events)
        causal, t_causal = timed_replay(log, settings, args.repeats, odometry_heading=args.odometry_heading)
        print(f"{name}: {n} inputs; causal RMSE {causal.metrics['truth_rmse']:.4f} m "
              f"({causal.metrics['n_scored']} poses), replay {t_causal * 1e6 / n:.2f} us/input")
        variants = [(k, it) for k in args.smoothers for it in (args.iterations if k == "iterated" else [1])]
        for smoother, iterations in variants:
            name = smoother if smoother == "rts" else f"iterated x{iterations}"
            for lag in args.lags:
                r, t = timed_replay(log, settings, args.repeats, lag=lag, smoother=smoother, iterations=iterations,
                                    odometry_heading=args.odometry_heading)
                m = r.smoothed_metrics
                met = "met" if m["truth_rmse"] <= target else "MISSED"
                verdict = f" (target <= {target} m: {met})" if lag == 2.0 else ""
                print(f"  {name:>12} {m['label']:>14}: RMSE {m['truth_rmse']:.4f} m{verdict}, "
                      f"ADE {m['truth_ade']:.4f} m, NEES {m['nees']:.2f}; smoother "
                      f"{(t - t_causal) * 1e6 / n:+.2f} us/input (target <= 20)")


if __name__ == "__main__":
    main()

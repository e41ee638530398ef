"""Benchmark: late measurements on Plaza1 (``LocalizerSettings.max_delay``).

Every range of Plaza1 is delivered late by a uniform 0–``--max-delay-ms``
delay (motion rows on time) and replayed causally with the ``plaza`` preset
(started from the data; odometry along the arc unless ``--odometry-heading end``):

1. with the default ``max_delay`` = 0.5 s: late ranges are applied at their
   own time (the inputs since applied again);
2. with ``max_delay`` = 0: late ranges are dropped (the behaviour before).

It prints the causal RMSE, the ranges applied and late, and the replay time
against the in-order replay in the same process (median of ``--repeats``).

    python bench/bench_late.py [--seeds 0 1 2] [--max-delay-ms 300] [--odometry-heading mid|end]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from safenav import replay as rp
from safenav.logs import plaza1_path


def timed_replay(log, settings, repeats, **options):
    """(result, median wall time [s]) of ``repeats`` replays with ``options`` (delays=, lag=)."""
    times, res = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = rp.replay(log, settings, **options)
        times.append(time.perf_counter() - t0)
    return res, statistics.median(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--max-delay-ms", type=float, default=300.0)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--odometry-heading", choices=rp.ODOMETRY_HEADINGS, default=rp.PLAZA_ODOMETRY_HEADING,
                    help="where an odometry row's heading change happens (docs/replay.md, 'Odometry along the arc')")
    args = ap.parse_args()
    oh = args.odometry_heading
    log = rp.load(plaza1_path(), range_std=rp.PLAZA_RANGE_STD)
    on = rp.preset_settings("plaza")
    off = rp.preset_settings("plaza")
    off.max_delay = 0.0
    ranges = log.events["kind"].isin(["range", "bearing", "range_bearing"]).to_numpy()
    ref, t_ref = timed_replay(log, on, args.repeats, odometry_heading=oh)
    print(f"Plaza1, causal, started from the data, odometry heading {oh}; in time order: RMSE {ref.metrics['truth_rmse']:.3f} m, "
          f"{ref.counts['applied']} applied, replay {t_ref * 1e3:.0f} ms")
    print(f"ranges delayed uniformly by 0-{args.max_delay_ms:g} ms:")
    print(f"{'seed':>4} {'max_delay':>9} {'RMSE':>8} {'applied':>7} {'late':>5} {'replay ms':>9} {'x in order':>10}")
    for seed in args.seeds:
        d = np.where(ranges, np.random.default_rng(seed).uniform(0, args.max_delay_ms / 1e3, len(ranges)), 0.0)
        for label, s in (("0.5 s", on), ("0", off)):
            res, t = timed_replay(log, s, args.repeats, delays=d, odometry_heading=oh)
            print(f"{seed:>4} {label:>9} {res.metrics['truth_rmse']:6.3f} m {res.counts['applied']:>7} "
                  f"{res.counts['late']:>5} {t * 1e3:9.0f} {t / t_ref:9.2f}x")


if __name__ == "__main__":
    main()

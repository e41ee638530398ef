"""Benchmark: replaying a ROS 2 bag (MCAP) against replaying the same log from CSV.

A real-like log (:func:`safenav.reallike.reallike_log`) long enough to make
about 1e5 messages (odometry twists at 67 Hz, a Range and a bearing per
sighting, truth at 20 Hz) is written as a rosbag2 folder with MCAP storage
(:func:`safenav.bags_write.write_bag`) and as a CSV log
(:func:`safenav.logs.write_log`).  Timed, best of ``--repeat``:

* bag: :func:`safenav.bags.read_bag` (``--odom-twist``) + :func:`safenav.replay.replay`;
* CSV: :func:`safenav.logs.read_log` + :func:`safenav.replay.replay`.

The target is read + replay of the bag in at most 5 s.  The two replays'
RMSEs are printed too (they agree to float32 rounding).

    python bench/bench_bags.py [--messages 100000] [--repeat 3] [--storage mcap|sqlite3]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from safenav import bags
from safenav import replay as rp
from safenav.bags_write import write_bag
from safenav.logs import read_log, write_log
from safenav.reallike import RealLikeConfig, reallike_log


def messages_per_second(log) -> float:
    """Messages a bag of ``log`` holds per second of log: one per motion row (plus one), per range, per
    bearing (two per range_bearing row), per truth row."""
    kinds = log.events["kind"]
    n = len(kinds) + (kinds == "range_bearing").sum() + 1 + (0 if log.truth is None else len(log.truth))
    return n / float(log.events["t"].iloc[-1])


def best(fn, repeat: int):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--messages", type=int, default=100_000)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--storage", choices=["mcap", "sqlite3"], default="mcap")
    args = p.parse_args(argv)

    rate = messages_per_second(reallike_log(0, RealLikeConfig(duration=60.0)))
    log = reallike_log(0, RealLikeConfig(duration=args.messages / rate))
    with tempfile.TemporaryDirectory() as tmp:
        bag, csv = Path(tmp) / "bag", Path(tmp) / "run.csv"
        t0 = time.perf_counter()
        write_bag(log, bag, storage=args.storage)
        t_write = time.perf_counter() - t0
        write_log(log, csv)
        from rosbags.highlevel import AnyReader

        with AnyReader([bag]) as r:
            n_msgs = r.message_count
        size = sum(f.stat().st_size for f in bag.iterdir())

        def from_bag():
            g = bags.read_bag(bag, odom_twist=True)
            return g, rp.replay(g)

        def from_csv():
            g = read_log(csv)
            return g, rp.replay(g)

        t_read, g_bag = best(lambda: bags.read_bag(bag, odom_twist=True), args.repeat)
        t_bag, (_, r_bag) = best(from_bag, args.repeat)
        t_csv, (g_csv, r_csv) = best(from_csv, args.repeat)
    print(f"real-like log, {log.events['t'].iloc[-1]:.0f} s: {len(log.events)} inputs, {len(log.truth)} truth rows; "
          f"bag ({args.storage}): {n_msgs} messages, {size / 1e6:.1f} MB, written in {t_write:.2f} s")
    print(f"bag: read {t_read:.2f} s, read + replay {t_bag:.2f} s (target <= 5 s: "
          f"{'met' if t_bag <= 5.0 else 'NOT met'})")
    print(f"CSV: read + replay {t_csv:.2f} s; bag / CSV = {t_bag / t_csv:.2f}")
    print(f"RMSE: bag {r_bag.metrics['truth_rmse']:.6f} m, CSV {r_csv.metrics['truth_rmse']:.6f} m, "
          f"difference {abs(r_bag.metrics['truth_rmse'] - r_csv.metrics['truth_rmse']):.2e} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Benchmark: ``safenav tune`` on real-like logs, judged on a held-out seed.

For each seed k, :func:`safenav.reallike.reallike_log` makes a log; the noise
is tuned on seed k (:func:`safenav.tune.tune`, truth-based and, again,
innovation-only with the truth rows dropped), and seed k + 1 is replayed with

1. the ``default`` preset (the log's own σ, the default process noise);
2. the preset tuned on seed k, truth-based;
3. the preset tuned on seed k, innovation-only;
4. with ``--runs N`` (N > 1), the preset tuned truth-based on N runs
   together: seeds k, k + 100, …, k + 100·(N − 1);
5. the plain 3-state unicycle EKF of ``bench/bench_reallike.py`` (numpy,
   the generator's *true* noise, started at the replay's start from the
   true pose: a head start the localizer does not get), imported from there.

It prints the causal position RMSE and mean position NEES (2 if consistent)
per seed and their medians.

    python bench/bench_tune.py [--seeds 0 1 2 3 4] [--duration 120] [--evaluations 150] [--runs 2]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_reallike import rmse_at_truth, unicycle_ekf, wrap  # noqa: E402  (the plain EKF lives there)

from safenav import replay as rp  # noqa: E402
from safenav import tune as tn  # noqa: E402
from safenav.logs import Log  # noqa: E402
from safenav.reallike import RealLikeConfig, reallike_log  # noqa: E402


def plain_ekf_rmse(log, cfg, t_start: float) -> float:
    tr = log.truth
    th = np.unwrap(tr["heading"].to_numpy())
    x0 = np.array([np.interp(t_start, tr["t"], tr["x"]), np.interp(t_start, tr["t"], tr["y"]),
                   wrap(np.interp(t_start, tr["t"], th))])
    return rmse_at_truth(unicycle_ekf(log, cfg, t_start, x0), tr, t_start)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument("--evaluations", type=int, default=150)
    ap.add_argument("--runs", type=int, default=1, help="also tune on this many runs together (seeds k + 100 i)")
    args = ap.parse_args()
    cfg = RealLikeConfig(duration=args.duration)
    cols = ("default", "tuned (truth)", "tuned (innov.)") + ((f"tuned ({args.runs} runs)",) if args.runs > 1 else ())
    print(f"tune on seed k, replay seed k+1 ({args.duration:g} s logs); RMSE [m] / mean position NEES (2 if "
          "consistent); plain EKF = numpy unicycle EKF with the true noise")
    print(f"{'k':>2} " + " ".join(f"{c:>18}" for c in cols) + f" {'plain EKF':>10} {'tune s':>7}")
    table = {c: [] for c in (*cols, "plain")}
    for k in args.seeds:
        train, test = reallike_log(k, cfg), reallike_log(k + 1, cfg)
        clock = time.perf_counter()
        with_truth = tn.tune(train, max_evaluations=args.evaluations)
        blind = tn.tune(Log(landmarks=train.landmarks, events=train.events), max_evaluations=args.evaluations)
        presets = [(rp.preset_settings("default"), None), (with_truth.settings, with_truth.noise),
                   (blind.settings, blind.noise)]
        if args.runs > 1:
            more = [train] + [reallike_log(k + 100 * i, cfg) for i in range(1, args.runs)]
            several = tn.tune(more, max_evaluations=args.evaluations)
            presets.append((several.settings, several.noise))
        wall = time.perf_counter() - clock
        row = []
        for name, (s, n) in zip(cols, presets):
            c = tn.consistency(test, s, n)
            table[name].append((c.get("rmse", np.nan), c.get("nees", np.nan)))
            row.append(f"{c.get('rmse', np.nan):8.3f} / {c.get('nees', np.nan):6.2f}  ")
        start = rp.replay(test).t_start
        plain = plain_ekf_rmse(test, cfg, start)
        table["plain"].append((plain, plain))
        print(f"{k:>2} " + " ".join(f"{r:>18}" for r in row) + f" {plain:10.3f} {wall:7.1f}")
    med = {c: np.nanmedian(np.array(v), axis=0) for c, v in table.items()}
    print("med " + " ".join(f"{med[c][0]:8.3f} / {med[c][1]:6.2f}    " for c in cols) + f"{med['plain'][0]:8.3f}")


if __name__ == "__main__":
    main()

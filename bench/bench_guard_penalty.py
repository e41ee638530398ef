"""Where our loop's time penalty over the papers' loop comes from (docs/safety.md, "The guard").

The default world, clean measurements, P1-P3 x SafeNav-CHull / SafeNav-Centroid, the
papers' path (hazard_weight 0) driven by both loops with the same trial seeds as
bench/bench_safety.py.  Per cell: mean steps of each loop and the penalty
(ours / paper - 1), and our loop's extra steps split into
  * path:  (driven length ours - paper) / (cruise speed x dt): a longer true track;
  * hold:  steps commanded to speed 0 (looks, holds, the start of a back-up);
  * slow:  sum over moving steps of (1 - commanded speed / cruise speed);
  * rest:  what the three leave (acceleration after a stop, the BMM's speed limits);
and the guard's events per trial (slow, steer, hold, recover) and outcomes.

    python bench/bench_guard_penalty.py [--trials 50] [--guard-k K]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from safenav import navigation as nav
from safenav import runner
from safenav.scenario import default_scenario


def run(scenario, path, method: str, paper: bool, seeds: list[int]) -> dict:
    n = nav.make_navigator(scenario, path, method=method, record=True, paper=paper)
    cruise, dt = n.settings.cruise_speed, n.problem.bmm.dt
    rs = [n.run(s) for s in seeds]
    speeds = [np.asarray(r.controls)[:, 0] for r in rs]
    out = dict(
        steps=np.mean([r.steps for r in rs]),
        length=np.mean([np.sum(np.hypot(*np.diff(np.asarray(r.truth)[:, :2], axis=0).T)) for r in rs]),
        hold=np.mean([np.sum(v == 0) for v in speeds]),
        slow=np.mean([np.sum(1 - v[v > 0] / cruise) for v in speeds]),
        outcomes={},
        cruise_step=cruise * dt,
    )
    for k in ("guard_slow", "guard_steer", "guard_hold", "guard_recover"):
        out[k] = np.mean([getattr(r, k, 0) for r in rs])  # guard_recover: not in older builds
    for r in rs:
        out["outcomes"][r.outcome_name] = out["outcomes"].get(r.outcome_name, 0) + 1
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=50)
    ap.add_argument("--guard-k", type=float, default=None, help="our loop's k (default: from the risk budget)")
    args = ap.parse_args()
    sc = default_scenario()
    if args.guard_k is not None:
        sc = dataclasses.replace(sc, navigation=dataclasses.replace(sc.navigation, guard_k=args.guard_k))
    t0 = time.perf_counter()
    print(f"default world, clean, {args.trials} trials per cell; extra steps of ours split into path / hold / slow / rest")
    print(f"{'path':4} {'method':8} {'paper':>7} {'ours':>7} {'penalty':>8} | {'path':>6} {'hold':>6} {'slow':>6} "
          f"{'rest':>6} | {'slow/tr':>7} {'steer/tr':>8} {'hold/tr':>7} {'recov/tr':>8} | outcomes (ours)")
    total = {"paper": 0.0, "ours": 0.0}
    parts = np.zeros(4)
    for stream, pt in enumerate(p.name for p in sc.path_types[:3]):
        path = nav.plan_safe_path(sc, pt, paper=True).path
        seeds = [int(s) for s in runner.trial_seeds(sc.seeds.trials, stream, args.trials)]
        for method in ("chull", "centroid"):
            p = run(sc, path, method, True, seeds)
            o = run(sc, path, method, False, seeds)
            extra = o["steps"] - p["steps"]
            split = np.array([(o["length"] - p["length"]) / o["cruise_step"], o["hold"], o["slow"], 0.0])
            split[3] = extra - split[:3].sum()
            parts += split
            total["paper"] += p["steps"]
            total["ours"] += o["steps"]
            print(f"{pt:4} {method:8} {p['steps']:7.0f} {o['steps']:7.0f} {o['steps'] / p['steps'] - 1:+8.1%} | "
                  + " ".join(f"{v:6.0f}" for v in split)
                  + f" | {o['guard_slow']:7.1f} {o['guard_steer']:8.1f} {o['guard_hold']:7.1f} {o['guard_recover']:8.1f}"
                  + f" | {o['outcomes']}", flush=True)
    pen = total["ours"] / total["paper"] - 1
    share = parts / max(parts.sum(), 1e-9)
    print(f"time penalty (sum of mean steps, as bench_safety): {pen:+.1%}; extra steps: path {share[0]:.0%}, "
          f"hold {share[1]:.0%}, slow {share[2]:.0%}, rest {share[3]:.0%}; {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()

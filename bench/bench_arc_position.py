"""Benchmark ``safenav.belief.arc_position`` (the arc of each recorded
position along a belief profile: the calibration's binning) against the
search over every leg (``all_legs=True``), which it prunes exactly.

The polyline is the expected belief's stages along CHull's nominal run on the
default scenario's belief-planned P1 (a leg per BMM step, about 2 300), the
points the true positions of recorded navigation trials: what
``sigma_calibration`` bins in ``bench/bench_certified.py``.  Both run in one
process on the same inputs; it prints the median time of each over the
repeats, their ratio, and that the arcs are identical.

Run:
    python bench/bench_arc_position.py [--trials 10] [--repeats 5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from safenav import certify as C
from safenav import navigation as nav
from safenav import runner
from safenav.belief import arc_position, propagate_belief_along
from safenav.scenario import default_scenario


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=10, help="recorded trials whose positions are binned")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    sc = default_scenario()
    raw = np.asarray(C.plan_or_none(sc, "P1").path)
    (cert,), _ = C.certify_paths(sc, {"P1": raw}, planner="belief")
    path = np.asarray(cert.path)
    navigator = nav.make_navigator(sc, path, method="chull", filter="ekf", record=True)
    along = {k: v for k, v in C.mission_inputs(sc, path).items() if k != "speed"}
    stages = np.asarray(propagate_belief_along(navigator.nominal_trajectory(), **along).positions)
    seeds = runner.trial_seeds(sc.seeds.trials, 0, args.trials)
    points = np.vstack([np.asarray(navigator.run(int(s)).truth)[:, :2] for s in seeds])
    times = {"arc_position": [], "all legs": []}
    for _ in range(args.repeats):
        for name, every in (("arc_position", False), ("all legs", True)):
            t0 = time.perf_counter()
            out = arc_position(stages, points, all_legs=every)
            times[name].append(time.perf_counter() - t0)
            if name == "arc_position":
                ours = out
            else:
                same = np.array_equal(ours, out)
    med = {k: float(np.median(v)) for k, v in times.items()}
    print(f"{len(stages) - 1} legs, {len(points)} points ({args.trials} trials), {args.repeats} repeats")
    for k, v in med.items():
        print(f"  {k:12}: median {v * 1e3:8.1f} ms")
    print(f"  ratio (all legs / arc_position): {med['all legs'] / med['arc_position']:.1f}x; identical arcs: {same}")


if __name__ == "__main__":
    main()

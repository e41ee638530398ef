#!/usr/bin/env python
"""LanBLoc's C++ front end (``safenav._core.LanBLocFrontEnd``) beside the Python whole-frame
pipeline with corner ranging, on the same rendered pairs.

Run from the repository root::

    python bench/bench_lanbloc_cpp.py            # 100 frames
    python bench/bench_lanbloc_cpp.py --frames 20

Frames (seed 0): a random pose, 3-6 markers at 5-25 m within ±0.6 rad of the heading at
heights 1-4 m, 640×480 (f = 350 px, B = 0.3 m), pixel noise σ = 1.  Per frame: the Python
pipeline (pip's cv2), the C++ front end on the whole frame (OpenCV 4.6 with OpenCV >= 4.8's
corner-refinement window rule), the same with OpenCV 4.6's own refinement, and the C++ front
end with windows from the true pose (σ = 0.3 m, 2°).  Prints the agreement of ids, ranges,
bearings and fixes, the fixes' errors against the truth, and the median time per frame.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_lanbloc_cpp import RIG, _front_end  # noqa: E402  (the tests' rig → front end adapter)

from safenav.vision.lanbloc import LanBLoc  # noqa: E402
from safenav.vision.render import StereoRenderer  # noqa: E402
from safenav.world import Landmark, World  # noqa: E402


def _frame(rng, k):
    pose = (rng.uniform(40, 160), rng.uniform(40, 160), rng.uniform(-math.pi, math.pi))
    th = pose[2]
    fwd, right = np.array([math.cos(th), math.sin(th)]), np.array([math.sin(th), -math.cos(th)])
    lms = []
    for j in range(int(rng.integers(3, 7))):
        z = rng.uniform(5, 25)
        lat = z * math.tan(rng.uniform(-0.6, 0.6))
        lms.append(Landmark(j * 7 + int(rng.integers(0, 7)), (*(np.array(pose[:2]) + z * fwd + lat * right),
                                                              rng.uniform(1.0, 4.0)), "m", 1))
    world = World(landmarks=tuple(lms))
    return pose, world, StereoRenderer(world, RIG, noise_std=1.0, seed=k).render(pose)


def _q(v) -> str:
    v = np.asarray(v)
    return f"n={len(v)} median={np.median(v):.2e} p95={np.percentile(v, 95):.2e} max={v.max():.2e}" if len(v) else "n=0"


def main(frames: int) -> None:
    rng = np.random.default_rng(0)
    same = {"cpp": 0, "cpp46": 0}
    d = {k: [] for k in ("range", "range46", "bearing", "fix", "fix46", "windows", "err_py", "err_cpp", "err_win")}
    t = {k: [] for k in ("python", "cpp", "windows")}
    P = np.diag([0.3 ** 2, 0.3 ** 2, math.radians(2.0) ** 2])
    for k in range(frames):
        pose, world, (left, right) = _frame(rng, k)
        t0 = time.perf_counter()
        py = LanBLoc(world, RIG, ranging="corners").localize(left, right)
        t1 = time.perf_counter()
        fe = _front_end(world)
        cc = fe.localize(left, right)
        t2 = time.perf_counter()
        cw = fe.localize(left, right, np.array(pose), P)
        t3 = time.perf_counter()
        c46 = _front_end(world, relative_corner_refinement_win_size=0.0).localize(left, right)
        t["python"].append(t1 - t0), t["cpp"].append(t2 - t1), t["windows"].append(t3 - t2)
        ids = [o.landmark_id for o in py.observations]
        for name, res, dr, df in (("cpp", cc, "range", "fix"), ("cpp46", c46, "range46", "fix46")):
            if [o.landmark_id for o in res.observations] != ids:
                continue
            same[name] += 1
            for o, q in zip(py.observations, res.observations):
                if o.ok and q.ok:
                    d[dr].append(abs(o.range - q.range))
                    if name == "cpp":
                        d["bearing"].append(abs(o.bearing - q.bearing))
            if py.ok and res.ok:
                d[df].append(np.linalg.norm(py.position - res.position))
        if cc.ok and cw.ok:
            d["windows"].append(np.linalg.norm(cw.position - cc.position))
        for key, res in (("err_py", py), ("err_cpp", cc), ("err_win", cw)):
            if res.ok:
                d[key].append(np.linalg.norm(res.position - np.array(pose[:2])))
    print(f"frames {frames}: same ids C++ {same['cpp']}, C++ with 4.6's refinement {same['cpp46']}")
    for key, label in (("range", "|d range| m"), ("range46", "|d range| m, 4.6's refinement"),
                       ("bearing", "|d bearing| rad"), ("fix", "|d fix| m"), ("fix46", "|d fix| m, 4.6's refinement"),
                       ("windows", "|fix windows - fix whole| m (C++)"), ("err_py", "error vs truth m, Python"),
                       ("err_cpp", "error vs truth m, C++"), ("err_win", "error vs truth m, C++ windows")):
        print(f"{label:40s} {_q(d[key])}")
    print("median ms per frame: " + ", ".join(f"{k} {1e3 * np.median(v):.1f}" for k, v in t.items()))


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=100)
    main(ap.parse_args().frames)

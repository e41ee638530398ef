#!/usr/bin/env python
"""The paper's SGBM ranging in the C++ front end beside the Python whole-frame pipeline with
SGBM ranging, on the same rendered pairs.

Run from the repository root::

    python bench/bench_lanbloc_sgbm.py                    # 100 frames, 640x480
    python bench/bench_lanbloc_sgbm.py --frames 20 --scenario-camera   # 2560x1440, f = 1400 px

Frames: bench/bench_lanbloc_cpp.py's (seed 0: 3-6 markers at 5-25 m, pixel noise σ = 1).  Per
frame, in one process:

* ``python``: ``LanBLoc(..., ranging="sgbm", backend="python")`` (pip's cv2 ArUco, SGBM over the
  boxes' row band through the core's StereoMatcher, box medians, trilateration);
* ``core``: the C++ front end with ``ranging = SGBM`` on the whole frame (the core's ArUco,
  then the same band, medians and trilateration in C++);
* ``core_boxes``: ``LanBLocFrontEnd.localize_boxes`` on the Python pipeline's boxes (a detector of
  the caller's, e.g. a YOLO model, with ranging in C++).

Prints how many frames give the same landmarks, how many ``core_boxes`` sightings equal the
Python pipeline's bit for bit, the fix differences and errors against the truth, and the
median time per frame with the ratios.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_lanbloc_cpp import _q, bench_rig, cli  # noqa: E402
from test_lanbloc_cpp import _front_end, random_frame  # noqa: E402

from safenav import _core  # noqa: E402
from safenav.vision.lanbloc import LanBLoc  # noqa: E402


def _bitwise(a, b) -> bool:
    return all((np.isnan(x) and np.isnan(y)) or x == y
               for x, y in ((a.range, b.range), (a.sigma, b.sigma), (a.bearing, b.bearing)))


def main(frames: int, scenario_camera: bool) -> None:
    rig = bench_rig(scenario_camera)
    rng = np.random.default_rng(0)
    t = {k: [] for k in ("python", "core", "core_boxes")}
    d = {k: [] for k in ("fix_core", "err_python", "err_core", "err_boxes")}
    same_ids = bitwise = sightings = 0
    for k in range(frames):
        pose, world, _, (left, right) = random_frame(rng, k, rig)
        lb = LanBLoc(world, rig, ranging="sgbm", backend="python")
        fe = _front_end(world, rig, ranging=_core.LanBLocRanging.SGBM)
        t0 = time.perf_counter()
        py = lb.localize(left, right)
        t1 = time.perf_counter()
        cc = fe.localize(left, right)
        t2 = time.perf_counter()
        cb = fe.localize_boxes(left, right, [(o.landmark_id, o.box) for o in py.observations])
        t3 = time.perf_counter()
        t["python"].append(t1 - t0), t["core"].append(t2 - t1), t["core_boxes"].append(t3 - t2)
        same_ids += [o.landmark_id for o in py.observations] == [o.landmark_id for o in cc.observations]
        sightings += len(py.observations)
        bitwise += sum(_bitwise(a, b) for a, b in zip(cb.observations, py.observations))
        if py.ok and cc.ok:
            d["fix_core"].append(np.linalg.norm(py.position - cc.position))
        for key, res in (("err_python", py), ("err_core", cc), ("err_boxes", cb)):
            if res.ok:
                d[key].append(np.linalg.norm(np.asarray(res.position) - np.array(pose[:2])))
    print(f"frames {frames} ({rig.width}x{rig.height}): same landmarks core/python {same_ids}; "
          f"core_boxes sightings equal to Python's bit for bit: {bitwise} of {sightings}")
    for key, label in (("fix_core", "|fix core - fix python| m"), ("err_python", "error vs truth m, Python"),
                       ("err_core", "error vs truth m, core"), ("err_boxes", "error vs truth m, core_boxes")):
        print(f"{label:34s} {_q(d[key])}")
    m = {k: np.median(v) for k, v in t.items()}
    print("median ms per frame: " + ", ".join(f"{k} {1e3 * v:.2f}" for k, v in m.items()))
    print(f"ratios (medians): python / core {m['python'] / m['core']:.2f}x, "
          f"python / core_boxes {m['python'] / m['core_boxes']:.2f}x")


if __name__ == "__main__":
    cli(main, __doc__)

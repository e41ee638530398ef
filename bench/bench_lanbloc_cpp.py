#!/usr/bin/env python
"""LanBLoc's C++ front end (``safenav._core.LanBLocFrontEnd``) beside the Python whole-frame
pipeline with corner ranging, on the same rendered pairs.

Run from the repository root::

    python bench/bench_lanbloc_cpp.py            # 100 frames
    python bench/bench_lanbloc_cpp.py --frames 20
    python bench/bench_lanbloc_cpp.py --frames 20 --scenario-camera   # 2560x1440, f = 1400 px

Frames (seed 0): a random pose, 3-6 markers at 5-25 m within ±0.6 rad of the heading at
heights 1-4 m, 640×480 (f = 350 px, B = 0.3 m), pixel noise σ = 1.  Per frame: the Python
pipeline (pip's cv2), the C++ front end on the whole frame (OpenCV 4.6 with OpenCV >= 4.8's
corner-refinement window rule), the same with OpenCV 4.6's own refinement, and the C++ front
end with windows from the true pose (σ = 0.3 m, 2°).  Prints the agreement of ids, ranges,
bearings and fixes, the fixes' errors against the truth, and the median time per frame.

The windows are searched at the pyramid levels (``detect_side_px``, the default) and again at full
resolution (``detect_side_px = 0``): markers found by each, the corner and fix differences, and
the time per frame of each beside the Python region pipeline on the same pixels (a
``StereoFrame`` cut from the rendered pair, its regions from the markers' true footprints).
``--scenario-camera``: the default scenario's camera (2560×1440) instead of 640×480.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_lanbloc_cpp import RIG, _front_end, random_frame  # noqa: E402  (the tests' rig → front end adapter)

from safenav.vision.detect import FiducialDetector  # noqa: E402
from safenav.vision.lanbloc import LanBLoc  # noqa: E402


def _q(v) -> str:
    v = np.asarray(v)
    return f"n={len(v)} median={np.median(v):.2e} p95={np.percentile(v, 95):.2e} max={v.max():.2e}" if len(v) else "n=0"


def _levels(world, rig, pose, ren, left, right, P, d, t, found) -> None:
    """The plan's windows at the pyramid levels and at full resolution, and the Python region
    pipeline on the same pixels."""
    pyr_fe, full_fe = _front_end(world, rig), _front_end(world, rig, detect_side_px=0.0)
    region = LanBLoc(world, rig, FiducialDetector(world, aruco3=True), ranging="corners")
    plan = pyr_fe.plan(np.array(pose), P)
    t0 = time.perf_counter()
    pyr = pyr_fe.localize_plan(left, right, plan)
    t1 = time.perf_counter()
    full = full_fe.localize_plan(left, right, plan)
    t2 = time.perf_counter()
    frame = ren.frame(pose, images=(left, right))
    t3 = time.perf_counter()
    region.localize_frame(frame)
    t4 = time.perf_counter()
    t["pyramid"].append(t1 - t0), t["full_res"].append(t2 - t1), t["python_regions"].append(t4 - t3)
    ip = {o.landmark_id: o for o in pyr.observations}
    iq = {o.landmark_id: o for o in full.observations}
    found["pyramid"] += len(ip)
    found["full_res"] += len(iq)
    found["missed"] += len(set(iq) - set(ip))
    found["extra"] += len(set(ip) - set(iq))
    found["fixes_pyramid"] += pyr.ok
    found["fixes_full_res"] += full.ok
    for i in set(ip) & set(iq):
        c = np.abs(np.vstack([ip[i].corners_left, ip[i].corners_right]) -
                   np.vstack([iq[i].corners_left, iq[i].corners_right]))
        if np.isfinite(c).any():
            d["corners_pyr"].append(np.nanmax(c))
    if pyr.ok and full.ok:
        d["fix_pyr"].append(np.linalg.norm(pyr.position - full.position))


def bench_rig(scenario_camera: bool):
    """The tests' 640×480 rig, or the default scenario's camera (2560×1440)."""
    if not scenario_camera:
        return RIG
    import safenav
    from safenav.vision.lanbloc import scenario_camera as camera
    return camera(safenav.default_scenario(), None, None, 1.5, {})[0]


def cli(main, doc: str) -> None:
    """``main(frames, scenario_camera)`` from the command line (``--frames``, ``--scenario-camera``)."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--scenario-camera", action="store_true")
    a = ap.parse_args()
    main(a.frames, a.scenario_camera)


def main(frames: int, scenario_camera: bool) -> None:
    rig = bench_rig(scenario_camera)
    rng = np.random.default_rng(0)
    same = {"cpp": 0, "cpp46": 0}
    d = {k: [] for k in ("range", "range46", "bearing", "fix", "fix46", "windows", "err_py", "err_cpp", "err_win",
                         "corners_pyr", "fix_pyr")}
    t = {k: [] for k in ("python", "cpp", "windows", "pyramid", "full_res", "python_regions")}
    found = {k: 0 for k in ("pyramid", "full_res", "missed", "extra", "fixes_pyramid", "fixes_full_res")}
    P = np.diag([0.3 ** 2, 0.3 ** 2, math.radians(2.0) ** 2])
    for k in range(frames):
        pose, world, ren, (left, right) = random_frame(rng, k, rig)
        t0 = time.perf_counter()
        py = LanBLoc(world, rig, ranging="corners", backend="python").localize(left, right)
        t1 = time.perf_counter()
        fe = _front_end(world, rig)
        cc = fe.localize(left, right)
        t2 = time.perf_counter()
        cw = fe.localize(left, right, np.array(pose), P)
        t3 = time.perf_counter()
        c46 = _front_end(world, rig, relative_corner_refinement_win_size=0.0).localize(left, right)
        t["python"].append(t1 - t0), t["cpp"].append(t2 - t1), t["windows"].append(t3 - t2)
        _levels(world, rig, pose, ren, left, right, P, d, t, found)
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
    print("median ms per frame: " + ", ".join(f"{k} {1e3 * np.median(v):.2f}" for k, v in t.items()))
    f = found
    print(f"windows at the pyramid levels vs full resolution: markers {f['pyramid']} vs {f['full_res']} (missed "
          f"{f['missed']}, only by the pyramid {f['extra']}), fixes {f['fixes_pyramid']} vs {f['fixes_full_res']}")
    for key, label in (("corners_pyr", "|d corner| px, pyramid - full"), ("fix_pyr", "|d fix| m, pyramid - full")):
        print(f"{label:40s} {_q(d[key])}")
    m = {k: np.median(v) for k, v in t.items()}
    print(f"ratios (medians): Python region pipeline / C++ pyramid {m['python_regions'] / m['pyramid']:.1f}x, "
          f"C++ full resolution / C++ pyramid {m['full_res'] / m['pyramid']:.1f}x")


if __name__ == "__main__":
    cli(main, __doc__)

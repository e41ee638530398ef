#!/usr/bin/env python
"""LanBLoc ranging and localization benchmarks: safenav beside its peers in one process.

Run from the repository root::

    python bench/bench_lanbloc.py            # 9 interleaved repeats
    python bench/bench_lanbloc.py --quick    # 3 repeats

1. Rectification + SGBM at 640×480 (grey, 64 disparities, block 5): our
   ``StereoMatcher.rectify`` + ``disparity`` (C++, Debian OpenCV 4.6) against
   ``cv2.remap`` with ``cv2.initUndistortRectifyMap`` maps (computed once) +
   ``cv2.StereoSGBM.compute`` (pip OpenCV) with the same parameters.  The
   disparities must agree (same algorithm); the script checks the fraction of
   equal pixels.  ms per frame, median over repeats, and the ratio.
2. Trilateration of one fix from 6 ranges (noisy, σ = 0.1 m):
   ``safenav.vision.localization.trilaterate`` (linear start + LM, covariance, GDOP,
   mirror-ambiguity check; outlier rejection off, since the peer has none) against ``scipy.optimize.least_squares`` (method "lm")
   started from the true position + 1 m on the same problem.  µs per fix,
   median over repeats, and the ratio.  The positions must agree to 1e-6 m.
   Ours is also timed with ``profile_probability=0`` (the linear covariance
   alone): the difference is what the profile check of the covariance costs.

Each repeat alternates ours and the peer (order flipped every repeat).
"""

from __future__ import annotations

import argparse
import platform
import time

import cv2
import numpy as np
from scipy import optimize

from safenav.vision.localization import trilaterate
from safenav.vision.stereo import StereoCalibration, StereoMatcher


def _median(xs):
    return float(np.median(xs)), float(np.min(xs)), float(np.max(xs))


def bench_stereo(repeats: int, frames: int):
    rng = np.random.default_rng(0)
    K = np.array([[600.0, 0, 320], [0, 600.0, 240], [0, 0, 1]])
    D = np.array([-0.1, 0.03, 0.001, -0.001, 0.0])
    R, _ = cv2.Rodrigues(np.array([0.005, -0.01, 0.002]))
    T = np.array([-0.12, 0.001, 0.0])
    size = (640, 480)
    calib = StereoCalibration(K, D, K, D, R, T, size)
    params = dict(min_disparity=0, num_disparities=64, block_size=5, P1=8 * 25, P2=32 * 25, disp12_max_diff=1,
                  pre_filter_cap=63, uniqueness_ratio=10, speckle_window_size=100, speckle_range=2)
    ours = StereoMatcher(calib, **params)
    rect = ours.rectification
    maps_l = cv2.initUndistortRectifyMap(K, D, rect["R1"], rect["P1"], size, cv2.CV_16SC2)
    maps_r = cv2.initUndistortRectifyMap(K, D, rect["R2"], rect["P2"], size, cv2.CV_16SC2)
    sgbm = cv2.StereoSGBM_create(minDisparity=0, numDisparities=64, blockSize=5, P1=8 * 25, P2=32 * 25,
                                 disp12MaxDiff=1, preFilterCap=63, uniquenessRatio=10, speckleWindowSize=100,
                                 speckleRange=2, mode=cv2.STEREO_SGBM_MODE_SGBM)
    # textured scene: a blurred random image and a copy shifted by 24 px
    base = cv2.GaussianBlur(rng.integers(0, 256, (480, 640 + 24)).astype(np.uint8), (3, 3), 0.8)
    left, right = base[:, :640].copy(), base[:, 24:664].copy()

    def run_ours():
        for _ in range(frames):
            lr, rr = ours.rectify(left, right)
            d = ours.disparity(lr, rr)
        return d

    def run_peer():
        for _ in range(frames):
            lr = cv2.remap(left, *maps_l, cv2.INTER_LINEAR)
            rr = cv2.remap(right, *maps_r, cv2.INTER_LINEAR)
            raw = sgbm.compute(lr, rr)
        return np.where(raw < 0, np.nan, raw / 16.0)

    d_ours, d_peer = run_ours(), run_peer()
    same = np.mean((d_ours == d_peer) | (np.isnan(d_ours) & np.isnan(d_peer)))
    t_ours, t_peer = [], []
    for k in range(repeats):
        for which in ((0, 1) if k % 2 == 0 else (1, 0)):
            t0 = time.perf_counter()
            (run_ours if which == 0 else run_peer)()
            (t_ours if which == 0 else t_peer).append((time.perf_counter() - t0) / frames * 1e3)
    return _median(t_ours), _median(t_peer), same


def bench_trilateration(repeats: int, fixes: int):
    rng = np.random.default_rng(1)
    anchors = rng.uniform(0, 50, (6, 2))
    p = np.array([22.0, 27.0])
    sig = np.full(6, 0.1)
    problems = [np.linalg.norm(anchors - p, axis=1) + sig * rng.standard_normal(6) for _ in range(fixes)]

    def run_ours():
        return [trilaterate(anchors, z, sig, reject_outliers=False).position for z in problems]

    def run_linear():
        return [trilaterate(anchors, z, sig, reject_outliers=False, profile_probability=0).position for z in problems]

    def run_peer():
        return [optimize.least_squares(lambda q, z=z: (z - np.linalg.norm(anchors - q, axis=1)) / sig, p + 1.0,
                                       method="lm").x for z in problems]

    diff = np.max(np.abs(np.array(run_ours()) - np.array(run_peer())))
    runs = (run_ours, run_peer, run_linear)
    times = ([], [], [])
    for k in range(repeats):
        for which in ((0, 1, 2) if k % 2 == 0 else (2, 1, 0)):
            t0 = time.perf_counter()
            runs[which]()
            times[which].append((time.perf_counter() - t0) / fixes * 1e6)
    return _median(times[0]), _median(times[1]), diff, _median(times[2])[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 repeats instead of 9")
    args = ap.parse_args()
    repeats = 3 if args.quick else 9
    print(f"# bench_lanbloc  ({platform.processor() or platform.machine()}, OpenCV pip {cv2.__version__}, "
          f"{repeats} repeats)")
    (mo, lo, hi), (mp, lp, hp), same = bench_stereo(repeats, frames=5)
    print(f"rectify+SGBM 640x480   ours {mo:8.2f} ms [{lo:.2f}-{hi:.2f}]   cv2 remap+StereoSGBM {mp:8.2f} ms "
          f"[{lp:.2f}-{hp:.2f}]   ratio peer/ours {mp / mo:5.2f}   identical disparities {same:.4f}")
    (mo, lo, hi), (mp, lp, hp), diff, ml = bench_trilateration(repeats, fixes=300)
    print(f"trilateration 6 ranges ours {mo:8.1f} us [{lo:.1f}-{hi:.1f}]   scipy least_squares(lm) {mp:8.1f} us "
          f"[{lp:.1f}-{hp:.1f}]   ratio peer/ours {mp / mo:5.1f}   max |Δp| {diff:.1e} m   "
          f"ours with the linear covariance alone {ml:8.1f} us")


if __name__ == "__main__":
    main()

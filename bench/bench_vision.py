#!/usr/bin/env python
"""Vision benchmark: the camera loop by region at the scenario camera's 2560×1440 beside today's
whole-frame loop at 640×480, in one process.

Run from the repository root::

    python bench/bench_vision.py            # 3 repeats over the frame set
    python bench/bench_vision.py --quick    # 1 repeat, fewer reference frames
    python bench/bench_vision.py --figure docs/figures/lanbloc_camera_loop.png

Frames: poses every 4 m along the default scenario's three paths (P1-P3),
heading along the path (as a vehicle's camera frames fall), markers 1.5 m,
pixel noise σ = 1 grey level.  Loops, each :class:`safenav.vision.CameraLoopSource`
per call (render + detect + range + trilaterate), interleaved frame by frame:

* **today** — the whole-frame loop this issue started from: 640×480
  (f = 350 px), whole images rendered, ArUco on the whole left image, SGBM
  with 64 disparities on the rows of the boxes, box-median ranges, no
  occlusion;
* **regions** — the new default: 2560×1440 (f = 1400 px), only the markers'
  regions rendered and searched (:class:`safenav.vision.render.StereoFrame`),
  the markers' corners triangulated; with and without the early out (frames
  with fewer than 3 markers in view are not processed; the fixes are the
  same);
* **full 2560** — the whole-frame reference at 2560×1440 (SGBM with the
  disparity search from the depth range), on a subset of frames.

Ratios are today's median time per frame over each loop's.  Then what each
loop measures along the paths (every 1.5 m): fix rate, error (all fixes and
fixes whose landmarks are all within 20 m), NEES, with and without occlusion.
"""

from __future__ import annotations

import argparse
import math
import platform
import time

import cv2
import numpy as np

import safenav
from safenav.vision.lanbloc import CameraLoopSource
from safenav.vision.render import StereoRig
from safenav.results import save_figure


def _frames(sc, step: float):
    out = []
    for pt in sc.path_types:
        poly = sc.world.path_polyline(pt)
        for a, b in zip(poly[:-1], poly[1:]):
            length = float(np.linalg.norm(b - a))
            th = math.atan2(*(b - a)[::-1])
            for d in np.arange(0.0, length, step):
                p = a + (b - a) * d / length
                out.append((pt.name, float(p[0]), float(p[1]), th))
    return out


def _timed(f, *args):
    t0 = time.perf_counter()
    out = f(*args)
    return out, time.perf_counter() - t0


def figure(path: str) -> None:
    """One camera-loop frame: left image with boxes and ranges, the pipeline's disparity, the fix on the map."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Ellipse, Rectangle

    sc = safenav.default_scenario()
    src = CameraLoopSource(sc.world, StereoRig(), mode="full", seed=1)
    poly = sc.world.path_polyline(sc.path_types[1])
    a, b = poly[0], poly[1]
    length = float(np.linalg.norm(b - a))
    th = math.atan2(*(b - a)[::-1])
    p = a + (b - a) * (length - 16.0) / length
    out = src(np.array([p[0], p[1], 1.0, th]), 0)
    res = src.last
    left, right = src.renderer.render((p[0], p[1], th))
    disp = src.pipeline.disparity(left, right, [d.box for d in res.detections])
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2), gridspec_kw=dict(width_ratios=[1.33, 1.33, 1]))
    ax[0].imshow(left, cmap="gray", vmin=0, vmax=255)
    for o in res.observations:
        x0, y0, x1, y1 = o.box
        ax[0].add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, color="tab:red", lw=1.5))
        ax[0].text(x0, y0 - 4, f"#{o.landmark_id} {o.range:.1f}±{o.sigma:.1f} m", color="yellow", fontsize=8)
    ax[0].set_title("left image, detections, horizontal ranges")
    im = ax[1].imshow(disp, cmap="viridis")
    fig.colorbar(im, ax=ax[1], fraction=0.035, label="disparity [px]")
    ax[1].set_title("SGBM disparity (row band), NaN blank")
    for ax_ in ax[:2]:
        ax_.set_xticks([])
        ax_.set_yticks([])
    lm = sc.world.landmark_array()
    ax[2].scatter(lm[:, 0], lm[:, 1], c="k", s=12, label="landmarks")
    ids, anchors, _, _ = res.range_measurements()
    ax[2].scatter(anchors[:, 0], anchors[:, 1], facecolors="none", edgecolors="tab:red", s=80, label="ranged")
    ax[2].plot(*poly.T, "--", color="0.6", lw=1, label="path P2")
    ax[2].plot(p[0], p[1], "o", color="tab:blue", label="true position")
    if out is not None:
        z, R = out
        w, V = np.linalg.eigh(R)
        ang = math.degrees(math.atan2(V[1, 1], V[0, 1]))
        ax[2].add_patch(Ellipse(z, 2 * 2.45 * math.sqrt(w[1]), 2 * 2.45 * math.sqrt(w[0]), angle=ang,
                                fill=False, color="tab:green", label="fix, 95 % ellipse"))
        ax[2].plot(*z, "x", color="tab:green")
    ax[2].set_xlim(p[0] - 8, p[0] + 30)
    ax[2].set_ylim(p[1] - 22, p[1] + 16)
    ax[2].set_aspect("equal")
    ax[2].legend(fontsize=7, loc="lower left")
    ax[2].set_title(f"fix: {res.status}, error {np.linalg.norm(out[0] - p) if out else float('nan'):.2f} m")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    print(f"wrote {path}")


def _today(sc):
    """The loop as it was: 640×480, whole frames, SGBM with 64 disparities, no occlusion."""
    return CameraLoopSource(sc.world, StereoRig(), mode="full", occlusion=False, seed=1,
                            sgbm=dict(min_disparity=0, num_disparities=64))


def _regions(sc, **kw):
    return CameraLoopSource.from_scenario(sc, seed=1, **kw)


def _along(sc, src, step=1.5):
    """Fix statistics of ``src`` along each path."""
    out = {}
    for pt in sc.path_types:
        n, fixes, errs, near, nees = 0, 0, [], [], []
        for i, (pn, x, y, th) in enumerate(f for f in _frames(sc, step) if f[0] == pt.name):
            fix = src(np.array([x, y, 1.0, th]), i)
            n += 1
            if fix is None:
                continue
            fixes += 1
            e = fix[0] - (x, y)
            errs.append(float(np.linalg.norm(e)))
            nees.append(float(e @ np.linalg.solve(fix[1], e)))
            if max(o.range for o in src.last.observations if o.ok) <= 20.0:
                near.append(errs[-1])
        out[pt.name] = (n, fixes, errs, near, nees)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="1 repeat, 5 reference frames")
    ap.add_argument("--step", type=float, default=4.0, help="metres between frames along the paths")
    ap.add_argument("--figure", metavar="PNG", help="only draw one camera-loop frame to PNG "
                    "(docs/figures/lanbloc_camera_loop.png) and exit")
    args = ap.parse_args()
    if args.figure:
        figure(args.figure)
        return
    cv2.setNumThreads(1)
    repeats = 1 if args.quick else 3
    sc = safenav.default_scenario()
    loops = {"today": _today(sc), "regions": _regions(sc, occlusion=False),
             "regions, no early out": _regions(sc, occlusion=False, early_out=False)}
    ref = CameraLoopSource.from_scenario(sc, seed=1, occlusion=False, mode="full")
    poses = _frames(sc, args.step)
    rig = loops["regions"].rig
    print(f"safenav {safenav.__version__} | OpenCV (pip) {cv2.__version__} | {platform.processor() or platform.machine()}"
          f" | one thread")
    print(f"{len(poses)} frames (poses every {args.step:g} m on P1-P3), {repeats} repeats; regions at "
          f"{rig.width}x{rig.height}, f = {rig.focal_length_px:g} px; today at 640x480, f = 350 px\n")
    t = {k: [] for k in (*loops, "full 2560")}
    has_marker = []
    for rep in range(repeats):
        for i, (_, x, y, th) in enumerate(poses):
            s = np.array([x, y, 1.0, th])
            names = list(loops) if rep % 2 == 0 else list(loops)[::-1]
            for name in names:
                _, dt = _timed(loops[name], s, i)
                t[name].append(dt)
            if rep == 0:
                has_marker.append(len(loops["regions"].renderer.culled((x, y, th))) > 0)
    n_ref = 5 if args.quick else 20
    marked = [p for p, m in zip(poses, has_marker) if m]
    for _, x, y, th in marked[:: max(len(marked) // n_ref, 1)][:n_ref]:
        _, dt = _timed(ref, np.array([x, y, 1.0, th]), 0)
        t["full 2560"].append(dt)
    mask = np.tile(np.array(has_marker), repeats)
    today = 1e3 * np.array(t["today"])
    print(f"{'loop':28s} {'frames':>7s} {'median ms':>10s} {'mean ms':>9s} {'today/loop':>11s} "
          f"{'median ms, marker in view':>26s} {'today/loop':>11s}")
    for name, v in t.items():
        v = 1e3 * np.array(v)
        if name == "full 2560":
            print(f"{name:28s} {len(v):7d} {'':>10s} {'':>9s} {'':>11s} {np.median(v):26.2f} "
                  f"{np.median(today[mask]) / np.median(v):11.3f}")
            continue
        print(f"{name:28s} {len(v):7d} {np.median(v):10.3f} {v.mean():9.3f} {np.median(today) / np.median(v):11.1f} "
              f"{np.median(v[mask]):26.3f} {np.median(today[mask]) / np.median(v[mask]):11.1f}")
    print(f"  mean over all frames: today {today.mean():.2f} ms, regions {1e3 * np.mean(t['regions']):.2f} ms "
          f"({today.mean() / (1e3 * np.mean(t['regions'])):.1f}x)")

    print("\ncamera loop along the paths (every 1.5 m, heading along the path):")
    print(f"{'loop':30s} {'path':5s} {'frames':>7s} {'fixes':>6s} {'median m':>9s} {'p95 m':>7s} "
          f"{'<=20 m: n':>10s} {'median m':>9s} {'NEES':>6s}")
    rows = {"today (640, full)": _today(sc), "regions 2560, no occlusion": _regions(sc, occlusion=False),
            "regions 2560, occlusion": _regions(sc, occlusion=True)}
    for name, src in rows.items():
        for path, (n, fixes, errs, near, nees) in _along(sc, src).items():
            e = np.array(errs) if errs else np.array([np.nan])
            print(f"{name:30s} {path:5s} {n:7d} {fixes:6d} {np.median(e):9.3f} {np.percentile(e, 95):7.3f} "
                  f"{len(near):10d} {np.median(near) if near else math.nan:9.3f} "
                  f"{np.mean(nees) if nees else math.nan:6.2f}")


if __name__ == "__main__":
    main()

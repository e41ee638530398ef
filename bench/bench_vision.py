#!/usr/bin/env python
"""Vision benchmark: the camera loop at 640×480, stage by stage, beside plain OpenCV SGBM.

Run from the repository root::

    python bench/bench_vision.py            # 5 repeats over the frame set
    python bench/bench_vision.py --quick    # 2 repeats
    python bench/bench_vision.py --paths-only --width 1280   # along-path statistics at 1280x720
    python bench/bench_vision.py --figure docs/figures/lanbloc_camera_loop.png

Frames: poses every 4 m along the default scenario's three paths (P1-P3),
heading along the path, kept where at least one marker is in view; the
camera is the scenario's scaled to 640×480 (f = 350 px, B = 0.3 m), markers
1.5 m, pixel noise σ = 1 grey level.

Stages, each timed per frame (median over frames and repeats), in one process:

* render — :class:`safenav.vision.render.StereoRenderer` (both images);
* detect — :class:`safenav.vision.detect.FiducialDetector` on the left image;
* disparity — the pipeline's SGBM (C++ core, OpenCV 4.6, on the band of rows
  holding the boxes) and, as the peer, ``cv2.StereoSGBM`` of pip's OpenCV on
  the whole pair with the same parameters (3-way, 64 disparities, block 5);
* range — box-median ranges of all detections;
* localize — trilateration;
* pipeline — ``LanBLoc.localize`` (detect … localize) and camera loop —
  render + pipeline, i.e. :class:`safenav.vision.lanbloc.CameraLoopSource` per call.

Ratios are the peer SGBM's time over each stage's.  The script also reports
what the camera loop measures along the three paths: how often a fix is made,
its error and NEES, and the box-median disparity error on the markers (the
basis of ``CameraLoopSource``'s σ_d = 0.2 px).
"""

from __future__ import annotations

import argparse
import math
import platform
import time

import cv2
import numpy as np

import safenav
from safenav.vision.lanbloc import STATUSES, CameraLoopSource, PIPELINE_SGBM
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


def _peer_sgbm():
    bs = PIPELINE_SGBM["block_size"]
    return cv2.StereoSGBM_create(minDisparity=0, numDisparities=PIPELINE_SGBM["num_disparities"], blockSize=bs,
                                 P1=8 * bs * bs, P2=32 * bs * bs, disp12MaxDiff=1, preFilterCap=63,
                                 uniquenessRatio=PIPELINE_SGBM["uniqueness_ratio"],
                                 speckleWindowSize=PIPELINE_SGBM["speckle_window_size"],
                                 speckleRange=PIPELINE_SGBM["speckle_range"], mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)


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
    src = CameraLoopSource(sc.world, seed=1)
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 repeats instead of 5")
    ap.add_argument("--step", type=float, default=4.0, help="metres between frames along the paths")
    ap.add_argument("--figure", metavar="PNG", help="only draw one camera-loop frame to PNG "
                    "(docs/figures/lanbloc_camera_loop.png) and exit")
    ap.add_argument("--width", type=int, default=640,
                    help="image width; the scenario camera (2560x1440, 85 deg) is scaled to it (480 rows at 640)")
    ap.add_argument("--paths-only", action="store_true", help="skip the timings, only the along-path statistics")
    args = ap.parse_args()
    if args.figure:
        figure(args.figure)
        return
    repeats = 2 if args.quick else 5

    sc = safenav.default_scenario()
    rig = StereoRig() if args.width == 640 else StereoRig.from_camera(sc.camera, args.width, None)
    src = CameraLoopSource(sc.world, rig, seed=1)
    rig, renderer, lb = src.rig, src.renderer, src.pipeline
    peer = _peer_sgbm()
    poses = _frames(sc, args.step)
    frames = [p for p in poses if len(renderer.culled(p[1:])) > 0]   # at least one marker in the field of view

    print(f"safenav {safenav.__version__} | OpenCV (pip) {cv2.__version__} | {platform.processor() or platform.machine()}"
          f" | {rig.width}x{rig.height}, f = {rig.focal_length_px:g} px, B = {rig.baseline_m:g} m")
    print(f"{len(frames)} frames with a marker in view (of {len(poses)} poses every {args.step:g} m on P1-P3), "
          f"{repeats} repeats" + (" (timings skipped)" if args.paths_only else "") + "\n")

    if args.paths_only:
        repeats = 0
    t = {k: [] for k in ("render", "detect", "disparity", "disparity_full", "peer_sgbm", "range", "localize",
                         "pipeline", "loop")}
    for rep in range(repeats):
        for _, x, y, th in frames:
            (left, right), dt = _timed(renderer.render, (x, y, th))
            t["render"].append(dt)
            dets, dt = _timed(lb.detector.detect, left)
            t["detect"].append(dt)
            boxes = [d.box for d in dets]
            # ours and the peer alternate, order flipped every repeat
            order = ("ours", "peer") if rep % 2 == 0 else ("peer", "ours")
            for who in order:
                if who == "ours":
                    disp, dt = _timed(lb.disparity, left, right, boxes)
                    t["disparity"].append(dt)
                    _, dt = _timed(lb.matcher.disparity, left, right)
                    t["disparity_full"].append(dt)
                else:
                    _, dt = _timed(peer.compute, left, right)
                    t["peer_sgbm"].append(dt)
            known = [d for d in dets if d.landmark_id in lb.landmarks]
            obs, dt = _timed(lambda: [lb.observe(d, disp) for d in known])
            t["range"].append(dt)
            ok = [o for o in obs if o.ok]
            if len(ok) >= 3:
                _, dt = _timed(safenav.vision.localization.trilaterate, np.array([o.anchor[:2] for o in ok]),
                               [o.range for o in ok], [o.sigma for o in ok])
                t["localize"].append(dt)
            _, dt = _timed(lb.localize, left, right)
            t["pipeline"].append(dt)
            _, dt = _timed(src, np.array([x, y, 1.0, th]), 0)
            t["loop"].append(dt)

    peer_ms = 1e3 * float(np.median(t["peer_sgbm"])) if repeats else math.nan
    rows = [("render (left + right)", "render"), ("detect (ArUco, left)", "detect"),
            ("disparity, row band (C++ SGBM)", "disparity"), ("disparity, full frame (C++ SGBM)", "disparity_full"),
            ("peer: cv2.StereoSGBM, full frame", "peer_sgbm"), ("range (all boxes)", "range"),
            ("localize (trilaterate)", "localize"), ("pipeline (detect..localize)", "pipeline"),
            ("camera loop (render + pipeline)", "loop")]
    if repeats:
        print(f"{'stage':36s} {'median ms':>10s} {'min-max ms':>17s} {'fps':>9s} {'peer SGBM / stage':>18s}")
    for label, key in rows:
        v = 1e3 * np.array(t[key])
        if len(v) == 0 or repeats == 0:
            continue
        med = float(np.median(v))
        print(f"{label:36s} {med:10.3f} {v.min():8.3f}-{v.max():8.3f} {1e3 / med:9.1f} {peer_ms / med:18.2f}")

    # ---- what the camera loop measures along the paths (one pass, every 1.5 m)
    print("\ncamera loop along the paths (every 1.5 m, heading along the path):")
    fB = rig.fB
    derr = []
    false_ids = 0
    for name in [p.name for p in sc.path_types]:
        stats = {s: 0 for s in STATUSES}
        errs, nees = [], []
        for pn, x, y, th in _frames(sc, 1.5):
            if pn != name:
                continue
            out = src(np.array([x, y, 1.0, th]), 0)
            stats[src.last.status] += 1
            corners = renderer.marker_corners((x, y, th))
            false_ids += sum(o.landmark_id not in corners for o in src.last.observations)
            for o in src.last.observations:
                if o.ok and o.landmark_id in corners:
                    _, z = renderer.project((x, y, th), corners[o.landmark_id].mean(axis=0)[None])
                    derr.append(o.disparity - fB / z[0])
            if out is not None:
                e = out[0] - (x, y)
                errs.append(float(np.linalg.norm(e)))
                nees.append(float(e @ np.linalg.solve(out[1], e)))
        n = sum(stats.values())
        print(f"  {name}: {n} frames, fixes {stats['ok']} ({100 * stats['ok'] / n:.0f} %), "
              + ", ".join(f"{k} {v}" for k, v in stats.items() if k != "ok" and v)
              + (f"; error median {np.median(errs):.2f} m, 95 % {np.percentile(errs, 95):.2f} m, "
                 f"mean NEES {np.mean(nees):.2f} (2 if consistent)" if errs else ""))
    d = np.abs(np.array(derr))
    print(f"  box-median disparity error on markers: RMS {math.sqrt(np.mean(d ** 2)):.3f} px, "
          f"median {np.median(d):.3f} px, 99 % {np.percentile(d, 99):.3f} px, max {d.max():.3f} px "
          f"({len(d)} ranges)")
    print(f"  detections of markers that are not in the field of view (false ids): {false_ids}")


if __name__ == "__main__":
    main()

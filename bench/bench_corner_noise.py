#!/usr/bin/env python
"""The refined corners' error against the renderer's true corners: the data behind the
corner-noise model of the front end's ranging (docs/lanbloc_cpp.md, "The corner-noise model").

Run from the repository root::

    python bench/bench_corner_noise.py --poses 150 --out /tmp/corner_noise.npz

Poses are drawn along the default scenario's planned paths P1–P3 (every ``--step`` m, the heading
along the path plus N(0, 15°), a lateral offset N(0, 1 m)); each pose's pair is rendered in the
windows that the core's front end plans from the true pose (σ 0.05 m, 0.5°: the camera loop with
a good prediction), at the scenario camera's resolution with pixel noise σ = 1, and searched by
the front end (``LanBLocFrontEnd.localize_plan``).  Per marker found in both images it records:

* the marker's side in the left image [px] (the mean of its four sides), its depth Z [m], the
  viewing angle (between the marker's normal and the ray to the camera) and the angle of its
  centre off the optical axis;
* each corner's error against the true projection, left and right, and its disparity error;
* the centre's disparity error (the front end's ``disparity`` against f·B/Z of the true centre)
  and the corners used.

It prints the error's RMS, median and 99th percentile by bins of marker size in pixels, and the
fitted model (see :func:`fit`).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

import safenav
from safenav import _core
from safenav import navigation as nv
from safenav.vision.camera_loop import CameraFrames, NOISE_STREAM


def sample_poses(sc, n: int, step: float, rng) -> np.ndarray:
    """``n`` poses (x, y, θ) along the planned paths P1–P3 (see the module docstring)."""
    pts = []
    for name in ("P1", "P2", "P3"):
        path = np.asarray(nv.plan_safe_path(sc, name).path)
        for a, b in zip(path[:-1], path[1:]):
            d = np.linalg.norm(b - a)
            th = math.atan2(*(b - a)[::-1])
            for s in np.arange(0.0, d, step):
                pts.append((*(a + (b - a) * s / d), th))
    pts = np.asarray(pts)
    pick = pts[rng.choice(len(pts), size=min(n, len(pts)), replace=False)]
    th = pick[:, 2] + rng.normal(0.0, math.radians(15.0), len(pick))
    lat = rng.normal(0.0, 1.0, len(pick))
    return np.column_stack([pick[:, 0] - lat * np.sin(th), pick[:, 1] + lat * np.cos(th), th])


def measure(poses, seed: int = 0, width: int | None = None) -> dict:
    """Per ranged marker (both images' corners found): the quantities in the module docstring."""
    sc = safenav.default_scenario()
    frames = CameraFrames.from_scenario(sc, width, seed=seed)
    ren, fe, rig = frames.renderer, frames.front_end, frames.rig
    noise = int(_core.derive_seed(int(_core.derive_seed(seed, NOISE_STREAM)), 0))
    lm = {l.id: np.array([*l.position[:2], l.height]) for l in sc.world.landmarks}
    rows = {k: [] for k in ("side_px", "Z", "view", "off_axis", "err_l", "err_r", "err_d", "err_dc", "used",
                            "dv", "sigma_rel")}
    for k, pose in enumerate(poses):
        plan = fe.plan(predicted_pose=tuple(pose),
                       predicted_covariance=np.diag([0.05 ** 2, 0.05 ** 2, math.radians(0.5) ** 2]))
        if plan.mode == _core.SearchMode.WHOLE_FRAME:
            continue
        left, right = ren.render_regions(pose, plan.left_regions, plan.right_regions, noise + k)
        fix = fe.localize_plan(left, right, plan)
        corners = ren.marker_corners(pose)
        Cl, Cr = rig.camera_centers(pose)
        for o in fix.observations:
            cr = np.asarray(o.corners_right)
            if o.landmark_id not in corners or not np.isfinite(cr).all() or not math.isfinite(o.disparity):
                continue
            tl, zl = ren.project(pose, corners[o.landmark_id], "left")
            tr, _ = ren.project(pose, corners[o.landmark_id], "right")
            cl = np.asarray(o.corners_left)
            c3 = corners[o.landmark_id].mean(axis=0)
            (uc,), Zc = ren.project(pose, c3[None], "left")
            Zc = float(Zc[0])
            n = np.cross(corners[o.landmark_id][1] - corners[o.landmark_id][0],
                         corners[o.landmark_id][3] - corners[o.landmark_id][0])
            ray = Cl - c3
            rows["side_px"].append(float(np.mean(np.linalg.norm(np.roll(tl, -1, 0) - tl, axis=1))))
            rows["Z"].append(Zc)
            rows["view"].append(math.degrees(math.acos(abs(n @ ray) / np.linalg.norm(n) / np.linalg.norm(ray))))
            rows["off_axis"].append(math.degrees(math.atan2(abs(uc[0] - rig.cx), rig.focal_length_px)))
            rows["err_l"].append(cl - tl)
            rows["err_r"].append(cr - tr)
            rows["err_d"].append((cl[:, 0] - cr[:, 0]) - (tl[:, 0] - tr[:, 0]))
            rows["err_dc"].append(o.disparity - rig.fB / Zc)
            rows["dv"].append(np.abs(cl[:, 1] - cr[:, 1]))
            rows["used"].append(bool(o.ok))
            rows["sigma_rel"].append(o.sigma / max(o.range, 1e-9) if o.ok else np.nan)
    return {k: np.asarray(v) for k, v in rows.items()}


def fit(data: dict, bins=(0, 20, 30, 40, 60, 90, 140, 1e9)) -> None:
    """Prints the centre's disparity error by marker size (RMS, median |e|, 99th percentile)."""
    s, e = data["side_px"], data["err_dc"]
    ok = data["used"]
    print(f"{ok.sum()} ranged markers of {len(ok)}; centre disparity error RMS {np.sqrt(np.mean(e[ok] ** 2)):.4f} px, "
          f"mean {np.mean(e[ok]):+.4f}, median |e| {np.median(np.abs(e[ok])):.4f}, 99 % {np.percentile(np.abs(e[ok]), 99):.4f}")
    for lo, hi in zip(bins[:-1], bins[1:]):
        m = ok & (s >= lo) & (s < hi)
        if m.sum() < 3:
            continue
        ed = data["err_d"][m]
        print(f"  side {lo:5.0f}-{hi:5.0f} px: n {m.sum():4d}  Z {np.median(data['Z'][m]):5.1f} m  centre RMS "
              f"{np.sqrt(np.mean(e[m] ** 2)):.4f} mean {np.mean(e[m]):+.4f} med|e| {np.median(np.abs(e[m])):.4f} "
              f"99% {np.percentile(np.abs(e[m]), 99):.4f}  corner-d RMS {np.sqrt(np.mean(ed ** 2)):.4f}  "
              f"view {np.median(data['view'][m]):4.1f}°")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=150)
    ap.add_argument("--step", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--width", type=int, default=None, help="image width [px] (default: the scenario camera's)")
    ap.add_argument("--out", default="")
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    sc = safenav.default_scenario()
    d = measure(sample_poses(sc, a.poses, a.step, rng), seed=a.seed, width=a.width)
    if a.out:
        np.savez(a.out, **d)
    fit(d)

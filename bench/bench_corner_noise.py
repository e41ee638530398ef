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
                            "dv", "sigma_rel", "corners_used")}
    fixes = {k: [] for k in ("fix_error", "fix_nees", "fix_range")}
    for k, pose in enumerate(poses):
        plan = fe.plan(predicted_pose=tuple(pose),
                       predicted_covariance=np.diag([0.05 ** 2, 0.05 ** 2, math.radians(0.5) ** 2]))
        if plan.mode == _core.SearchMode.WHOLE_FRAME:
            continue
        left, right = ren.render_regions(pose, plan.left_regions, plan.right_regions, noise + k)
        fix = fe.localize_plan(left, right, plan)
        if fix.ok:
            e = np.asarray(fix.position) - pose[:2]
            fixes["fix_error"].append(float(np.hypot(*e)))
            fixes["fix_nees"].append(float(e @ np.linalg.solve(fix.covariance, e)))
            fixes["fix_range"].append(max(o.range for o in fix.observations if o.ok))
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
            rows["corners_used"].append(int(o.corners_used))
            rows["sigma_rel"].append(o.sigma / max(o.range, 1e-9) if o.ok else np.nan)
    return {k: np.asarray(v) for k, v in {**rows, **fixes}.items()}


def fit(data: dict, bins=(0, 20, 30, 40, 60, 80, 100, 120, 140, 180, 250, 400, 1e9)) -> None:
    """Prints the centre's disparity error by marker size (RMS, median |e|, 99th percentile), the
    maximum-likelihood σ of a constant model and of σ·(side/100 px)^p (the exponent tells whether the
    size matters), the corner pairs' correlation, and the fixes' NEES.  A marker whose corners are more
    than 2 px from the true ones is a misdetection, not corner noise, and is left out (counted)."""
    from scipy.optimize import minimize

    s, e = data["side_px"], data["err_dc"]
    good = np.abs(data["err_l"]).max(axis=(1, 2)) < 2.0
    print(f"misdetections (a corner > 2 px off): {(~good).sum()}")
    ok = data["used"] & good & (data["corners_used"] == 4)
    print(f"ranged from three corners: {(data['used'] & (data['corners_used'] == 3)).sum()}")
    nll = lambda sig: float(np.sum(np.log(sig) + 0.5 * (e[ok] / sig) ** 2))   # noqa: E731
    p = minimize(lambda q: nll(np.exp(q[0]) * (s[ok] / 100.0) ** q[1]), [np.log(0.03), 0.0], method="Nelder-Mead").x
    kurt = np.mean(e[ok] ** 4) / np.mean(e[ok] ** 2) ** 2
    rms = np.sqrt(np.mean(e[ok] ** 2))
    print(f"constant model: sigma_d = {rms:.4f} +- {rms * np.sqrt((kurt - 1) / (4 * ok.sum())):.4f} px "
          f"(kurtosis {kurt:.1f}); sigma_d (side/100 px)^p: {np.exp(p[0]):.4f} px, p = {p[1]:+.3f}")
    C = np.corrcoef(data["err_d"][ok].T)
    print(f"corner disparity error correlation: same edge {np.mean([C[0, 3], C[1, 2]]):.2f}, "
          f"across {np.mean([C[0, 1], C[0, 2], C[1, 3], C[2, 3]]):+.2f}")
    n, fe = data.get("fix_nees", np.zeros(0)), data.get("fix_error", np.zeros(0))
    if len(n):
        print(f"{len(n)} fixes: NEES mean {n.mean():.2f} (2 +- {1.96 * 2 / np.sqrt(len(n)):.2f} for a calibrated "
              f"2-D fix), median {np.median(n):.2f} (1.39); median error {np.median(fe):.3f} m, within 20 m "
              f"{np.median(fe[data['fix_range'] <= 20]) if (data['fix_range'] <= 20).any() else np.nan:.3f} m "
              f"({(data['fix_range'] <= 20).sum()} fixes)")
    print(f"{ok.sum()} markers ranged from four corners of {len(ok)}; centre disparity error RMS "
          f"{np.sqrt(np.mean(e[ok] ** 2)):.4f} px, mean {np.mean(e[ok]):+.4f}, median |e| "
          f"{np.median(np.abs(e[ok])):.4f}, 99 % {np.percentile(np.abs(e[ok]), 99):.4f}")
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

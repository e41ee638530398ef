"""Real data for LanBLoc's measurement side (see ``DESIGN.md``, "Real data").

* :func:`middlebury_motorcycle` — the Middlebury 2014 "motorcycle" pair at ¼
  scale from scikit-image, with its ground-truth disparity and the rectified
  camera from its docstring (f = 994.978 px, cx = 311.193, cy = 254.877,
  B = 0.193001 m, doffs = 31.086 px).  :func:`motorcycle_evaluation` scores
  SGBM against the ground truth and box-median depths over a grid of boxes.
* :func:`load_plaza1` — the Plaza1 range-only robot data set shipped in the
  gtsam wheel (``gtsam/Data/Plaza1_.mat``: ground truth ``GT`` at 5 Hz,
  odometry ``DR`` = (t, Δdistance, Δheading), ranges ``TD`` = (t, robot,
  beacon, range) and beacon positions ``TL``), parsed and checked by
  :func:`safenav.logs.load_plaza`.  The range rows are sorted by time (two
  are out of order in the file).
* :func:`plaza1_ekf` — localisation from odometry and the real ranges with an
  EKF whose state is augmented by the range *scale* bias: the ranges read
  long by about 7 % of the distance (2.6–2.9 m on average here), so the
  measurement model is ``r = (1 + k)·‖p − a‖ + v`` and ``k`` is estimated
  online (state ``(x, y, θ, k)``).  :func:`plaza1_core_filter` runs the same
  data through the core BMM EKF or particle filter (``filter_trajectory``) with
  the ranges divided by ``1 + k̂`` from the augmented EKF (bias modelled, not
  estimated, in that pass).  That k̂ is the augmented EKF's value at the *end*
  of the run, so these figures are look-ahead, not online.  The online,
  causal path is ``safenav replay`` (:mod:`safenav.replay`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..logs import load_plaza, plaza1_path

__all__ = ["middlebury_motorcycle", "motorcycle_evaluation", "Plaza1", "load_plaza1", "plaza1_ekf",
           "plaza1_core_filter", "Plaza1Result"]


# ---------------------------------------------------------------------------
# Middlebury motorcycle
# ---------------------------------------------------------------------------

def middlebury_motorcycle():
    """``(left, right, disparity_gt, camera)``: uint8 RGB images (500, 741, 3),
    ground-truth disparity (NaN where unknown; the file marks those inf) and
    the :class:`~safenav.vision.RectifiedCamera` in metres."""
    from skimage import data

    from ..vision import RectifiedCamera

    left, right, gt = data.stereo_motorcycle()
    gt = np.where(np.isfinite(gt), gt, np.nan).astype(np.float32)
    cam = RectifiedCamera(f=994.978, cx=311.193, cy=254.877, baseline=0.193001, doffs=31.086,
                          width=left.shape[1], height=left.shape[0])
    return left, right, gt, cam


def motorcycle_evaluation(*, box: int = 40, num_disparities: int = 64, block_size: int = 3,
                          mode: str = "sgbm_3way", **sgbm) -> dict:
    """SGBM on the motorcycle pair against the ground truth.

    Returns ``bad2`` (fraction of pixels with both a ground truth and an SGBM
    disparity whose error exceeds 2 px), ``mae`` (mean absolute disparity
    error there), ``density`` (fraction of ground-truth pixels SGBM gives a
    disparity), and for a grid of ``box``×``box`` boxes the box-median depth
    against the median ground-truth depth of the same box: ``depth_rel_errors``
    (array), ``depth_median_rel_error`` and ``depth_p90_rel_error``, and
    ``n_boxes``/``n_ranged``.
    """
    from ..vision import StereoMatcher

    left, right, gt, cam = middlebury_motorcycle()
    m = StereoMatcher(cam, num_disparities=num_disparities, block_size=block_size, mode=mode, **sgbm)
    d = m.disparity(left, right)
    has_gt = np.isfinite(gt)
    both = has_gt & np.isfinite(d)
    err = np.abs(d - gt)[both]
    z_gt = cam.depth_of(gt)
    rel = []
    n_boxes = 0
    for y0 in range(0, cam.height - box + 1, box):
        for x0 in range(num_disparities, cam.width - box + 1, box):  # SGBM's invalid left band excluded
            g = z_gt[y0:y0 + box, x0:x0 + box]
            if np.isfinite(g).mean() < 0.5:
                continue
            n_boxes += 1
            r = m.box_range(d, (x0, y0, x0 + box, y0 + box))
            if r.ok:
                zt = float(np.nanmedian(g))
                rel.append(abs(r.range - zt) / zt)
    rel = np.asarray(rel)
    return dict(bad2=float((err > 2).mean()), mae=float(err.mean()), density=float(both.sum() / has_gt.sum()),
                depth_rel_errors=rel, depth_median_rel_error=float(np.median(rel)),
                depth_p90_rel_error=float(np.percentile(rel, 90)), n_boxes=n_boxes, n_ranged=len(rel))


# ---------------------------------------------------------------------------
# Plaza1
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class Plaza1:
    """Plaza1 (range-only): arrays as in the gtsam ``Plaza1_.mat``."""

    gt: np.ndarray        #: (N+1, 4) t, x, y, θ at the odometry times
    odometry: np.ndarray  #: (N, 3) t, Δdistance, Δheading
    ranges: np.ndarray    #: (M, 3) t, beacon id, range — sorted by time
    beacons: dict         #: beacon id → (x, y)


def load_plaza1(path=None) -> Plaza1:
    """Load Plaza1 from ``Plaza1_.mat`` (default: the copy in the gtsam wheel,
    :func:`~safenav.logs.plaza1_path`), parsed and checked by
    :func:`~safenav.logs.load_plaza`."""
    log = load_plaza(path or plaza1_path())
    if log.truth is None:
        raise ValueError(f"{path}: GT has no rows")
    ev = log.events

    def columns(rows, names):
        return np.ascontiguousarray(rows[list(names)].to_numpy(np.float64))

    return Plaza1(gt=columns(log.truth, ("t", "x", "y", "heading")),
                  odometry=columns(ev[ev["kind"] == "odometry"], ("t", "distance", "heading_change")),
                  ranges=columns(ev[ev["kind"] == "range"], ("t", "landmark", "range")),
                  beacons=dict(log.landmarks))


@dataclass(frozen=True)
class Plaza1Result:
    times: np.ndarray       #: (N+1,) estimate times (odometry)
    states: np.ndarray      #: (N+1, k) estimates
    rmse: float             #: position RMSE against ground truth (m)
    n_updates: int
    n_rejected: int
    scale: float            #: final range scale bias estimate k̂ (ranges ≈ (1 + k)·true)


def _position_rmse(states_xy, gt) -> float:
    return float(np.sqrt(np.mean(np.sum((states_xy - gt[:, 1:3]) ** 2, axis=1))))


def plaza1_ekf(data: Plaza1 | None = None, *, estimate_scale: bool = True, range_std: float = 1.0,
               odometry_std=(0.05, 0.01), scale_walk: float = 1e-5, gate: float = 0.999) -> Plaza1Result:
    """EKF over ``(x, y, θ, k)`` from odometry and the beacon ranges.

    Prediction per odometry row ``(Δd, Δθ)``: ``x += Δd·cos(θ + Δθ/2)``,
    ``y += Δd·sin(θ + Δθ/2)``, ``θ += Δθ``, ``k`` a random walk with step
    ``scale_walk``; odometry noise σ = ``odometry_std`` (m, rad per step).
    Update per range: ``r = (1 + k)·‖p − a‖``, σ = ``range_std``, Joseph form,
    NIS gate at probability ``gate`` (Plaza1 has gross range outliers).
    ``estimate_scale=False`` fixes ``k = 0`` (the plain range model).
    The filter starts at the first ground-truth pose (as usual for Plaza).
    """
    from scipy.stats import chi2

    d = data or load_plaza1()
    gt, od, rg = d.gt, d.odometry, d.ranges
    x = np.array([gt[0, 1], gt[0, 2], gt[0, 3], 0.0])
    P = np.diag([0.1, 0.1, 0.02, 0.05 if estimate_scale else 0.0]) ** 2
    Qo = np.diag(np.square(odometry_std))
    thr = chi2.ppf(gate, 1)
    out = np.empty((len(od) + 1, 4))
    out[0] = x
    j = 0
    n_up = n_rej = 0
    for i, (t, dd, dth) in enumerate(od):
        # measurements up to this odometry time
        while j < len(rg) and rg[j, 0] <= t:
            a = d.beacons[int(rg[j, 1])]
            dx, dy = x[0] - a[0], x[1] - a[1]
            rho = math.hypot(dx, dy)
            s = 1.0 + x[3]
            H = np.array([s * dx / rho, s * dy / rho, 0.0, rho if estimate_scale else 0.0])
            y = rg[j, 2] - s * rho
            S = H @ P @ H + range_std**2
            if y * y / S > thr:
                n_rej += 1
            else:
                K = P @ H / S
                x = x + K * y
                IKH = np.eye(4) - np.outer(K, H)
                P = IKH @ P @ IKH.T + np.outer(K, K) * range_std**2
                n_up += 1
            j += 1
        c, sn = math.cos(x[2] + dth / 2), math.sin(x[2] + dth / 2)
        F = np.eye(4)
        F[0, 2], F[1, 2] = -dd * sn, dd * c
        G = np.array([[c, -dd * sn / 2], [sn, dd * c / 2], [0.0, 1.0], [0.0, 0.0]])
        x = x + np.array([dd * c, dd * sn, dth, 0.0])
        P = F @ P @ F.T + G @ Qo @ G.T
        if estimate_scale:
            P[3, 3] += scale_walk**2
        out[i + 1] = x
    return Plaza1Result(times=np.concatenate([[gt[0, 0]], od[:, 0]]), states=out,
                        rmse=_position_rmse(out[:, :2], gt), n_updates=n_up, n_rejected=n_rej,
                        scale=float(x[3]))


def plaza1_core_filter(filter: str = "ekf", data: Plaza1 | None = None, *, scale: float | None = None,
                       range_std: float = 1.5, n_particles: int = 2000, seed: int = 0, gate: float = 0.999):
    """Run Plaza1 through the core :func:`~safenav.filters.filter_trajectory`
    (BMM state ``(x, y, v, θ)``, ``filter`` = "ekf" or "pf").

    Controls per odometry step are ``(Δd/Δt, Δθ)`` with a BMM whose limits do
    not bind (Δt = 0.2 s, the odometry rate); ranges are put on the step at or
    after their time (the last one wins when two fall in one step) and divided
    by ``1 + scale`` (default: the scale the augmented :func:`plaza1_ekf`
    estimates online from the same data).  The EKF uses an NIS gate; the PF
    has none (its likelihood is Gaussian, so gross outliers are absorbed by
    the spread of ``range_std``).
    """
    from ..filters import filter_trajectory
    from ..motion import BmmParams

    d = data or load_plaza1()
    if scale is None:
        scale = plaza1_ekf(d).scale
    gt, od, rg = d.gt, d.odometry, d.ranges
    dt = float(np.median(np.diff(od[:, 0])))
    params = BmmParams(acceleration=100.0, deceleration=100.0, max_speed=20.0, max_heading_rate=20.0, dt=dt,
                       terrain_effect=0.0, speed_noise=0.05, heading_noise=0.02, position_noise=0.02)
    controls = np.column_stack([od[:, 1] / dt, od[:, 2]])
    ids = sorted(d.beacons)
    col = {b: i for i, b in enumerate(ids)}
    ranges = np.full((len(od), len(ids)), np.nan)
    step = np.searchsorted(od[:, 0], rg[:, 0], side="left").clip(0, len(od) - 1)
    for k, (_, b, r) in zip(step, rg):
        ranges[k, col[int(b)]] = r / (1.0 + scale)
    landmarks = np.array([d.beacons[b] for b in ids])
    x0 = np.array([gt[0, 1], gt[0, 2], 0.0, gt[0, 3]])
    P0 = np.diag([0.1, 0.1, 0.1, 0.02]) ** 2
    res = filter_trajectory(controls, x0, P0, params=params, filter=filter, ranges=ranges, range_std=range_std,
                            landmarks=landmarks, n_particles=n_particles, seed=seed,
                            gate=gate if filter == "ekf" else 0.0)
    return Plaza1Result(times=np.concatenate([[gt[0, 0]], od[:, 0]]), states=res.states,
                        rmse=_position_rmse(res.states[:, :2], gt), n_updates=res.n_updates,
                        n_rejected=res.n_rejected, scale=float(scale))

"""Real data for LanBLoc's measurement side (``docs/lanbloc.md``, "Real data").

* :func:`middlebury_motorcycle` — the Middlebury 2014 "motorcycle" pair at ¼
  scale from scikit-image, with its ground-truth disparity and the rectified
  camera from its docstring (f = 994.978 px, cx = 311.193, cy = 254.877,
  B = 0.193001 m, doffs = 31.086 px).  :func:`motorcycle_evaluation` scores
  SGBM against the ground truth and box-median depths over a grid of boxes.
* :func:`middlebury_aloe` — the Middlebury 2006 "Aloe" pair at full size
  from OpenCV's sample data (Debian ``opencv-doc``).
  :func:`middlebury_range_table` runs SGBM on both pairs with a fixed 64
  disparities and with the search from geometry
  (:func:`~safenav.vision.stereo.disparity_range`), scored Middlebury-style
  two ways: unmatched pixels counted as bad, and over matched pixels only
  (with the density).  ``python -m safenav.experiments.real OUT`` writes it.
* :func:`load_plaza1` — the Plaza1 range-only robot data set shipped in the
  gtsam wheel (``gtsam/Data/Plaza1_.mat``: ground truth ``GT`` at 5 Hz,
  odometry ``DR`` = (t, Δdistance, Δheading), ranges ``TD`` = (t, robot,
  beacon, range) and beacon positions ``TL``), parsed and checked by
  :func:`safenav.logs.load_plaza`.  The range rows are sorted by time (two
  are out of order in the file).
  Localisation on Plaza1 is ``safenav replay`` (:mod:`safenav.replay`: the
  online core localizer with range-scale and heading-rate-bias states, the
  ``plaza`` preset), the one Plaza path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..logs import load_plaza, plaza1_path

__all__ = ["middlebury_motorcycle", "motorcycle_evaluation", "middlebury_aloe", "sgbm_evaluation",
           "middlebury_range_table", "write_middlebury_table", "Plaza1", "load_plaza1"]


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
                          mode: str = "sgbm_3way", min_disparity: int = 0, **sgbm) -> dict:
    """SGBM on the motorcycle pair against the ground truth.

    Returns ``bad2`` (fraction of pixels with both a ground truth and an SGBM
    disparity whose error exceeds 2 px: over matched pixels only), ``mae``
    (mean absolute disparity error there), ``density`` (fraction of
    ground-truth pixels SGBM gives a disparity); ``bad2_all`` (the same
    error, unmatched ground-truth pixels counted as bad) and ``scores``, the
    full :class:`~safenav.vision.scores.DisparityScores` (bad-0.5/1/2/4 both
    ways); and for a grid of ``box``×``box`` boxes the box-median depth
    against the median ground-truth depth of the same box: ``depth_rel_errors``
    (array), ``depth_median_rel_error`` and ``depth_p90_rel_error``, and
    ``n_boxes``/``n_ranged``.  Boxes start right of SGBM's unmatched left band
    (``min_disparity + num_disparities`` columns).
    """
    from ..vision import StereoMatcher, disparity_scores

    left, right, gt, cam = middlebury_motorcycle()
    m = StereoMatcher(cam, min_disparity=min_disparity, num_disparities=num_disparities, block_size=block_size,
                      mode=mode, **sgbm)
    d = m.disparity(left, right)
    scores = disparity_scores(d, gt)
    z_gt = cam.depth_of(gt)
    rel = []
    n_boxes = 0
    band = max(min_disparity + num_disparities, 0)
    for y0 in range(0, cam.height - box + 1, box):
        for x0 in range(band, cam.width - box + 1, box):  # SGBM's invalid left band excluded
            g = z_gt[y0:y0 + box, x0:x0 + box]
            if np.isfinite(g).mean() < 0.5:
                continue
            n_boxes += 1
            r = m.box_range(d, (x0, y0, x0 + box, y0 + box))
            if r.ok:
                zt = float(np.nanmedian(g))
                rel.append(abs(r.range - zt) / zt)
    rel = np.asarray(rel)
    return dict(bad2=scores.bad(2.0, "matched"), bad2_all=scores.bad(2.0, "all"), mae=scores.mae,
                density=scores.density, scores=scores,
                depth_rel_errors=rel, depth_median_rel_error=float(np.median(rel)),
                depth_p90_rel_error=float(np.percentile(rel, 90)), n_boxes=n_boxes, n_ranged=len(rel))


# ---------------------------------------------------------------------------
# Middlebury Aloe (Debian's opencv-doc)
# ---------------------------------------------------------------------------

#: Where Debian's ``opencv-doc`` puts OpenCV's sample data (``aloeL.jpg``,
#: ``aloeR.jpg``, ``aloeGT.png``; also the chessboard pairs).
OPENCV_SAMPLE_DATA = Path("/usr/share/doc/opencv-doc/examples/data")

#: The nominal rig given to Aloe: Middlebury describes its 2005/2006 sets as
#: taken with f = 3740 px and B = 160 mm at full size (quoted, not checked
#: here: nothing that ships with the pair says so).  ``doffs`` is 0 because
#: these files leave out the crop offset (``dmin``): the depths are nominal.
#: The disparity range below is exact all the same, since the near depth is
#: made from a ground-truth disparity through this same camera.
ALOE_NOMINAL_F_PX = 3740.0
ALOE_NOMINAL_BASELINE_M = 0.160


def middlebury_aloe(folder=None):
    """``(left, right, disparity_gt, camera)`` of the Middlebury 2006 "Aloe"
    pair at full size (1282×1110) as OpenCV ships it in its sample data
    (Debian ``opencv-doc``: :data:`OPENCV_SAMPLE_DATA`).

    ``left``/``right`` are uint8 RGB (the files are JPEG, so they carry
    compression noise the original PNGs do not); ``disparity_gt`` is
    ``aloeGT.png`` as float32 full-size pixels with its unknown pixels (0)
    NaN; ``camera`` is the nominal :class:`~safenav.vision.RectifiedCamera`
    (:data:`ALOE_NOMINAL_F_PX`, :data:`ALOE_NOMINAL_BASELINE_M`, ``doffs = 0``).
    The 2006 sets have no ``calib.txt`` and so no ``ndisp``.  Raises
    ``FileNotFoundError`` naming the file when the data are not installed.
    """
    import cv2

    from ..vision import RectifiedCamera

    folder = Path(folder) if folder is not None else OPENCV_SAMPLE_DATA
    images = []
    for name, flag in (("aloeL.jpg", cv2.IMREAD_COLOR), ("aloeR.jpg", cv2.IMREAD_COLOR),
                       ("aloeGT.png", cv2.IMREAD_UNCHANGED)):
        path = folder / name
        img = cv2.imread(str(path), flag) if path.is_file() else None
        if img is None:
            raise FileNotFoundError(f"{path}: not found or not an image (apt-get install opencv-doc)")
        images.append(img)
    left, right, gt = images
    if gt.ndim != 2 or gt.shape != left.shape[:2] or left.shape != right.shape:
        raise ValueError(f"Aloe files disagree in size: left {left.shape}, right {right.shape}, gt {gt.shape}")
    left = np.ascontiguousarray(left[:, :, ::-1])
    right = np.ascontiguousarray(right[:, :, ::-1])
    gt = np.where(gt > 0, gt, np.nan).astype(np.float32)
    h, w = gt.shape
    cam = RectifiedCamera(f=ALOE_NOMINAL_F_PX, cx=(w - 1) / 2.0, cy=(h - 1) / 2.0,
                          baseline=ALOE_NOMINAL_BASELINE_M, doffs=0.0, width=w, height=h)
    return left, right, gt, cam


def sgbm_evaluation(left, right, gt, camera, *, min_disparity: int = 0, num_disparities: int = 64,
                    block_size: int = 3, mode: str = "sgbm_3way", repeats: int = 1, **sgbm) -> dict:
    """SGBM on a rectified pair scored against ``gt`` both ways
    (:func:`~safenav.vision.scores.disparity_scores`): the scores' columns
    (``bad2_all``, ``bad2_matched``, …, ``density``, ``mae``), the search
    (``min_disparity``, ``num_disparities``) and ``time ms``, the median of
    ``repeats`` SGBM runs (the first builds the matcher's buffers, and is
    timed too)."""
    import time

    from ..vision import StereoMatcher, disparity_scores

    m = StereoMatcher(camera, min_disparity=min_disparity, num_disparities=num_disparities,
                      block_size=block_size, mode=mode, **sgbm)
    times = []
    for _ in range(max(int(repeats), 1)):
        t0 = time.perf_counter()
        d = m.disparity(left, right)
        times.append(time.perf_counter() - t0)
    return dict(min_disparity=int(min_disparity), num_disparities=int(num_disparities),
                **disparity_scores(d, gt).as_dict(), **{"time ms": 1e3 * float(np.median(times))})


def middlebury_range_table(datasets=("aloe", "motorcycle"), *, repeats: int = 1, block_size: int = 3,
                           mode: str = "sgbm_3way") -> "pd.DataFrame":
    """Fixed 64 disparities against the search from geometry
    (:func:`~safenav.vision.stereo.disparity_range`), per data set, scored
    both ways.  Rows per data set:

    * ``fixed 64`` — ``min_disparity = 0``, ``num_disparities = 64``;
    * ``geometry, far = inf`` — ``near_m`` = the depth of the ground truth's
      largest disparity (``Z = f·B/(d_max + doffs)``), ``far_m = ∞``;
    * ``geometry, far = gt`` — the same ``near_m``, ``far_m`` = the depth of
      the ground truth's smallest disparity.

    Neither data set ships an ``ndisp``: the 2006 Aloe has no ``calib.txt``
    and scikit-image's motorcycle gives only f, B, the principal point and
    doffs; so the depth range comes from the ground truth.  Columns:
    ``dataset``, ``search``, ``near_m``, ``far_m``, ``gt_disparity_min``/``max``,
    then :func:`sgbm_evaluation`'s.
    """
    import pandas as pd

    from ..vision import disparity_range

    loaders = {"aloe": middlebury_aloe, "motorcycle": middlebury_motorcycle}
    rows = []
    for name in datasets:
        if name not in loaders:
            raise ValueError(f"dataset {name!r} is unknown (have: {', '.join(loaders)})")
        left, right, gt, cam = loaders[name]()
        g = gt[np.isfinite(gt)]
        g_min, g_max = float(g.min()), float(g.max())
        near = float(cam.depth_of(g_max))
        far_gt = float(cam.depth_of(g_min)) if g_min + cam.doffs > 0 else math.inf
        searches = [("fixed 64", math.nan, math.nan, (0, 64))]
        for label, far in (("geometry, far = inf", math.inf), ("geometry, far = gt", far_gt)):
            searches.append((label, near, far, disparity_range(cam, near, far, block_size=block_size)))
        for label, near_m, far_m, (lo, num) in searches:
            ev = sgbm_evaluation(left, right, gt, cam, min_disparity=lo, num_disparities=num,
                                 block_size=block_size, mode=mode, repeats=repeats)
            rows.append(dict(dataset=name, search=label, near_m=near_m, far_m=far_m, gt_disparity_min=g_min,
                             gt_disparity_max=g_max, **ev))
    return pd.DataFrame(rows)


#: The columns of :func:`middlebury_range_table` that the Markdown table shows.
MIDDLEBURY_SUMMARY_COLUMNS = ("dataset", "search", "min_disparity", "num_disparities", "bad2_all", "bad2_matched",
                              "density", "bad1_all", "bad1_matched", "bad4_all", "bad4_matched", "mae", "time ms")


def write_middlebury_table(folder, **options) -> list[Path]:
    """Run :func:`middlebury_range_table` and write ``middlebury.csv`` (all
    columns), ``middlebury.md`` (:data:`MIDDLEBURY_SUMMARY_COLUMNS`) and the
    SGBM times in ``middlebury_timings.csv``."""
    from ..results import write_table

    df = middlebury_range_table(**options)
    folder = Path(folder)
    title = ("Middlebury, SGBM (3-way, block 3): fixed 64 disparities against the search from geometry; "
             "bad-t_all counts unmatched ground-truth pixels as bad, bad-t_matched is over matched pixels "
             "(density = matched / ground-truth pixels)")
    files = write_table(df, folder / "middlebury", parquet=False)
    files += write_table(df[list(MIDDLEBURY_SUMMARY_COLUMNS)], folder / "middlebury_summary", parquet=False,
                         markdown=title)
    return files


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


if __name__ == "__main__":  # python -m safenav.experiments.real [OUT_FOLDER] [REPEATS]
    import sys

    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/experiments/real")
    for f in write_middlebury_table(out, repeats=int(sys.argv[2]) if len(sys.argv) > 2 else 3):
        print(f)
    print((out / "middlebury_summary.md").read_text())

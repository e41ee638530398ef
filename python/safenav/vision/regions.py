"""LanBLoc's region pipeline (ours): a :class:`~safenav.vision.frame.StereoFrame`
processed region by region, so that the work per frame grows with the
markers in view rather than with the image (steps 2–5 of
:mod:`safenav.vision.lanbloc`, [SafeNav §IV-A]).

Detection runs on each of the left image's regions at a pyramid level chosen
by the marker's size; a fiducial's corners are refined at full resolution
(or a coarser level for a large marker); with ``ranging="corners"`` the
marker is found in the right image by template matching along its rows and
its corners are triangulated, with ``"sgbm"`` SGBM runs on a strip around
each box only.  The ranges then go through the shared ranging and
trilateration step (:class:`~safenav.vision.ranging.LandmarkRanging`), as in
the whole-frame pipeline (:mod:`safenav.vision.full_frame`).
"""

from __future__ import annotations

import dataclasses
import math
import time

import cv2
import numpy as np

from .detect import Detection, Detector
from .ranging import LandmarkRanging, check_faults, check_finite, check_pixels, check_ranging
from .frame import StereoFrame
from .sighting import LandmarkSighting, LanBLocResult

__all__ = ["RegionPipeline"]


class RegionPipeline:
    """StereoFrames through LanBLoc, region by region (the parameters are
    :class:`~safenav.vision.lanbloc.LanBLoc`'s of the same names)."""

    def __init__(self, ranger: LandmarkRanging, detector: Detector, *, ranging: str = "sgbm",
                 band_margin_px: int = 24, detect_side_px: float = 48.0, region_margin_px: int = 8,
                 min_correlation: float = 0.8):
        self.ranger = ranger
        self.detector = detector
        self.ranging = check_ranging(ranging, detector)
        self.band_margin_px = check_pixels("band_margin_px", band_margin_px)
        self.detect_side_px = check_finite("detect_side_px", detect_side_px, positive=True)
        if self.detect_side_px < 16:
            raise ValueError(f"detect_side_px = {detect_side_px!r}: must be >= 16 (ArUco needs ~4 px per cell)")
        self.region_margin_px = check_pixels("region_margin_px", region_margin_px)
        self.min_correlation = check_finite("min_correlation", min_correlation)
        if not -1.0 <= self.min_correlation <= 1.0:
            raise ValueError(f"min_correlation = {min_correlation!r}: must be in [-1, 1]")

    def localize(self, frame: StereoFrame, *, faults=None, position=None, seed: int = 0) -> LanBLocResult:
        """The pipeline on a :class:`~safenav.vision.frame.StereoFrame`, region by region (ours).

        Detection runs on each of the left image's :meth:`~StereoFrame.regions`
        at the pyramid level where its smallest marker is about
        ``detect_side_px`` pixels wide (grown by ``region_margin_px`` pixels
        of that level), and a fiducial's corners found there are refined
        (``cv2.cornerSubPix``, one patch, in a window of about 0.7 cell) at
        full resolution, or for a marker wider than :attr:`REFINE_SIDE_PX` at
        the level where it is that wide.  With ``ranging="corners"`` the same
        is done in the right image and
        :meth:`~safenav.vision.ranging.LandmarkRanging.observe_corners`
        triangulates the corners of the markers found in both (matched by
        their decoded id); with ``"sgbm"`` (natural landmarks, e.g. YOLO
        boxes) SGBM runs on a strip around each box only (its rows and columns
        plus the disparity range), and
        :meth:`~safenav.vision.ranging.LandmarkRanging.observe` takes the box
        median as for a whole frame.  The frame's rig must be this pipeline's
        camera.
        """
        faults = check_faults(faults)
        if not isinstance(frame, StereoFrame):
            raise ValueError(f"frame = {frame!r}: must be a safenav.vision.render.StereoFrame")
        r = frame.rig
        c = self.ranger.camera
        if (r.width, r.height) != (c.width, c.height) or abs(r.focal_length_px - c.f) > 1e-9 * c.f:
            raise ValueError(f"frame's rig ({r.width}x{r.height}, f = {r.focal_length_px:g} px) is not the "
                             f"pipeline's camera ({c.width}x{c.height}, f = {c.f:g} px)")
        t = {"rectify": 0.0}
        t1 = time.perf_counter()
        found = self._detect_regions(frame, "left")
        level = {id(d): (lv, lr, patch) for d, lv, lr, patch in found}
        dets = self.ranger.known([d for d, *_ in found])
        t2 = time.perf_counter()
        t["detect"] = t2 - t1
        if not dets:
            return self.ranger.no_landmarks(t)
        if self.ranging == "corners":
            obs = []
            for d in dets:
                lv, lr, patch = level[id(d)]
                r, rr, why = self._find_in_right(frame, d, lv, patch)
                obs.append(self.ranger.observe_corners(d, r, refine_level=max(lr, rr), reason=why))
            obs = tuple(obs)
            t3 = time.perf_counter()
            t["disparity"] = t3 - t2
        else:
            obs = tuple(self._observe_strip(frame, d) for d in dets)
            t3 = time.perf_counter()
            t["disparity"] = t3 - t2
        return self.ranger.solve(dets, obs, t, t3, faults, position, seed)

    def _detect_regions(self, frame: StereoFrame, camera: str) -> list[tuple[Detection, int, int, tuple | None]]:
        """Detections in ``camera``'s regions of ``frame``, in level-0 pixels, corners refined, each with
        the pyramid levels it was found and refined at and the patch it was found in (image, its
        level-pixel origin)."""
        out = []
        for box, side in frame.regions(camera, self.region_margin_px):
            level = 0
            while level < 6 and side / (1 << (level + 1)) >= self.detect_side_px:
                level += 1
            k = 1 << level
            # the margin counts at the detection level: ArUco needs background around the quiet zone
            g = self.region_margin_px * (k - 1)
            box = (max(box[0] - g, 0), max(box[1] - g, 0), min(box[2] + g, frame.rig.width),
                   min(box[3] + g, frame.rig.height))
            img = frame.patch(camera, box, level)
            off = np.array([box[0] // k, box[1] // k], float)
            for d in self.detector.detect(img):
                if d.corners is None:   # a box detector: scale the box
                    x0, y0, x1, y1 = d.box
                    bb = tuple(float(v) for v in ((np.array([x0, y0, x1, y1]).reshape(2, 2) + off + 0.5) * k - 0.5)
                               .ravel())
                    out.append((dataclasses.replace(d, box=bb), level, level, None))
                    continue
                corners, lr, _ = self._refine_corners(frame, camera,
                                                      (np.asarray(d.corners, float) + off + 0.5) * k - 0.5)
                (x0, y0), (x1, y1) = corners.min(axis=0), corners.max(axis=0)
                out.append((dataclasses.replace(d, box=(float(x0), float(y0), float(x1), float(y1)),
                                                corners=corners), level, lr, (img, box[0] // k, box[1] // k)))
        return out

    #: Largest marker side [px] refined in one patch: bigger markers are refined at the pyramid level
    #: where they are about this size.
    REFINE_SIDE_PX = 128

    def _refine_corners(self, frame: StereoFrame, camera: str, corners: np.ndarray
                        ) -> tuple[np.ndarray, int, bool]:
        """``cv2.cornerSubPix`` of the four corners (level-0 pixels) in one patch around the marker, at
        the finest pyramid level where the marker is at most :attr:`REFINE_SIDE_PX` wide, in a window of
        about 0.7 marker cell; returns the corners (level 0), that level, and whether every corner was
        refined (a corner whose window leaves the image keeps its position)."""
        side = float(np.min(np.linalg.norm(corners - np.roll(corners, 1, axis=0), axis=1)))
        level = 0
        while side / (1 << level) > self.REFINE_SIDE_PX and level < 6:
            level += 1
        k = 1 << level
        c = (corners + 0.5) / k - 0.5                       # level-L pixels
        cells = getattr(getattr(self.detector, "dictionary", None), "markerSize", 4) + 2
        w = int(min(max(round(0.7 * side / k / cells), 2), 12))
        W, H = -(-frame.rig.width // k), -(-frame.rig.height // k)
        lo = np.floor(c).astype(int) - w - 3
        hi = np.floor(c).astype(int) + w + 5
        inside = (lo >= 0).all(axis=1) & (hi[:, 0] <= W) & (hi[:, 1] <= H)
        out = corners.copy()
        if not inside.any():
            return out, level, False
        x0, y0 = lo[inside].min(axis=0)
        x1, y1 = hi[inside].max(axis=0)
        img = frame.patch(camera, (x0 * k, y0 * k, min(x1 * k, frame.rig.width), min(y1 * k, frame.rig.height)),
                          level)
        p = (c[inside] - [x0, y0]).astype(np.float32).reshape(-1, 1, 2)
        cv2.cornerSubPix(img, p, (w, w), (-1, -1), (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.001))
        out[inside] = (p.reshape(-1, 2) + [x0, y0] + 0.5) * k - 0.5
        return out, level, bool(inside.all())

    def _find_in_right(self, frame: StereoFrame, det: Detection, level: int, patch=None
                       ) -> tuple[Detection | None, int, str]:
        """The marker of the left detection ``det`` in the right image: its patch (pyramid level
        ``level``; cut from ``patch``, the detection's, when it holds it) matched along its rows
        over the disparity search (normalised cross-correlation,
        parabolic sub-pixel peak), then the corners refined (:meth:`_refine_corners`; returned with
        its level).  ``None``, with the reason, when the best correlation is below
        ``min_correlation`` or a corner's window leaves the right image."""
        k = 1 << level
        W, H = frame.rig.width, frame.rig.height
        cl = np.asarray(det.corners, float)
        g = 2 * k
        tx0, ty0 = max(int(math.floor(cl[:, 0].min())) - g, 0), max(int(math.floor(cl[:, 1].min())) - g, 0)
        tx1, ty1 = min(int(math.ceil(cl[:, 0].max())) + g, W), min(int(math.ceil(cl[:, 1].max())) + g, H)
        p = self.ranger.matcher.sgbm_params
        d_lo, d_hi = p["min_disparity"], p["min_disparity"] + p["num_disparities"]
        sx0, sx1 = max(tx0 - d_hi - g, 0), min(tx1 - d_lo + g, W)
        sy0, sy1 = max(ty0 - g, 0), min(ty1 + g, H)
        if sx1 - sx0 < tx1 - tx0 or sy1 - sy0 < ty1 - ty0:
            return None, 0, "not found in the right image"
        a0, b0, a1, b1 = tx0 // k, ty0 // k, -(-tx1 // k), -(-ty1 // k)
        if patch is not None and a0 >= patch[1] and b0 >= patch[2] and a1 - patch[1] <= patch[0].shape[1] \
                and b1 - patch[2] <= patch[0].shape[0]:   # the template from the patch it was found in
            tmpl = patch[0][b0 - patch[2]:b1 - patch[2], a0 - patch[1]:a1 - patch[1]]
        else:
            tmpl = frame.patch("left", (tx0, ty0, tx1, ty1), level)
        search = frame.patch("right", (sx0, sy0, sx1, sy1), level)
        if search.shape[0] < tmpl.shape[0] or search.shape[1] < tmpl.shape[1]:
            return None, 0, "not found in the right image"
        res = cv2.matchTemplate(search, tmpl, cv2.TM_CCOEFF_NORMED)
        _, score, _, (mx, my) = cv2.minMaxLoc(res)
        if not score >= self.min_correlation:
            return None, 0, (f"not found in the right image (best correlation {score:.2f} < "
                             f"min_correlation = {self.min_correlation:g})")
        sub = 0.0
        if 0 < mx < res.shape[1] - 1:
            l_, c_, r_ = res[my, mx - 1], res[my, mx], res[my, mx + 1]
            den = l_ - 2 * c_ + r_
            sub = 0.5 * (l_ - r_) / den if den < 0 else 0.0
        d = (tx0 // k - (sx0 // k + mx + sub)) * k
        dy = (ty0 // k - (sy0 // k + my)) * k
        cr, lr, whole = self._refine_corners(frame, "right", cl - [d, dy])
        if not whole:
            return None, lr, "the marker leaves the right image"
        (x0, y0), (x1, y1) = cr.min(axis=0), cr.max(axis=0)
        return dataclasses.replace(det, box=(float(x0), float(y0), float(x1), float(y1)), corners=cr,
                                   score=float(score)), lr, ""

    def _observe_strip(self, frame: StereoFrame, det: Detection) -> LandmarkSighting:
        """SGBM on the strip around ``det``'s box only (rows ± margin, columns from the box's left edge
        minus the disparity range to its right edge), then the box median as
        :meth:`~safenav.vision.ranging.LandmarkRanging.observe`."""
        rg = self.ranger
        c, p = rg.camera, rg.matcher.sgbm_params
        m = self.band_margin_px
        x0, y0, x1, y1 = det.box
        X0 = max(int(math.floor(x0)) - p["min_disparity"] - p["num_disparities"] - m, 0)
        X1 = min(int(math.ceil(x1)) + 1 + m, c.width)
        Y0 = max(int(math.floor(y0)) - m, 0)
        Y1 = min(int(math.ceil(y1)) + 1 + m, c.height)
        box = (X0, Y0, X1, Y1)
        left, right = frame.patch("left", box), frame.patch("right", box)
        mt = rg.crop_matcher(X0, Y0, X1, Y1)
        disp = mt.disparity(left, right)
        sx, sy = rg.box_shrink * (x1 - x0), rg.box_shrink * (y1 - y0)
        br = mt.box_range(disp, (x0 + sx - X0, y0 + sy - Y0, x1 - sx - X0, y1 - sy - Y0), sigma_d=rg.sigma_d,
                          max_range=rg.max_range_m)
        return rg.sighting(det, det.center, br.ok, br.range, br.sigma, br.point, float(br.disparity),
                           int(br.n_valid), br.reason)

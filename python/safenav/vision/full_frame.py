"""LanBLoc's whole-frame pipeline [SafeNav §IV-A]: the paper's pipeline, and
the reference for the region pipeline (:mod:`safenav.vision.regions`).

Per stereo pair: rectification (skipped for a rectified camera), detection
on the whole rectified left image, SGBM disparity on the band of rows that
holds the boxes (or the whole image), the box-median range of each detection
(or, with ``ranging="corners"``, the fiducial's corners found in both
images), then the shared ranging and trilateration step
(:class:`~safenav.vision.ranging.LandmarkRanging`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from .detect import Detector, check_image
from .ranging import LandmarkRanging, check_faults, check_pixels, check_ranging
from .sighting import LanBLocResult

__all__ = ["FullFramePipeline"]


class FullFramePipeline:
    """Whole stereo pairs through LanBLoc (the parameters are
    :class:`~safenav.vision.lanbloc.LanBLoc`'s of the same names)."""

    def __init__(self, ranger: LandmarkRanging, detector: Detector, *, ranging: str = "sgbm", row_band: bool = True,
                 band_margin_px: int = 24):
        self.ranger = ranger
        self.detector = detector
        self.ranging = check_ranging(ranging, detector)
        self.row_band = bool(row_band)
        self.band_margin_px = check_pixels("band_margin_px", band_margin_px)

    def check_pair(self, left, right) -> tuple[np.ndarray, np.ndarray]:
        """Validate a stereo pair (uint8, non-empty, same shape, the calibration's size)."""
        left = check_image(left, "left image")
        right = check_image(right, "right image")
        if left.shape != right.shape:
            raise ValueError(f"left and right images differ in size: {left.shape} vs {right.shape}")
        want = (self.ranger.camera.height, self.ranger.camera.width)
        if left.shape[:2] != want:
            raise ValueError(f"images are {left.shape[1]}x{left.shape[0]} px but the calibration is "
                             f"{want[1]}x{want[0]} px")
        return left, right

    def disparity(self, left, right, boxes=()) -> np.ndarray:
        """SGBM disparity of the rectified pair (NaN where invalid or outside the row band)."""
        h = left.shape[0]
        if not self.row_band or len(boxes) == 0:
            return self.ranger.matcher.disparity(left, right)
        b = np.asarray(boxes, dtype=float).reshape(-1, 4)
        q = 16   # band edges on a 16-row grid, so that band matchers are reused
        y0 = max((int(math.floor(b[:, 1].min())) - self.band_margin_px) // q * q, 0)
        y1 = min(-(-(int(math.ceil(b[:, 3].max())) + 1 + self.band_margin_px) // q) * q, h)
        if y1 - y0 >= 0.8 * h or y1 <= y0:   # a band of most rows, or none (every box above or below the image)
            return self.ranger.matcher.disparity(left, right)
        out = np.full((h, left.shape[1]), np.nan, np.float32)
        m = self.ranger.crop_matcher(0, y0, self.ranger.camera.width, y1)
        out[y0:y1] = m.disparity(np.ascontiguousarray(left[y0:y1]), np.ascontiguousarray(right[y0:y1]))
        return out

    def localize(self, left, right, *, faults=None, position=None, seed: int = 0) -> LanBLocResult:
        """Run the pipeline on one stereo pair (raw if the camera needs rectification).

        ``faults``: landmark-level faults (a :class:`safenav.navigation.LandmarkFaults`) on
        the ranges before trilateration, with the vehicle's true ``position``
        and the frame's ``seed`` (see
        :meth:`~safenav.vision.ranging.LandmarkRanging.apply_faults`); ``None``: none.
        """
        faults = check_faults(faults)
        t = {}
        t0 = time.perf_counter()
        left, right = self.check_pair(left, right)
        if self.ranger.matcher.needs_rectification:
            left, right = self.ranger.matcher.rectify(left, right)
        t1 = time.perf_counter()
        t["rectify"] = t1 - t0
        dets = self.ranger.known(self.detector.detect(left))
        t2 = time.perf_counter()
        t["detect"] = t2 - t1
        if not dets:
            return self.ranger.no_landmarks(t)
        if self.ranging == "corners":
            right_dets = {d.landmark_id: d for d in self.ranger.known(self.detector.detect(right), unknown="skip")}
            t3 = time.perf_counter()
            t["disparity"] = t3 - t2
            obs = tuple(self.ranger.observe_corners(d, right_dets.get(d.landmark_id)) for d in dets)
        else:
            disp = self.disparity(left, right, [d.box for d in dets])
            t3 = time.perf_counter()
            t["disparity"] = t3 - t2
            obs = tuple(self.ranger.observe(d, disp) for d in dets)
        return self.ranger.solve(dets, obs, t, t3, faults, position, seed)

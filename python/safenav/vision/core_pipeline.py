"""The whole-frame pipeline through the core's front end (ours; [SafeNav §IV-A]):
``LanBLoc(..., backend="core")``.

With the default fiducial detector, detection, corner refinement and ranging (from
the corners, or the paper's SGBM box median) run in C++
(``safenav._core.LanBLocFrontEnd``, docs/lanbloc_cpp.md).  With a detector of the
caller's (a YOLO model for natural landmarks) and SGBM ranging, the detector runs in
Python and its boxes are ranged in C++ (``LanBLocFrontEnd.localize_boxes``), equal to
the Python pipeline's SGBM ranging bit for bit.  The sightings come back as
:class:`~safenav.vision.sighting.LandmarkSighting` and go through the same last step as
every other pipeline (:meth:`~safenav.vision.ranging.LandmarkRanging.solve`: landmark
faults, the core's trilateration, the mirror ambiguity), so the result is a
:class:`~safenav.vision.sighting.LanBLocResult` like the Python pipeline's.  It equals the
Python pipeline's on the same pair up to the two OpenCV versions' detectors (the C++ core
links Debian's OpenCV 4.6, the Python side pip's cv2): same landmarks in 98 of 100 random
frames, ranges within 1.4e-5 m median (``bench/bench_lanbloc_cpp.py``).
"""

from __future__ import annotations

import time

import numpy as np

from .. import _core
from .detect import Detection, FiducialDetector
from .ranging import LandmarkRanging, check_faults
from .sighting import LandmarkSighting, LanBLocResult

__all__ = ["CorePipeline"]


class CorePipeline:
    """Whole rectified pairs through the core's LanBLoc front end; the parameters are
    :class:`~safenav.vision.lanbloc.LanBLoc`'s.  ``detector``: a
    :class:`~safenav.vision.detect.FiducialDetector` whose marker ids are the landmark ids
    (detected in the core), or, with ``ranging="sgbm"``, any detector (detected here, ranged
    in the core)."""

    def __init__(self, ranger: LandmarkRanging, detector, check_pair, *, ranging: str = "corners",
                 row_band: bool = True, band_margin_px: int = 24):
        fiducial = isinstance(detector, FiducialDetector)
        if not fiducial and ranging != "sgbm":
            raise ValueError(f"backend = 'core' with ranging = {ranging!r} needs a FiducialDetector, got "
                             f"{type(detector).__name__}")
        if fiducial and detector._map is not None and any(m != lm for m, lm in detector._map.items()):
            raise ValueError("backend = 'core' needs marker id = landmark id (the detector's landmark_map maps "
                             "other ids)")
        self.ranger, self.detector, self._check_pair = ranger, detector, check_pair
        self.detect_in_core = fiducial   # markers detected by the core's ArUco (its own parameters)
        r, cam = ranger, ranger.camera
        c = _core.RectifiedCamera()
        c.f, c.cx, c.cy, c.baseline, c.doffs, c.width, c.height = (cam.f, cam.cx, cam.cy, cam.baseline, cam.doffs,
                                                                    cam.width, cam.height)
        s = _core.LanBLocSettings(r.corner_settings)   # the corner-noise model and row check, as the ranger's
        s.dictionary = detector.dictionary_name if fiducial else ""   # "": boxes only (localize_boxes)
        s.bearing_sigma_px = r.bearing_sigma_px
        s.max_range_m, s.min_landmarks, s.resolve_ambiguity = r.max_range_m, r.min_landmarks, r.resolve_ambiguity
        s.ranging = _core.LanBLocRanging.SGBM if ranging == "sgbm" else _core.LanBLocRanging.CORNERS
        s.sgbm = r.matcher._m.params                   # the ranger's search, resolved (the same function)
        s.min_range_m, s.sgbm_sigma_d, s.box_shrink = r.min_range_m, r.sigma_d, r.box_shrink
        s.row_band, s.band_margin_px = bool(row_band), int(band_margin_px)
        self.ranging = ranging
        self.front_end = _core.LanBLocFrontEnd(_core.LanBLocRig(c, r.camera_height_m, r.pitch_rad),
                                               {k: tuple(v[0]) for k, v in r.landmarks.items()}, s)

    def localize(self, left, right, *, faults=None, position=None, seed: int = 0) -> LanBLocResult:
        """One pair (raw if the camera needs rectification): the core's front end on the whole
        frame (or the detector's boxes ranged in the core), then :meth:`LandmarkRanging.solve`."""
        faults = check_faults(faults)
        t = {}
        t0 = time.perf_counter()
        left, right = self._check_pair(left, right)
        if self.ranger.matcher.needs_rectification:
            left, right = self.ranger.matcher.rectify(left, right)
        if left.ndim == 3:
            import cv2
            left, right = cv2.cvtColor(left, cv2.COLOR_BGR2GRAY), cv2.cvtColor(right, cv2.COLOR_BGR2GRAY)
        t1 = time.perf_counter()
        t["rectify"] = t1 - t0
        if self.detect_in_core:
            fix = self.front_end.localize(left, right)
            given = {}
        else:
            dets = self.ranger.known(self.detector.detect(left))
            t["detect"] = time.perf_counter() - t1
            if not dets:
                return self.ranger.no_landmarks(t)
            fix = self.front_end.localize_boxes(left, right, [(d.landmark_id, d.box) for d in dets])
            given = {d.landmark_id: d for d in dets}   # the detector's own, with class names and scores
        t3 = time.perf_counter()
        if self.detect_in_core:
            t["detect"], t["disparity"] = t3 - t1, 0.0
        else:
            t["disparity"] = t3 - t1 - t["detect"]
        if self.ranger.unknown_landmark == "error" and fix.unmapped:
            raise ValueError(f"detected landmark id {fix.unmapped[0]} is not in the landmark map (known ids: "
                             f"{sorted(self.ranger.landmarks)})")
        if not fix.observations:
            return self.ranger.no_landmarks(t)
        dets, obs = [], []
        for o in fix.observations:
            d = given.get(o.landmark_id)
            if d is None:
                c = np.asarray(o.corners_left)
                _, name = self.ranger.landmarks[o.landmark_id]
                d = Detection(o.landmark_id, name, tuple(o.box), 1.0, corners=c)
            dets.append(d)
            ok = bool(o.ok)
            n_valid = o.n_valid if self.ranging == "sgbm" else 4 if np.isfinite(o.corners_right).all() else 0
            obs.append(LandmarkSighting(
                landmark_id=o.landmark_id, class_name=d.class_name, box=d.box, score=d.score,
                anchor=np.asarray(o.anchor), ok=ok, range=o.range if ok else np.nan, sigma=o.sigma if ok else np.nan,
                slant_range=o.slant_range, depth=o.depth, disparity=o.disparity, n_valid=n_valid,
                bearing=o.bearing, bearing_sigma=o.bearing_sigma, reason=o.reason))
        return self.ranger.solve(dets, tuple(obs), t, t3, faults, position, seed)

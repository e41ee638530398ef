"""The step LanBLoc's two pipelines share (steps 4–5 of :mod:`safenav.vision.lanbloc`, [SafeNav §IV-A]):
from a recognised landmark and its stereo depth to a range and bearing
(:class:`~safenav.vision.sighting.LandmarkSighting`), then landmark faults
and trilateration to a fix (:class:`~safenav.vision.sighting.LanBLocResult`).

:class:`LandmarkRanging` holds the landmark map, the rectified camera and its
SGBM matcher, and the ranging and trilateration settings.  The whole-frame
pipeline (:mod:`safenav.vision.full_frame`) and the region pipeline
(:mod:`safenav.vision.regions`) each find the landmarks and measure their
depths their own way and hand them to it:

* :meth:`LandmarkRanging.observe` — the box median of an SGBM disparity map
  (``σ_Z ≈ Z²·σ_d/(f·B)``);
* :meth:`LandmarkRanging.observe_corners` — a fiducial's corners in both
  images, triangulated (ours);
* :meth:`LandmarkRanging.sighting` — slant range, horizontal range
  ``ρ = sqrt(s² − (z_ℓ − h)²)`` and bearing from a depth;
* :meth:`LandmarkRanging.solve` — landmark faults
  (:meth:`LandmarkRanging.apply_faults`), trilateration
  (:func:`~safenav.vision.localization.trilaterate`) and the mirror
  ambiguity settled by the bearings (:meth:`LandmarkRanging.bearings_agree`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Mapping, Sequence

import numpy as np

from .. import _core
from ..motion import wrap_angle
from ..world import Landmark, World
from .detect import Detection, Detector
from .localization import LocalizationResult, horizontal_range, trilaterate
from .rig import StereoRig, camera_rotation
from .sighting import REPEATED, STATUSES, LandmarkSighting, LanBLocResult
from .stereo import RectifiedCamera, StereoCalibration, StereoMatcher

__all__ = ["LandmarkRanging", "PIPELINE_SGBM", "check_ranging", "check_faults", "check_finite"]

#: Default SGBM settings for the pipeline: 3-way SGBM, uniqueness 10.  The disparity search is not
#: fixed: it follows from the camera and the depths of interest, from ``min_range_m`` at the image's
#: edge to infinity (:func:`safenav.vision.stereo.disparity_range`).
PIPELINE_SGBM = dict(block_size=5, mode="sgbm_3way", uniqueness_ratio=10, speckle_window_size=100, speckle_range=2)


def _chi2_999(dof: int) -> float:
    """The 99.9 % quantile of χ² with ``dof`` (at least 1) degrees of freedom."""
    from scipy.stats import chi2
    return float(chi2.ppf(0.999, max(dof, 1)))


def _landmark_table(landmarks) -> dict[int, tuple[np.ndarray, str]]:
    """``id → (map position (x, y, z), class name)`` from a World, Landmarks or a mapping
    (:class:`~safenav.vision.lanbloc.LanBLoc`'s ``landmarks``)."""
    if isinstance(landmarks, World):
        landmarks = landmarks.landmarks
    table = {}
    if isinstance(landmarks, Mapping):
        for k, v in landmarks.items():
            if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 0:
                raise ValueError(f"landmarks: id {k!r} must be a non-negative integer")
            try:
                p = np.asarray(v, dtype=float).ravel()
            except (TypeError, ValueError):
                p = np.zeros(0)
            if p.size not in (2, 3) or not np.isfinite(p).all():
                raise ValueError(f"landmarks[{k!r}] = {v!r}: must be a finite (x, y) or (x, y, z)")
            table[int(k)] = (np.append(p, 0.0) if p.size == 2 else p, "landmark")
        return table
    if isinstance(landmarks, (str, bytes)) or not isinstance(landmarks, Sequence):
        raise ValueError(f"landmarks = {landmarks!r}: must be a World, a sequence of Landmark or a mapping "
                         f"id -> (x, y[, z])")
    for i, lm in enumerate(landmarks):
        if not isinstance(lm, Landmark):
            raise ValueError(f"landmarks[{i}] = {lm!r}: must be a Landmark")
        table[lm.id] = (np.array([*lm.position[:2], lm.height]), lm.class_name)
    return table


def check_finite(name, v, *, positive=False, nonneg=False):
    """``v`` as a float, if a finite number (and > 0 with ``positive``, >= 0 with ``nonneg``); else
    ``ValueError`` naming ``name``."""
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v):
        raise ValueError(f"{name} = {v!r}: must be a finite number")
    if (positive and not v > 0) or (nonneg and v < 0):
        raise ValueError(f"{name} = {v!r}: must be {'> 0' if positive else '>= 0'}")
    return float(v)


def check_faults(faults):
    """``faults`` as given (a validated :class:`safenav.navigation.LandmarkFaults`) or ``None``."""
    if faults is None:
        return None
    if not isinstance(faults, _core.LandmarkFaults):
        raise ValueError(f"faults = {faults!r}: must be a safenav.navigation.LandmarkFaults or None")
    faults.validate()   # ValueError naming the bad field (faults.dropout_probability = ...)
    return faults


def check_ranging(ranging: str, detector) -> str:
    """``ranging`` (``"sgbm"`` or ``"corners"``) checked against the ``detector`` it needs."""
    if not isinstance(detector, Detector):
        raise ValueError(f"detector = {detector!r}: must be a safenav.vision.detect.Detector")
    if ranging not in ("sgbm", "corners"):
        raise ValueError(f"ranging = {ranging!r}: must be 'sgbm' or 'corners'")
    if ranging == "corners" and not hasattr(detector, "dictionary"):
        raise ValueError(f"ranging = 'corners' needs a fiducial detector (marker corners), not "
                         f"{type(detector).__name__}")
    return ranging


def check_pixels(name: str, value) -> int:
    """A pixel count: an integer >= 0 (not a bool)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise ValueError(f"{name} = {value!r}: must be an integer >= 0")
    return int(value)


def _matcher(camera, min_range_m: float, sgbm: Mapping | None) -> StereoMatcher:
    """The pipeline's SGBM matcher for ``camera``: its search from ``min_range_m`` to infinity."""
    if isinstance(camera, StereoMatcher):
        return camera
    if isinstance(camera, (RectifiedCamera, StereoCalibration)):
        near = min_range_m
        if isinstance(camera, RectifiedCamera):   # the depth of a landmark at min_range_m on the image's edge
            near = _core.ranging_near_depth(camera._core(), min_range_m)
        # The search reaches disparity 0 (depth ∞), not f·B/max_range: a landmark beyond the range
        # keeps its true, small disparity and is rejected as too far, instead of being matched at
        # the search's floor to a false depth inside the range.
        return StereoMatcher.for_depth_range(camera, near, math.inf, **{**PIPELINE_SGBM, **dict(sgbm or {})})
    raise ValueError(f"camera = {camera!r}: must be a StereoRig, RectifiedCamera, StereoCalibration "
                     f"or StereoMatcher")


def _trilateration_options(trilateration: Mapping | None) -> dict:
    """``trilateration`` as a dict, its names checked against :func:`trilaterate`'s keyword options."""
    import inspect

    options = dict(trilateration or {})
    known = [n for n, p in inspect.signature(trilaterate).parameters.items() if p.kind == p.KEYWORD_ONLY]
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise ValueError(f"trilateration: unknown option {unknown[0]!r} (known: {', '.join(known)})")
    return options


class LandmarkRanging:
    """Ranging and trilateration for one stereo camera and landmark map (the
    parameters are :class:`~safenav.vision.lanbloc.LanBLoc`'s of the same names)."""

    def __init__(self, landmarks, camera, *, camera_height_m: float | None = None, pitch_rad: float | None = None,
                 sigma_d: float = 0.5, min_landmarks: int = 3, max_range_m: float = math.inf,
                 box_shrink: float = 0.1, bearing_sigma_px: float = 1.0, unknown_landmark: str = "error",
                 resolve_ambiguity: bool = True, sgbm: Mapping | None = None, trilateration: Mapping | None = None,
                 corner_sigma_d: float | None = None, max_row_error_px: float | None = None,
                 min_range_m: float = 2.5):
        self.landmarks = _landmark_table(landmarks)
        rig = camera if isinstance(camera, StereoRig) else None
        if rig is not None:
            camera = rig.rectified_camera()
            camera_height_m = rig.camera_height_m if camera_height_m is None else camera_height_m
            pitch_rad = rig.pitch_rad if pitch_rad is None else pitch_rad
            max_range_m = rig.max_range_m if max_range_m == math.inf else max_range_m
        if camera_height_m is None:
            raise ValueError("camera_height_m is required unless camera is a StereoRig")
        self.camera_height_m = check_finite("camera_height_m", camera_height_m, nonneg=True)
        self.pitch_rad = check_finite("pitch_rad", 0.0 if pitch_rad is None else pitch_rad)
        if not (isinstance(max_range_m, (int, float)) and max_range_m > 0):
            raise ValueError(f"max_range_m = {max_range_m!r}: must be > 0")
        self.min_range_m = check_finite("min_range_m", min_range_m, positive=True)
        if not self.min_range_m < max_range_m:
            raise ValueError(f"min_range_m = {min_range_m!r}: must be < max_range_m = {max_range_m!r}")
        self.matcher = _matcher(camera, self.min_range_m, sgbm)
        self.camera = self.matcher.camera
        self.sigma_d = check_finite("sigma_d", sigma_d, positive=True)
        if isinstance(min_landmarks, bool) or not isinstance(min_landmarks, (int, np.integer)) or min_landmarks < 3:
            raise ValueError(f"min_landmarks = {min_landmarks!r}: must be an integer >= 3 (2D trilateration)")
        self.min_landmarks = int(min_landmarks)
        self.max_range_m = float(max_range_m)
        self.box_shrink = check_finite("box_shrink", box_shrink, nonneg=True)
        if self.box_shrink >= 0.5:
            raise ValueError(f"box_shrink = {box_shrink!r}: must be < 0.5")
        self.bearing_sigma_px = check_finite("bearing_sigma_px", bearing_sigma_px, positive=True)
        if unknown_landmark not in ("error", "skip"):
            raise ValueError(f"unknown_landmark = {unknown_landmark!r}: must be 'error' or 'skip'")
        self.unknown_landmark = unknown_landmark
        self.resolve_ambiguity = bool(resolve_ambiguity)
        # the corner-noise model and the row check: the core's (corner_disparity), its defaults declared
        # once in LanBLocSettings
        self.corner_settings = _core.LanBLocSettings()
        cs = self.corner_settings
        if corner_sigma_d is not None:
            cs.corner_sigma_d = check_finite("corner_sigma_d", corner_sigma_d, positive=True)
        if max_row_error_px is not None:
            cs.max_row_error_px = check_finite("max_row_error_px", max_row_error_px, positive=True)
        self.corner_sigma_d, self.max_row_error_px = cs.corner_sigma_d, cs.max_row_error_px
        self.trilateration = _trilateration_options(trilateration)
        c = self.camera
        self._core_camera = _core.RectifiedCamera()
        (self._core_camera.f, self._core_camera.cx, self._core_camera.cy, self._core_camera.baseline,
         self._core_camera.doffs, self._core_camera.width, self._core_camera.height) = (
            c.f, c.cx, c.cy, c.baseline, c.doffs, c.width, c.height)
        self._R0t = camera_rotation(0.0, self.pitch_rad).T   # camera → world directions at heading 0
        # the landmark faults' map: row k is landmark self._ids[k]
        self._ids = sorted(self.landmarks)
        self._map_xy = np.array([self.landmarks[i][0][:2] for i in self._ids], dtype=float).reshape(-1, 2)
        self._anchors = {i: tuple(self.landmarks[i][0]) for i in self._ids}
        self._crop_matchers: dict[tuple[int, int, int, int], StereoMatcher] = {}

    def crop_matcher(self, x0: int, y0: int, x1: int, y1: int) -> StereoMatcher:
        """The pipeline's SGBM matcher for the crop ``[x0, x1) × [y0, y1)`` of the rectified images (the
        camera's principal point shifted into it), cached: a row band or a strip around a box."""
        key = (x0, y0, x1, y1)
        m = self._crop_matchers.get(key)
        if m is None:
            c = self.camera
            crop = RectifiedCamera(c.f, c.cx - x0, c.cy - y0, c.baseline, c.doffs, x1 - x0, y1 - y0)
            m = StereoMatcher(crop, **self.matcher.sgbm_params)
            if len(self._crop_matchers) > 64:
                self._crop_matchers.clear()
            self._crop_matchers[key] = m
        return m

    def observe(self, det: Detection, disparity: np.ndarray) -> LandmarkSighting:
        """Range and bearing of one detection from the SGBM disparity: the median over its box shrunk by
        ``box_shrink`` per side (step 4 of :mod:`safenav.vision.lanbloc`)."""
        x0, y0, x1, y1 = det.box
        sx, sy = self.box_shrink * (x1 - x0), self.box_shrink * (y1 - y0)
        box = (x0 + sx, y0 + sy, x1 - sx, y1 - sy)
        br = self.matcher.box_range(disparity, box, sigma_d=self.sigma_d, max_range=self.max_range_m)
        return self.sighting(det, det.center, br.ok, br.range, br.sigma, br.point, float(br.disparity),
                             int(br.n_valid), br.reason)

    def observe_corners(self, det: Detection, right: Detection | None, refine_level: int = 0,
                        reason: str = "") -> LandmarkSighting:
        """Range and bearing of a fiducial from its corners in both images (ours).

        The centre and its disparity come from the core's
        ``_core.corner_disparity`` (the C++ front end's rule, one place): the
        four refined corners ``(u_i, v_i)`` of the left image and ``u'_i`` of
        the right give disparities ``d_i = u_i − u'_i``; the marker is a
        plane, so its disparity is affine in the left image's ``(u, v)``: the
        least-squares plane ``d = a·u + b·v + c`` through the four is
        evaluated at the marker's centre, the diagonals' intersection
        ``(u_c, v_c)`` (the image of the centre under the homography).  When
        exactly one corner is more than ``max_row_error_px`` off its epipolar
        line (row), e.g. half hidden behind another board's edge differently
        in the two images, the centre is the midpoint of the other diagonal's
        two corners, triangulated (exact for exact corners).
        ``Z = f·B/(d_c + doffs)`` with ``σ_Z = Z²·σ_d/(f·B)``; σ_d is the
        corner-noise model ``_core.corner_disparity_sigma`` (fitted to the
        refined corners' measured errors: bench/bench_corner_noise.py) times
        ``2^refine_level`` (corners refined at pyramid level L are 2^L times
        coarser, :meth:`safenav.vision.regions.RegionPipeline.localize`); the
        centre's slant distance and horizontal range follow as for SGBM.  No
        range when the marker is not found in the right image (``right`` is
        None; ``reason`` says why), when two or more corners are off their
        rows, or when ``d_c + doffs`` is below 1 px or the depth beyond
        ``max_range_m``.
        """
        cl = np.asarray(det.corners, dtype=float).reshape(4, 2)
        cam = self.camera
        centre = np.asarray(_core.marker_centre(cl))
        nan3 = np.full(3, np.nan)
        if right is None or right.corners is None:
            return self.sighting(det, centre, False, math.nan, math.nan, nan3, math.nan, 0,
                                 reason or "not found in the right image")
        cr = np.asarray(right.corners, dtype=float).reshape(4, 2)
        cd = _core.corner_disparity(cl, cr, self._core_camera, self.corner_settings, float(1 << int(refine_level)))
        if cd.corners_used == 3:
            centre = np.asarray(cd.centre)
        if not cd.ok:
            return self.sighting(det, centre, False, math.nan, math.nan, nan3, cd.disparity, cd.corners_used or 4,
                                 cd.reason)
        d = float(cd.disparity)
        Z = cam.f * cam.baseline / (d + cam.doffs)
        if Z > self.max_range_m:
            return self.sighting(det, centre, False, math.nan, math.nan, nan3, d, cd.corners_used,
                                 f"beyond resolvable range ({Z:.1f} m > max_range_m = {self.max_range_m:g} m)")
        point = np.array([(centre[0] - cam.cx) * Z / cam.f, (centre[1] - cam.cy) * Z / cam.f, Z])
        sigma_z = Z * Z * cd.sigma / (cam.f * cam.baseline)
        return self.sighting(det, centre, True, Z, sigma_z, point, d, cd.corners_used, "")

    def sighting(self, det: Detection, centre, ok: bool, depth: float, sigma_z: float, point, disparity: float,
                 n_valid: int, reason: str) -> LandmarkSighting:
        """The sighting of ``det`` from its image centre and, when ``ok``, its depth ``Z`` with σ_Z and
        its 3D ``point`` in the rectified left camera frame: slant range, horizontal range and bearing."""
        anchor, _ = self.landmarks[det.landmark_id]
        cam = self.camera
        u, v = centre
        ray = self._R0t @ np.array([(u - cam.cx) / cam.f, (v - cam.cy) / cam.f, 1.0])
        bearing = math.atan2(ray[1], ray[0])
        b_sigma = self.bearing_sigma_px / cam.f
        common = dict(landmark_id=det.landmark_id, class_name=det.class_name, box=det.box, score=det.score,
                      anchor=anchor, bearing=bearing, bearing_sigma=b_sigma, disparity=float(disparity),
                      n_valid=int(n_valid))
        if not ok:
            return LandmarkSighting(ok=False, range=math.nan, sigma=math.nan, slant_range=math.nan,
                                    depth=math.nan, reason=reason, **common)
        # ‖P‖ summed left to right, as the core's front end sums it (Eigen), so that the two agree bit for bit
        s = math.sqrt(float(point[0]) * float(point[0]) + float(point[1]) * float(point[1])
                      + float(point[2]) * float(point[2]))
        sigma_s = sigma_z * s / depth
        rho, sigma_rho = horizontal_range(s, anchor[2], self.camera_height_m, sigma=sigma_s)
        if not rho > 0:
            return LandmarkSighting(ok=False, range=math.nan, sigma=math.nan, slant_range=s, depth=depth,
                                    reason=f"slant range {s:.3f} m is shorter than the height difference "
                                           f"{anchor[2] - self.camera_height_m:.3f} m", **common)
        return LandmarkSighting(ok=True, range=float(rho), sigma=float(sigma_rho), slant_range=s,
                                depth=float(depth), **common)

    def apply_faults(self, observations: Sequence[LandmarkSighting], faults, position, seed: int
                     ) -> tuple[tuple[LandmarkSighting, ...], int]:
        """The sightings after the landmark faults, and how many ranges were dropped.

        The core camera loop's faults (``_core.apply_sighting_faults``): each ranged
        sighting goes through :meth:`safenav.navigation.LandmarkFaults.apply` (the
        simulator's model) alone, with the vehicle at ``position`` (the truth: a misassociation picks another
        landmark within ``max_range_m`` of it, else any other) and its own draw
        stream ``derive_seed(seed, landmark id)``.  A dropped range is removed;
        a misassociated one carries the wrong landmark's id, class and map
        position (its range and bearing stay those of the landmark seen;
        ``true_landmark_id`` says which); an outlier's range is off by
        ``±outlier_magnitude``.  Sightings without a range pass unchanged.
        """
        faults = check_faults(faults)
        if faults is None:
            return tuple(observations), 0
        p = np.asarray(position, dtype=float).ravel() if position is not None else np.zeros(0)
        if p.shape != (2,) or not np.isfinite(p).all():
            raise ValueError(f"position = {position!r}: must be the vehicle's finite (x, y) when faults are given")
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2 ** 64:
            raise ValueError(f"seed = {seed!r}: must be an integer in [0, 2**64)")
        out, dropped = [], 0
        for o in observations:
            if not o.ok:
                out.append(o)
                continue
            # the core camera loop's faults (apply_sighting_faults), one sighting per call so that the
            # result maps back to the detection; its draws depend on the seed and its id alone
            kept, _ = _core.apply_sighting_faults(
                faults, [_core.LandmarkSighting(o.landmark_id, float(o.range), np.asarray(o.anchor, dtype=float))],
                self._map_xy, self._ids, self._anchors, p, self.max_range_m, int(seed))
            if not kept:
                dropped += 1
                continue
            k = kept[0]
            changes = dict(range=float(k.range), faults=int(k.faults))
            if k.true_landmark_id >= 0:
                anchor, class_name = self.landmarks[k.landmark_id]
                changes.update(landmark_id=k.landmark_id, class_name=class_name, anchor=anchor,
                               true_landmark_id=o.landmark_id)
            out.append(dataclasses.replace(o, **changes))
        return tuple(out), dropped

    @staticmethod
    def drop_repeated(obs: Sequence[LandmarkSighting]) -> tuple[LandmarkSighting, ...]:
        """The sightings with every usable range whose landmark another usable
        range names too marked unusable (``_core.repeated_landmarks``, the
        core front end's rule): one of the two is a wrong match, and nothing
        in the frame says which."""
        ok = [i for i, o in enumerate(obs) if o.ok]
        twice = _core.repeated_landmarks([obs[i].landmark_id for i in ok])
        out = list(obs)
        for i, rep in zip(ok, twice):
            if rep:
                out[i] = dataclasses.replace(
                    obs[i], ok=False, range=math.nan, sigma=math.nan,
                    reason=f"landmark {obs[i].landmark_id} {REPEATED}")
        return tuple(out)

    def bearings_agree(self, loc: LocalizationResult, obs: Sequence[LandmarkSighting]) -> bool:
        """Whether the bearings fit the fix ``loc`` with one common heading (χ² test, 99.9 %).

        The absolute bearing from the fix to landmark i is β_i; the measured
        bearing relative to the heading is b_i; with the heading estimated as
        the circular mean of β_i − b_i the residuals must be within their σ:
        the bearing σ plus the fix's uncertainty across the line of sight.
        The mirror image of a fix reverses the landmarks' order, which no
        heading explains.
        """
        p, P = loc.position, loc.covariance
        res, var = [], []
        for o in obs:
            d = o.anchor[:2] - p
            rho = float(np.hypot(*d))
            if rho < 1e-6:
                return False
            n = np.array([-d[1], d[0]]) / rho
            res.append(math.atan2(d[1], d[0]) - o.bearing)
            var.append(o.bearing_sigma ** 2 + float(n @ P @ n) / rho ** 2)
        res = np.asarray(res)
        theta = math.atan2(np.sin(res).mean(), np.cos(res).mean())
        r = wrap_angle(res - theta)
        chi2 = float(np.sum(r * r / np.asarray(var)))
        return chi2 <= _chi2_999(len(obs) - 1)

    def known(self, detections, unknown: str | None = None) -> list[Detection]:
        """The detections of mapped landmarks, the best-scoring one per landmark."""
        unknown = self.unknown_landmark if unknown is None else unknown
        dets, seen = [], set()
        for d in detections:
            if d.landmark_id not in self.landmarks:
                if unknown == "error":
                    raise ValueError(f"detected landmark id {d.landmark_id} ({d.class_name!r}) is not in the "
                                     f"landmark map (known ids: {sorted(self.landmarks)})")
                continue
            if d.landmark_id in seen:   # keep the best-scoring box of a landmark
                continue
            seen.add(d.landmark_id)
            dets.append(d)
        return dets

    def early_out(self, in_view: int) -> LanBLocResult:
        """The result of a frame with fewer markers in view than a fix needs, not processed."""
        nan2, nan22 = np.full(2, np.nan), np.full((2, 2), np.nan)
        t = dict.fromkeys(("rectify", "detect", "disparity", "range", "localize"), 0.0)
        if in_view == 0:
            return LanBLocResult("no_landmarks", "no landmark in view", nan2, nan22, math.nan, (), (), None, t)
        return LanBLocResult("too_few_ranges", f"{in_view} landmark(s) in view, {self.min_landmarks} needed "
                             f"(frame not processed)", nan2, nan22, math.nan, (), (), None, t)

    @staticmethod
    def no_landmarks(t: dict) -> LanBLocResult:
        """The result of a frame in which no mapped landmark was recognised (timings ``t`` so far)."""
        t["disparity"] = t["range"] = t["localize"] = 0.0
        nan2, nan22 = np.full(2, np.nan), np.full((2, 2), np.nan)
        return LanBLocResult("no_landmarks", "no landmark recognised in the left image", nan2, nan22, math.nan,
                             (), (), None, t)

    def solve(self, dets, obs, t: dict, t3: float, faults, position, seed) -> LanBLocResult:
        """Steps after ranging: landmark faults, trilateration, the mirror ambiguity, the result."""
        nan2, nan22 = np.full(2, np.nan), np.full((2, 2), np.nan)
        obs, dropped = self.apply_faults(obs, faults, position, seed)
        obs = self.drop_repeated(obs)
        t4 = time.perf_counter()
        t["range"] = t4 - t3
        ok = [o for o in obs if o.ok]
        if len(ok) < self.min_landmarks:
            t["localize"] = 0.0
            why = [f"landmark {o.landmark_id}: {o.reason}" for o in obs if not o.ok]
            why += [f"{dropped} dropped by landmark faults"] if dropped else []
            return LanBLocResult("too_few_ranges", f"{len(ok)} usable range(s), {self.min_landmarks} needed"
                                 + (f" ({'; '.join(why)})" if why else ""), nan2, nan22, math.nan, obs,
                                 tuple(dets), None, t, dropped)
        anchors = np.array([o.anchor[:2] for o in ok])
        rng, sig = [o.range for o in ok], [o.sigma for o in ok]
        loc = trilaterate(anchors, rng, sig, **self.trilateration)
        if loc.status == "degenerate" and self.resolve_ambiguity:
            # a forward camera sees every landmark on one side, so the mirror image of the fix across
            # them often fits the ranges too; the bearings' left-to-right order tells the two apart
            best = trilaterate(anchors, rng, sig, **{**self.trilateration, "ambiguity_margin": 0.0})
            if best.ok and self.bearings_agree(best, ok):
                loc = dataclasses.replace(best, reason="mirror ambiguity resolved by the bearings")
        t["localize"] = time.perf_counter() - t4
        if not loc.ok:
            status = {"too_few": "too_few_ranges"}.get(loc.status, loc.status)
            status = status if status in STATUSES else "degenerate"
            return LanBLocResult(status, loc.reason, nan2, nan22, float(loc.gdop), obs, tuple(dets), loc, t,
                                 dropped)
        return LanBLocResult("ok", loc.reason, np.array(loc.position), np.array(loc.covariance), float(loc.gdop),
                             obs, tuple(dets), loc, t, dropped)

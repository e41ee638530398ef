"""The LanBLoc pipeline: stereo pair → landmarks → ranges → position [SafeNav §IV-A].

LanBLoc recognises landmarks in the left image, measures the distance to each
by stereo matching, and trilaterates with the recognised landmarks as anchors
("with further position optimization").  :class:`LanBLoc` runs, per frame:

1. rectification (skipped when the camera is a
   :class:`~safenav.vision.stereo.RectifiedCamera`, e.g. the renderer's);
2. detection on the rectified left image (:mod:`safenav.vision.detect`; default the
   ArUco :class:`~safenav.vision.detect.FiducialDetector`);
3. SGBM disparity (:class:`~safenav.vision.stereo.StereoMatcher`), by default only on
   the band of rows that holds the boxes (plus a margin);
4. per detection, the box-median depth ``Z`` with ``σ_Z ≈ Z²·σ_d/(f·B)``
   (:meth:`~safenav.vision.stereo.StereoMatcher.box_range`, on the box shrunk by
   ``box_shrink`` per side so that background pixels at the edges stay out);
   the slant distance ``s = ‖P‖`` of the box centre ``P`` at that depth; the
   horizontal range ``ρ = sqrt(s² − (z_ℓ − h)²)`` from the landmark's known
   height ``z_ℓ`` and the camera height ``h``
   (:func:`~safenav.vision.localization.horizontal_range`, ``σ_ρ = σ_s·s/ρ``); and
   the bearing of the box centre relative to the heading (counter-clockwise,
   as in :meth:`safenav.MeasurementModel.bearing`);
5. trilateration of the ranges to the landmarks' map positions
   (:func:`~safenav.vision.localization.trilaterate`: linear start, weighted
   Levenberg–Marquardt, covariance ``(JᵀWJ)⁻¹``, GDOP, outlier consensus).
   A forward-looking camera sees all its landmarks on one side, so the
   mirror image of the fix across them may fit the ranges nearly as well;
   trilateration then says "degenerate".  The bearings settle it: at the
   mirror image the landmarks' left-to-right order is reversed, which no
   heading explains (a χ² test on the bearing residuals, 99.9 %).

The result (:class:`LanBLocResult`) carries an explicit ``status`` —
``ok``, ``no_landmarks``, ``too_few_ranges``, ``degenerate`` or
``did_not_converge`` — with a ``reason``, the position and covariance when ok,
and every landmark's range and bearing (:class:`LandmarkObservation`) so that a
filter can use the ranges directly (``result.range_measurements()`` →
anchors, ranges, σ for :meth:`safenav.MeasurementModel.range`).

The fix is the position of the **left camera's centre** projected on the
ground: the rig's reference point (see :mod:`safenav.vision.render`).

:class:`CameraLoopSource` closes the camera loop for the navigation
experiments: it renders the pair at the true vehicle pose
(:class:`~safenav.vision.render.StereoRenderer`), runs the pipeline and returns the
fix and its covariance, or ``None`` (a dropout) when localization fails.

Landmark-level faults (ours; :class:`safenav.navigation.LandmarkFaults`: dropout,
misassociation, outliers) act on the per-landmark ranges after stereo ranging
and before trilateration (``LanBLoc.localize(..., faults=...)``,
``CameraLoopSource(..., faults=...)``), through the core's
:meth:`~safenav.navigation.LandmarkFaults.apply`, the model of the simulator's
``FixModel.RANGES``: a dropped range is gone, a misassociated one keeps its
range but carries another landmark's id and so that landmark's map position,
an outlier's range is off by ``±outlier_magnitude``.  The trilateration's
outlier test then sees them as it would in the simulator.

Bad input raises ``ValueError`` naming the value: images of different sizes
or not matching the calibration, empty images, a NaN calibration or camera
height, a detected landmark id that the landmark table does not know.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import cv2
import numpy as np

from .. import _core
from ..motion import wrap_angle
from ..world import Landmark, World
from .detect import Detection, Detector, FiducialDetector, check_image
from .localization import LocalizationResult, horizontal_range, trilaterate
from .render import StereoFrame, StereoRenderer, StereoRig, camera_rotation
from .stereo import RectifiedCamera, StereoCalibration, StereoMatcher

__all__ = ["LandmarkObservation", "LanBLocResult", "LanBLoc", "CameraLoopSource", "STATUSES", "MISASSOCIATED",
           "OUTLIER"]

#: Result statuses, in the order the pipeline can stop.
STATUSES = ("ok", "no_landmarks", "too_few_ranges", "degenerate", "did_not_converge")

#: Landmark fault flags of :attr:`LandmarkObservation.faults` (the core's ``LandmarkFaults`` flags).
MISASSOCIATED = 2
OUTLIER = 4

#: The random stream of the landmark faults under :class:`CameraLoopSource`'s seed
#: (``derive_seed(derive_seed(seed, FAULT_STREAM), step)`` per frame).
FAULT_STREAM = 1
#: The pixel-noise stream of :class:`CameraLoopSource`'s frames in region mode
#: (``derive_seed(derive_seed(seed, NOISE_STREAM), step)`` per frame).
NOISE_STREAM = 2

#: Default SGBM settings for the pipeline: 3-way SGBM, uniqueness 10.  The disparity search is not
#: fixed: it follows from the camera and the depths of interest, from ``min_range_m`` at the image's
#: edge to infinity (:func:`safenav.vision.stereo.disparity_range`).
PIPELINE_SGBM = dict(block_size=5, mode="sgbm_3way", uniqueness_ratio=10, speckle_window_size=100, speckle_range=2)


@dataclass(frozen=True)
class LandmarkObservation:
    """One recognised landmark and what stereo made of it."""

    landmark_id: int
    class_name: str
    box: tuple[float, float, float, float]   #: detection box in the rectified left image [px]
    score: float
    anchor: np.ndarray        #: the landmark's map position (x, y, z) [m]
    ok: bool                  #: a usable range was measured
    range: float              #: horizontal range ρ from the camera's vertical axis to the landmark's [m]
    sigma: float              #: σ_ρ [m]
    slant_range: float        #: s, camera centre to the box centre at the median depth [m]
    depth: float              #: median Z in the box [m]
    disparity: float          #: median disparity [px]
    n_valid: int              #: valid disparity pixels in the (shrunk) box
    bearing: float            #: bearing of the box centre relative to the heading, CCW [rad]
    bearing_sigma: float      #: σ of the bearing [rad]
    reason: str = ""          #: why there is no range ("" when ok)
    faults: int = 0           #: landmark faults applied: :data:`MISASSOCIATED` | :data:`OUTLIER` bits
    true_landmark_id: int | None = None   #: the recognised landmark when misassociated (``landmark_id`` is wrong)


@dataclass(frozen=True)
class LanBLocResult:
    """The outcome of one LanBLoc frame (see the module docstring)."""

    status: str
    reason: str
    position: np.ndarray                      #: (2,) [m]; NaN unless ok
    covariance: np.ndarray                    #: (2, 2) [m²]; NaN unless ok
    gdop: float
    observations: tuple[LandmarkObservation, ...]
    detections: tuple[Detection, ...]
    localization: LocalizationResult | None = None
    timings: dict = field(default_factory=dict, compare=False)   #: seconds per stage
    dropped: int = 0                          #: ranges removed by landmark faults (not in ``observations``)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def n_ranges(self) -> int:
        return sum(o.ok for o in self.observations)

    @property
    def rejected(self) -> tuple[LandmarkObservation, ...]:
        """The ranges that the trilateration's outlier test rejected (empty unless ok)."""
        if not self.ok:
            return ()
        ranged = [o for o in self.observations if o.ok]
        return tuple(o for o, inlier in zip(ranged, self.localization.inliers) if not inlier)

    @property
    def faults_in_fix(self) -> tuple[LandmarkObservation, ...]:
        """The faulty ranges (``faults != 0``) that the fix used as inliers (empty unless ok)."""
        if not self.ok:
            return ()
        ranged = [o for o in self.observations if o.ok]
        return tuple(o for o, inlier in zip(ranged, self.localization.inliers) if inlier and o.faults)

    def range_measurements(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(landmark ids (n,), anchors (n, 2), horizontal ranges (n,), σ (n,))`` of the usable ranges."""
        obs = [o for o in self.observations if o.ok]
        return (np.array([o.landmark_id for o in obs], dtype=int),
                np.array([o.anchor[:2] for o in obs], dtype=float).reshape(-1, 2),
                np.array([o.range for o in obs], dtype=float), np.array([o.sigma for o in obs], dtype=float))

    def range_model(self):
        """``(model, z)`` for a filter update with the ranges directly: a
        :class:`safenav.MeasurementModel` of kind RANGE over the ranged
        landmarks with ``R = diag(σ²)``, and ``z`` the horizontal ranges;
        ``None`` when no range was measured.  ``filter.update(model, z)``."""
        from ..measurement import MeasurementKind, MeasurementModel
        _, anchors, z, sigma = self.range_measurements()
        if len(z) == 0:
            return None
        return MeasurementModel(MeasurementKind.RANGE, np.diag(sigma ** 2), anchors), z

    def bearing_measurements(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(landmark ids, anchors (n, 2), bearings relative to the heading (n,), σ (n,))`` of every detection."""
        obs = self.observations
        return (np.array([o.landmark_id for o in obs], dtype=int),
                np.array([o.anchor[:2] for o in obs], dtype=float).reshape(-1, 2),
                np.array([o.bearing for o in obs], dtype=float), np.array([o.bearing_sigma for o in obs], dtype=float))


def _chi2_999(dof: int) -> float:
    from scipy.stats import chi2
    return float(chi2.ppf(0.999, max(dof, 1)))


def _landmark_table(landmarks) -> dict[int, tuple[np.ndarray, str]]:
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


def _finite(name, v, *, positive=False, nonneg=False):
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v):
        raise ValueError(f"{name} = {v!r}: must be a finite number")
    if (positive and not v > 0) or (nonneg and v < 0):
        raise ValueError(f"{name} = {v!r}: must be {'> 0' if positive else '>= 0'}")
    return float(v)


def _check_faults(faults):
    """``faults`` as given (a validated :class:`safenav.navigation.LandmarkFaults`) or ``None``."""
    if faults is None:
        return None
    if not isinstance(faults, _core.LandmarkFaults):
        raise ValueError(f"faults = {faults!r}: must be a safenav.navigation.LandmarkFaults or None")
    faults.validate()   # ValueError naming the bad field (faults.dropout_probability = ...)
    return faults


class LanBLoc:
    """The LanBLoc vision pipeline for one stereo rig and landmark map.

    Parameters
    ----------
    landmarks:
        A :class:`~safenav.world.World`, a sequence of
        :class:`~safenav.world.Landmark`, or a mapping ``id → (x, y[, z])``.
        ``z`` is the height of the landmark's reference point (the marker
        centre) above the ground.
    camera:
        A :class:`~safenav.vision.render.StereoRig` (rendered, rectified pairs), a
        :class:`~safenav.vision.stereo.RectifiedCamera`, a
        :class:`~safenav.vision.stereo.StereoCalibration` (pairs are rectified first)
        or a ready :class:`~safenav.vision.stereo.StereoMatcher`.
    detector:
        A :class:`~safenav.vision.detect.Detector`; default a
        :class:`~safenav.vision.detect.FiducialDetector` on the landmark ids.
    camera_height_m, pitch_rad:
        The camera centres' height above the ground and the pitch (positive
        up); taken from the rig when ``camera`` is a StereoRig.
    sigma_d:
        Disparity noise σ_d [px] for σ_Z = Z²·σ_d/(f·B).  The default 0.5 px
        allows for SGBM's pixel locking on the markers' flat cells.
    min_landmarks:
        Ranges needed to trilaterate (the paper: at least 3).
    max_range_m:
        Ranges beyond this are "beyond resolvable range".
    box_shrink:
        Fraction of the box width/height cut from each side before the median.
    row_band:
        Match only the rows spanned by the boxes (plus ``band_margin_px``);
        ``False`` matches the whole image.
    bearing_sigma_px:
        σ of the box centre [px], for the bearings' σ = σ_px / f.
    unknown_landmark:
        ``"error"`` (default): a detection whose landmark id is not in
        ``landmarks`` raises ``ValueError``; ``"skip"`` ignores it.
    resolve_ambiguity:
        When trilateration reports a degenerate fix, retry without its
        mirror-ambiguity check and accept the best fit if the bearings agree
        with it (see :meth:`_bearings_agree`); collinear anchors and large
        GDOP stay degenerate.
    sgbm:
        SGBM parameters (:data:`safenav.vision.stereo.SGBM_DEFAULTS` names), over
        :data:`PIPELINE_SGBM`; the disparity search (``min_disparity``,
        ``num_disparities``) defaults to the depths from ``min_range_m`` to
        infinity (:meth:`~safenav.vision.stereo.StereoMatcher.for_depth_range`);
        ranges beyond ``max_range_m`` are then rejected.
    min_range_m:
        The nearest landmark of interest [m] (at the image's edge, for a
        rectified camera): the top of the disparity search.
    trilateration:
        Keyword arguments for :func:`~safenav.vision.localization.trilaterate`.
    ranging:
        ``"sgbm"`` (the paper's dense stereo: the box median of SGBM
        disparities, :meth:`observe`) or ``"corners"`` (ours, fiducials only:
        the marker's refined corners found in both images, triangulated,
        :meth:`observe_corners`).
    corner_sigma_d:
        σ [px] of the marker centre's disparity from the corners, for
        ``σ_Z = Z²·σ/(f·B)`` (``"corners"``).
    max_row_error_px:
        Largest row difference between a corner in the left and the right
        image (rectified: ideally 0) before the pair is rejected.
    detect_side_px, region_margin_px:
        On a :class:`~safenav.vision.render.StereoFrame`: the marker side
        [px] at the pyramid level used for detection, and the margin around
        the markers' footprints (:meth:`localize_frame`).
    """

    def __init__(self, landmarks, camera, detector: Detector | None = None, *,
                 camera_height_m: float | None = None, pitch_rad: float | None = None, sigma_d: float = 0.5,
                 min_landmarks: int = 3, max_range_m: float = math.inf, box_shrink: float = 0.1,
                 row_band: bool = True, band_margin_px: int = 24, bearing_sigma_px: float = 1.0,
                 unknown_landmark: str = "error", resolve_ambiguity: bool = True, sgbm: Mapping | None = None,
                 trilateration: Mapping | None = None, ranging: str = "sgbm", corner_sigma_d: float = 0.035,
                 max_row_error_px: float = 1.0, detect_side_px: float = 48.0, region_margin_px: int = 8,
                 min_range_m: float = 2.5, min_correlation: float = 0.8):
        self.landmarks = _landmark_table(landmarks)
        rig = camera if isinstance(camera, StereoRig) else None
        if rig is not None:
            camera = rig.rectified_camera()
            camera_height_m = rig.camera_height_m if camera_height_m is None else camera_height_m
            pitch_rad = rig.pitch_rad if pitch_rad is None else pitch_rad
            max_range_m = rig.max_range_m if max_range_m == math.inf else max_range_m
        if camera_height_m is None:
            raise ValueError("camera_height_m is required unless camera is a StereoRig")
        self.camera_height_m = _finite("camera_height_m", camera_height_m, nonneg=True)
        self.pitch_rad = _finite("pitch_rad", 0.0 if pitch_rad is None else pitch_rad)
        if not (isinstance(max_range_m, (int, float)) and max_range_m > 0):
            raise ValueError(f"max_range_m = {max_range_m!r}: must be > 0")
        self.min_range_m = _finite("min_range_m", min_range_m, positive=True)
        if not self.min_range_m < max_range_m:
            raise ValueError(f"min_range_m = {min_range_m!r}: must be < max_range_m = {max_range_m!r}")
        if isinstance(camera, StereoMatcher):
            self.matcher = camera
        elif isinstance(camera, (RectifiedCamera, StereoCalibration)):
            near = self.min_range_m
            if isinstance(camera, RectifiedCamera):   # the depth of a landmark at min_range_m on the image's edge
                near *= math.cos(math.atan2(max(camera.cx, camera.width - 1 - camera.cx), camera.f))
            # The search reaches disparity 0 (depth ∞), not f·B/max_range: a landmark beyond the range
            # keeps its true, small disparity and is rejected as too far, instead of being matched at
            # the search's floor to a false depth inside the range.
            self.matcher = StereoMatcher.for_depth_range(camera, near, math.inf,
                                                         **{**PIPELINE_SGBM, **dict(sgbm or {})})
        else:
            raise ValueError(f"camera = {camera!r}: must be a StereoRig, RectifiedCamera, StereoCalibration "
                             f"or StereoMatcher")
        self.camera = self.matcher.camera
        self.detector = FiducialDetector(landmarks if isinstance(landmarks, World) else
                                         {k: k for k in self.landmarks}) if detector is None else detector
        if not isinstance(self.detector, Detector):
            raise ValueError(f"detector = {detector!r}: must be a safenav.vision.detect.Detector")
        self.sigma_d = _finite("sigma_d", sigma_d, positive=True)
        if isinstance(min_landmarks, bool) or not isinstance(min_landmarks, (int, np.integer)) or min_landmarks < 3:
            raise ValueError(f"min_landmarks = {min_landmarks!r}: must be an integer >= 3 (2D trilateration)")
        self.min_landmarks = int(min_landmarks)
        self.max_range_m = float(max_range_m)
        self.box_shrink = _finite("box_shrink", box_shrink, nonneg=True)
        if self.box_shrink >= 0.5:
            raise ValueError(f"box_shrink = {box_shrink!r}: must be < 0.5")
        self.row_band = bool(row_band)
        if isinstance(band_margin_px, bool) or not isinstance(band_margin_px, (int, np.integer)) or band_margin_px < 0:
            raise ValueError(f"band_margin_px = {band_margin_px!r}: must be an integer >= 0")
        self.band_margin_px = int(band_margin_px)
        self.bearing_sigma_px = _finite("bearing_sigma_px", bearing_sigma_px, positive=True)
        if unknown_landmark not in ("error", "skip"):
            raise ValueError(f"unknown_landmark = {unknown_landmark!r}: must be 'error' or 'skip'")
        self.unknown_landmark = unknown_landmark
        self.resolve_ambiguity = bool(resolve_ambiguity)
        if ranging not in ("sgbm", "corners"):
            raise ValueError(f"ranging = {ranging!r}: must be 'sgbm' or 'corners'")
        if ranging == "corners" and not hasattr(self.detector, "dictionary"):
            raise ValueError(f"ranging = 'corners' needs a fiducial detector (marker corners), not "
                             f"{type(self.detector).__name__}")
        self.ranging = ranging
        self.corner_sigma_d = _finite("corner_sigma_d", corner_sigma_d, positive=True)
        self.max_row_error_px = _finite("max_row_error_px", max_row_error_px, positive=True)
        self.detect_side_px = _finite("detect_side_px", detect_side_px, positive=True)
        if self.detect_side_px < 16:
            raise ValueError(f"detect_side_px = {detect_side_px!r}: must be >= 16 (ArUco needs ~4 px per cell)")
        if isinstance(region_margin_px, bool) or not isinstance(region_margin_px, (int, np.integer)) \
                or region_margin_px < 0:
            raise ValueError(f"region_margin_px = {region_margin_px!r}: must be an integer >= 0")
        self.region_margin_px = int(region_margin_px)
        self.min_correlation = _finite("min_correlation", min_correlation)
        if not -1.0 <= self.min_correlation <= 1.0:
            raise ValueError(f"min_correlation = {min_correlation!r}: must be in [-1, 1]")
        self.trilateration = dict(trilateration or {})
        import inspect
        known = [n for n, p in inspect.signature(trilaterate).parameters.items() if p.kind == p.KEYWORD_ONLY]
        unknown = sorted(set(self.trilateration) - set(known))
        if unknown:
            raise ValueError(f"trilateration: unknown option {unknown[0]!r} (known: {', '.join(known)})")
        self._R0t = camera_rotation(0.0, self.pitch_rad).T   # camera → world directions at heading 0
        # the landmark faults' map: row k is landmark self._ids[k]
        self._ids = sorted(self.landmarks)
        self._rows = {i: k for k, i in enumerate(self._ids)}
        self._map_xy = np.array([self.landmarks[i][0][:2] for i in self._ids], dtype=float).reshape(-1, 2)
        self._band_matchers: dict[tuple[int, int], StereoMatcher] = {}

    # ---------------------------------------------------------------- stages
    def check_pair(self, left, right) -> tuple[np.ndarray, np.ndarray]:
        """Validate a stereo pair (uint8, non-empty, same shape, the calibration's size)."""
        left = check_image(left, "left image")
        right = check_image(right, "right image")
        if left.shape != right.shape:
            raise ValueError(f"left and right images differ in size: {left.shape} vs {right.shape}")
        want = (self.camera.height, self.camera.width)
        if left.shape[:2] != want:
            raise ValueError(f"images are {left.shape[1]}x{left.shape[0]} px but the calibration is "
                             f"{want[1]}x{want[0]} px")
        return left, right

    def disparity(self, left, right, boxes=()) -> np.ndarray:
        """SGBM disparity of the rectified pair (NaN where invalid or outside the row band)."""
        h = left.shape[0]
        if not self.row_band or len(boxes) == 0:
            return self.matcher.disparity(left, right)
        b = np.asarray(boxes, dtype=float).reshape(-1, 4)
        q = 16   # band edges on a 16-row grid, so that band matchers are reused
        y0 = max((int(math.floor(b[:, 1].min())) - self.band_margin_px) // q * q, 0)
        y1 = min(-(-(int(math.ceil(b[:, 3].max())) + 1 + self.band_margin_px) // q) * q, h)
        if y1 - y0 >= 0.8 * h:
            return self.matcher.disparity(left, right)
        m = self._band_matchers.get((y0, y1))
        if m is None:
            c = self.camera
            band = RectifiedCamera(c.f, c.cx, c.cy - y0, c.baseline, c.doffs, c.width, y1 - y0)
            m = StereoMatcher(band, **self.matcher.sgbm_params)
            if len(self._band_matchers) > 64:
                self._band_matchers.clear()
            self._band_matchers[(y0, y1)] = m
        out = np.full((h, left.shape[1]), np.nan, np.float32)
        out[y0:y1] = m.disparity(np.ascontiguousarray(left[y0:y1]), np.ascontiguousarray(right[y0:y1]))
        return out

    def observe(self, det: Detection, disparity: np.ndarray) -> LandmarkObservation:
        """Range and bearing of one detection from the SGBM disparity (step 4 of the module docstring)."""
        x0, y0, x1, y1 = det.box
        sx, sy = self.box_shrink * (x1 - x0), self.box_shrink * (y1 - y0)
        box = (x0 + sx, y0 + sy, x1 - sx, y1 - sy)
        br = self.matcher.box_range(disparity, box, sigma_d=self.sigma_d, max_range=self.max_range_m)
        return self._observation(det, det.center, br.ok, br.range, br.sigma, br.point, float(br.disparity),
                                 int(br.n_valid), br.reason)

    def observe_corners(self, det: Detection, right: Detection | None, refine_level: int = 0,
                        reason: str = "") -> LandmarkObservation:
        """Range and bearing of a fiducial from its corners in both images (ours; issue 16).

        The four refined corners ``(u_i, v_i)`` of the left image and ``u'_i``
        of the right give disparities ``d_i = u_i − u'_i``; the marker is a
        plane, so its disparity is affine in the left image's ``(u, v)``: the
        least-squares plane ``d = a·u + b·v + c`` through the four is
        evaluated at the marker's centre, the diagonals' intersection
        ``(u_c, v_c)`` (the image of the centre under the homography).
        ``Z = f·B/(d_c + doffs)`` with ``σ_Z = Z²·σ_c/(f·B)``, σ_c =
        ``corner_sigma_d·2^refine_level`` (measured at level 0:
        bench/bench_vision.py; corners refined at pyramid level L are 2^L
        times coarser, :meth:`localize_frame`); the centre's
        slant distance and horizontal range follow as for SGBM.  No range when
        the marker is not found in the right image (``right`` is None; ``reason`` says why), when its
        corners are more
        than ``max_row_error_px`` off their epipolar lines (rows), or when
        ``d_c + doffs`` is below 1 px or the depth beyond ``max_range_m``.
        """
        cl = np.asarray(det.corners, dtype=float).reshape(4, 2)
        cam = self.camera
        # the centre: intersection of the diagonals 0-2 and 1-3
        p, r = cl[0], cl[2] - cl[0]
        q, s_ = cl[1], cl[3] - cl[1]
        den = r[0] * s_[1] - r[1] * s_[0]
        centre = p + r * (((q - p)[0] * s_[1] - (q - p)[1] * s_[0]) / den) if abs(den) > 1e-12 else cl.mean(axis=0)
        nan3 = np.full(3, np.nan)
        if right is None or right.corners is None:
            return self._observation(det, centre, False, math.nan, math.nan, nan3, math.nan, 0,
                                     reason or "not found in the right image")
        cr = np.asarray(right.corners, dtype=float).reshape(4, 2)
        dv = float(np.abs(cl[:, 1] - cr[:, 1]).max())
        if dv > self.max_row_error_px:
            return self._observation(det, centre, False, math.nan, math.nan, nan3, math.nan, 4,
                                     f"corners {dv:.2f} px off their epipolar lines "
                                     f"(max_row_error_px = {self.max_row_error_px:g})")
        coef, *_ = np.linalg.lstsq(np.column_stack([cl, np.ones(4)]), cl[:, 0] - cr[:, 0], rcond=None)
        d = float(coef[0] * centre[0] + coef[1] * centre[1] + coef[2])
        w = d + cam.doffs
        if not w >= 1.0:
            return self._observation(det, centre, False, math.nan, math.nan, nan3, d, 4,
                                     f"beyond resolvable range (disparity {w:.2f} px < 1 px)")
        Z = cam.f * cam.baseline / w
        if Z > self.max_range_m:
            return self._observation(det, centre, False, math.nan, math.nan, nan3, d, 4,
                                     f"beyond resolvable range ({Z:.1f} m > max_range_m = {self.max_range_m:g} m)")
        point = np.array([(centre[0] - cam.cx) * Z / cam.f, (centre[1] - cam.cy) * Z / cam.f, Z])
        sigma_z = Z * Z * self.corner_sigma_d * (1 << int(refine_level)) / (cam.f * cam.baseline)
        return self._observation(det, centre, True, Z, sigma_z, point, d, 4, "")

    def _observation(self, det: Detection, centre, ok: bool, depth: float, sigma_z: float, point, disparity: float,
                     n_valid: int, reason: str) -> LandmarkObservation:
        """The observation of ``det`` from its image centre and, when ``ok``, its depth ``Z`` with σ_Z and
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
            return LandmarkObservation(ok=False, range=math.nan, sigma=math.nan, slant_range=math.nan,
                                       depth=math.nan, reason=reason, **common)
        s = float(np.linalg.norm(point))
        sigma_s = sigma_z * s / depth
        rho, sigma_rho = horizontal_range(s, anchor[2], self.camera_height_m, sigma=sigma_s)
        if not rho > 0:
            return LandmarkObservation(ok=False, range=math.nan, sigma=math.nan, slant_range=s, depth=depth,
                                       reason=f"slant range {s:.3f} m is shorter than the height difference "
                                              f"{anchor[2] - self.camera_height_m:.3f} m", **common)
        return LandmarkObservation(ok=True, range=float(rho), sigma=float(sigma_rho), slant_range=s,
                                   depth=float(depth), **common)

    def apply_faults(self, observations: Sequence[LandmarkObservation], faults, position, seed: int
                     ) -> tuple[tuple[LandmarkObservation, ...], int]:
        """The observations after the landmark faults, and how many ranges were dropped.

        Each ranged observation goes through the core's
        :meth:`safenav.navigation.LandmarkFaults.apply` (the simulator's model) with the
        vehicle at ``position`` (the truth: a misassociation picks another
        landmark within ``max_range_m`` of it, else any other) and its own draw
        stream ``derive_seed(seed, landmark id)``.  A dropped range is removed;
        a misassociated one carries the wrong landmark's id, class and map
        position (its range and bearing stay those of the landmark seen;
        ``true_landmark_id`` says which); an outlier's range is off by
        ``±outlier_magnitude``.  Observations without a range pass unchanged.
        """
        faults = _check_faults(faults)
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
            # one observation per call: its own draws, so that the result maps back to the detection
            rows, ranges, flags, n_dropped = faults.apply(
                [self._rows[o.landmark_id]], [o.range], self._map_xy, p, self.max_range_m,
                _core.derive_seed(int(seed), o.landmark_id))
            if n_dropped:
                dropped += 1
                continue
            lm = self._ids[rows[0]]
            changes = dict(range=float(ranges[0]), faults=int(flags[0]))
            if lm != o.landmark_id:
                anchor, class_name = self.landmarks[lm]
                changes.update(landmark_id=lm, class_name=class_name, anchor=anchor, true_landmark_id=o.landmark_id)
            out.append(dataclasses.replace(o, **changes))
        return tuple(out), dropped

    def _bearings_agree(self, loc: LocalizationResult, obs: Sequence[LandmarkObservation]) -> bool:
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

    # ---------------------------------------------------------------- the whole frame
    def localize(self, left, right, *, faults=None, position=None, seed: int = 0) -> LanBLocResult:
        """Run the pipeline on one stereo pair (raw if the camera needs rectification).

        ``left`` may also be a :class:`~safenav.vision.render.StereoFrame` (with
        ``right=None``): then :meth:`localize_frame` runs.

        ``faults``: landmark-level faults (a :class:`safenav.navigation.LandmarkFaults`) on
        the ranges before trilateration, with the vehicle's true ``position``
        and the frame's ``seed`` (see :meth:`apply_faults`); ``None``: none.
        """
        if isinstance(left, StereoFrame):
            if right is not None:
                raise ValueError("right must be None when left is a StereoFrame")
            return self.localize_frame(left, faults=faults, position=position, seed=seed)
        faults = _check_faults(faults)
        t = {}
        t0 = time.perf_counter()
        left, right = self.check_pair(left, right)
        if self.matcher.needs_rectification:
            left, right = self.matcher.rectify(left, right)
        t1 = time.perf_counter()
        t["rectify"] = t1 - t0
        dets = self._known(self.detector.detect(left))
        t2 = time.perf_counter()
        t["detect"] = t2 - t1
        if not dets:
            return self._no_landmarks(t)
        if self.ranging == "corners":
            right_dets = {d.landmark_id: d for d in self._known(self.detector.detect(right), unknown="skip")}
            t3 = time.perf_counter()
            t["disparity"] = t3 - t2
            obs = tuple(self.observe_corners(d, right_dets.get(d.landmark_id)) for d in dets)
        else:
            disp = self.disparity(left, right, [d.box for d in dets])
            t3 = time.perf_counter()
            t["disparity"] = t3 - t2
            obs = tuple(self.observe(d, disp) for d in dets)
        return self._solve(dets, obs, t, t3, faults, position, seed)

    def localize_frame(self, frame: StereoFrame, *, faults=None, position=None, seed: int = 0) -> LanBLocResult:
        """The pipeline on a :class:`~safenav.vision.render.StereoFrame`, region by region (ours; issue 16).

        Detection runs on each of the left image's :meth:`~StereoFrame.regions`
        at the pyramid level where its smallest marker is about
        ``detect_side_px`` pixels wide (grown by ``region_margin_px`` pixels
        of that level), and a fiducial's corners found there are refined
        (``cv2.cornerSubPix``, one patch, in a window of about 0.7 cell) at
        full resolution, or for a marker wider than :attr:`REFINE_SIDE_PX` at
        the level where it is that wide.  With ``ranging="corners"`` the same
        is done in the right image and :meth:`observe_corners` triangulates
        the corners of the markers found in both (matched by their decoded
        id); with ``"sgbm"`` (natural landmarks, e.g. YOLO boxes) SGBM runs on
        a strip around each box only (its rows and columns plus the disparity
        range), and :meth:`observe` takes the box median as for a whole frame.
        The frame's rig must be this pipeline's camera.
        """
        faults = _check_faults(faults)
        if not isinstance(frame, StereoFrame):
            raise ValueError(f"frame = {frame!r}: must be a safenav.vision.render.StereoFrame")
        r = frame.rig
        c = self.camera
        if (r.width, r.height) != (c.width, c.height) or abs(r.focal_length_px - c.f) > 1e-9 * c.f:
            raise ValueError(f"frame's rig ({r.width}x{r.height}, f = {r.focal_length_px:g} px) is not the "
                             f"pipeline's camera ({c.width}x{c.height}, f = {c.f:g} px)")
        t = {"rectify": 0.0}
        t1 = time.perf_counter()
        found = self._detect_regions(frame, "left")
        level = {id(d): (lv, lr, patch) for d, lv, lr, patch in found}
        dets = self._known([d for d, *_ in found])
        t2 = time.perf_counter()
        t["detect"] = t2 - t1
        if not dets:
            return self._no_landmarks(t)
        if self.ranging == "corners":
            obs = []
            for d in dets:
                lv, lr, patch = level[id(d)]
                r, rr, why = self._find_in_right(frame, d, lv, patch)
                obs.append(self.observe_corners(d, r, refine_level=max(lr, rr), reason=why))
            obs = tuple(obs)
            t3 = time.perf_counter()
            t["disparity"] = t3 - t2
        else:
            obs = tuple(self._observe_strip(frame, d) for d in dets)
            t3 = time.perf_counter()
            t["disparity"] = t3 - t2
        return self._solve(dets, obs, t, t3, faults, position, seed)

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
        ``level``; cut from ``patch``, the detection's, when it holds it) matched along its rows over the disparity search (normalised cross-correlation,
        parabolic sub-pixel peak), then the corners refined (:meth:`_refine_corners`; returned with
        its level).  ``None``, with the reason, when the best correlation is below
        ``min_correlation`` or a corner's window leaves the right image."""
        k = 1 << level
        W, H = frame.rig.width, frame.rig.height
        cl = np.asarray(det.corners, float)
        g = 2 * k
        tx0, ty0 = max(int(math.floor(cl[:, 0].min())) - g, 0), max(int(math.floor(cl[:, 1].min())) - g, 0)
        tx1, ty1 = min(int(math.ceil(cl[:, 0].max())) + g, W), min(int(math.ceil(cl[:, 1].max())) + g, H)
        p = self.matcher.sgbm_params
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

    def _observe_strip(self, frame: StereoFrame, det: Detection) -> LandmarkObservation:
        """SGBM on the strip around ``det``'s box only (rows ± margin, columns from the box's left edge
        minus the disparity range to its right edge), then the box median as :meth:`observe`."""
        c = self.camera
        p = self.matcher.sgbm_params
        m = self.band_margin_px
        x0, y0, x1, y1 = det.box
        X0 = max(int(math.floor(x0)) - p["min_disparity"] - p["num_disparities"] - m, 0)
        X1 = min(int(math.ceil(x1)) + 1 + m, c.width)
        Y0 = max(int(math.floor(y0)) - m, 0)
        Y1 = min(int(math.ceil(y1)) + 1 + m, c.height)
        box = (X0, Y0, X1, Y1)
        left, right = frame.patch("left", box), frame.patch("right", box)
        key = (X0, Y0, X1 - X0, Y1 - Y0)
        mt = self._band_matchers.get(key)
        if mt is None:
            strip = RectifiedCamera(c.f, c.cx - X0, c.cy - Y0, c.baseline, c.doffs, X1 - X0, Y1 - Y0)
            mt = StereoMatcher(strip, **p)
            if len(self._band_matchers) > 64:
                self._band_matchers.clear()
            self._band_matchers[key] = mt
        disp = mt.disparity(left, right)
        sx, sy = self.box_shrink * (x1 - x0), self.box_shrink * (y1 - y0)
        br = mt.box_range(disp, (x0 + sx - X0, y0 + sy - Y0, x1 - sx - X0, y1 - sy - Y0), sigma_d=self.sigma_d,
                          max_range=self.max_range_m)
        return self._observation(det, det.center, br.ok, br.range, br.sigma, br.point, float(br.disparity),
                                 int(br.n_valid), br.reason)

    def _known(self, detections, unknown: str | None = None) -> list[Detection]:
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

    def _early_out(self, in_view: int) -> LanBLocResult:
        """The result of a frame with fewer markers in view than a fix needs, not processed."""
        nan2, nan22 = np.full(2, np.nan), np.full((2, 2), np.nan)
        t = dict.fromkeys(("rectify", "detect", "disparity", "range", "localize"), 0.0)
        if in_view == 0:
            return LanBLocResult("no_landmarks", "no landmark in view", nan2, nan22, math.nan, (), (), None, t)
        return LanBLocResult("too_few_ranges", f"{in_view} landmark(s) in view, {self.min_landmarks} needed "
                             f"(frame not processed)", nan2, nan22, math.nan, (), (), None, t)

    @staticmethod
    def _no_landmarks(t: dict) -> LanBLocResult:
        t["disparity"] = t["range"] = t["localize"] = 0.0
        nan2, nan22 = np.full(2, np.nan), np.full((2, 2), np.nan)
        return LanBLocResult("no_landmarks", "no landmark recognised in the left image", nan2, nan22, math.nan,
                             (), (), None, t)

    def _solve(self, dets, obs, t: dict, t3: float, faults, position, seed) -> LanBLocResult:
        """Steps after ranging: landmark faults, trilateration, the mirror ambiguity, the result."""
        nan2, nan22 = np.full(2, np.nan), np.full((2, 2), np.nan)
        obs, dropped = self.apply_faults(obs, faults, position, seed)
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
            if best.ok and self._bearings_agree(best, ok):
                loc = dataclasses.replace(best, reason="mirror ambiguity resolved by the bearings")
        t["localize"] = time.perf_counter() - t4
        if not loc.ok:
            status = {"too_few": "too_few_ranges"}.get(loc.status, loc.status)
            status = status if status in STATUSES else "degenerate"
            return LanBLocResult(status, loc.reason, nan2, nan22, float(loc.gdop), obs, tuple(dets), loc, t,
                                 dropped)
        return LanBLocResult("ok", loc.reason, np.array(loc.position), np.array(loc.covariance), float(loc.gdop),
                             obs, tuple(dets), loc, t, dropped)

    __call__ = localize


# --------------------------------------------------------------------------- the camera loop

class CameraLoopSource:
    """LanBLoc through the camera loop: a position source for the navigation loop.

    ``source(true_state, step)`` renders the stereo pair at the true pose
    ``(x, y, θ)`` of ``true_state = (x, y, v, θ)``, runs :class:`LanBLoc`, and
    returns ``(z (2,), R (2, 2))`` — the fix and its covariance — or ``None``
    when localization fails (a dropout: no landmark in view, too few ranges,
    degenerate geometry).  ``R`` is the trilateration covariance plus
    ``covariance_floor_m² · I`` (default 0).

    Two modes (issue 16):

    * ``"regions"`` (default): the renderer's :class:`~safenav.vision.render.StereoFrame`,
      drawn only where markers project, and :meth:`LanBLoc.localize_frame`:
      detection in those regions and, for fiducials, ranging by triangulating
      the markers' refined corners (:meth:`LanBLoc.observe_corners`).  The work
      per frame grows with the markers in view, so the scenario camera's own
      resolution (the default rig, 2560×1440) is affordable.
    * ``"full"``: whole images rendered, detection on the whole left image and
      SGBM (the paper's pipeline; the reference).

    ``occlusion`` (default on): obstacles hide the landmarks behind them
    (:meth:`~safenav.vision.render.StereoRenderer.hidden`).

    ``early_out`` (region mode, default on): a frame whose left image holds
    fewer whole markers (all four corners inside the image) than
    ``min_landmarks`` cannot give a fix, so it is not processed (status ``no_landmarks`` or ``too_few_ranges``, no
    observations; first a cheaper bound, the markers whose centres project
    into the image).  Each frame's pixel noise is its own stream
    (``derive_seed(derive_seed(seed, NOISE_STREAM), step)``), so the fixes
    are the same with and without it; the per-landmark counts of the
    skipped frames (``fault_stats``) are missing, and a skipped frame's
    status is ``no_landmarks`` only when the bound is 0.

    The last frame's :class:`LanBLocResult` is :attr:`last` (detections,
    per-landmark ranges and bearings, status and reason, stage timings);
    :attr:`last_images` holds the pair when ``keep_images`` is set (full mode),
    :attr:`last_frame` the StereoFrame (regions mode);
    :attr:`stats` counts calls, fixes and failure statuses.

    ``faults`` (a :class:`safenav.navigation.LandmarkFaults`, default none) corrupts the
    per-landmark ranges before trilateration, as the simulator's
    ``FixModel.RANGES`` does (:meth:`LanBLoc.apply_faults`), with the vehicle's
    true position and the frame seed ``derive_seed(derive_seed(seed,
    FAULT_STREAM), step)``.  :attr:`fault_stats` counts, over all frames, the
    ranged ``observations`` (before faults), the ``dropped``, ``outliers`` and
    ``misassociated`` ones, the ``ranges_rejected`` by the trilateration's
    outlier test in the fixes, and the faulty ranges that fixes used
    (``faults_in_fix``); the last fix's are ``last.faults_in_fix``.
    """

    name = "lanbloc-camera"
    emulated = False

    #: The default rig: the scenario camera at its own resolution ([SafeNav-ext §V-A2]: 2560×1440 px,
    #: f = 1400 px, B = 0.3 m).
    DEFAULT_RIG = StereoRig(2560, 1440, 1400.0, 0.3)

    def __init__(self, world: World, rig: StereoRig | None = None, detector: Detector | None = None, *,
                 marker_size_m: float = 1.5, dictionary: str = "DICT_4X4_100", noise_std: float = 1.0,
                 sigma_d: float = 0.2, mode: str = "regions", occlusion: bool = True, early_out: bool = True,
                 seed: int = 0, texture_seed: int = 0, covariance_floor_m: float = 0.0, keep_images: bool = False,
                 faults=None, **pipeline):
        if mode not in ("regions", "full"):
            raise ValueError(f"mode = {mode!r}: must be 'regions' (render and detect the markers' regions, "
                             f"triangulate corners) or 'full' (whole frames, SGBM; the reference)")
        self.mode = mode
        self.early_out = bool(early_out)
        if not isinstance(world, World):
            raise ValueError(f"world = {world!r}: must be a safenav World")
        self.faults = _check_faults(faults)
        self.seed = seed
        if self.faults is not None or mode == "regions":
            if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2 ** 64:
                raise ValueError(f"seed = {seed!r}: must be an integer in [0, 2**64)")
            self._fault_seed = int(_core.derive_seed(int(seed), FAULT_STREAM))
            self._noise_seed = int(_core.derive_seed(int(seed), NOISE_STREAM))
        self.world = world
        self.rig = self.DEFAULT_RIG if rig is None else rig
        self.renderer = StereoRenderer(world, self.rig, marker_size_m=marker_size_m, dictionary=dictionary,
                                       noise_std=noise_std, seed=seed, texture_seed=texture_seed,
                                       occlusion=occlusion)
        if detector is None:
            detector = FiducialDetector(world, dictionary=dictionary, aruco3=mode == "regions")
        if mode == "regions" and isinstance(detector, FiducialDetector):
            pipeline.setdefault("ranging", "corners")
        self.pipeline = LanBLoc(world, self.rig, detector, sigma_d=sigma_d, **pipeline)
        self.covariance_floor_m = _finite("covariance_floor_m", covariance_floor_m, nonneg=True)
        self.keep_images = bool(keep_images)
        self.last: LanBLocResult | None = None
        self.last_step: int | None = None
        self.last_images: tuple[np.ndarray, np.ndarray] | None = None
        self.last_frame: StereoFrame | None = None
        self.stats: dict[str, int] = {"calls": 0, **{s: 0 for s in STATUSES}}
        self.fault_stats: dict[str, int] = dict.fromkeys(
            ("observations", "dropped", "outliers", "misassociated", "ranges_rejected", "faults_in_fix"), 0)

    @classmethod
    def from_scenario(cls, scenario, width: int | None = None, height: int | None = None, *,
                      camera_height_m: float = 1.5, **kwargs) -> "CameraLoopSource":
        """From a :class:`~safenav.scenario.Scenario`: its world, its camera (at its own resolution, or
        scaled to ``width`` px), its detection range, minimum landmark count and occlusion setting."""
        width = scenario.camera.image_width_px if width is None else width
        rig = StereoRig.from_camera(scenario.camera, width, height, camera_height_m=camera_height_m,
                                    max_range_m=scenario.detection.max_range_m)
        kwargs.setdefault("min_landmarks", max(3, scenario.detection.min_landmarks))
        kwargs.setdefault("occlusion", getattr(scenario.detection, "occlusion", False))
        return cls(scenario.world, rig, **kwargs)

    def __call__(self, true_state, step: int):
        s = np.asarray(true_state, dtype=float).ravel()
        if s.shape != (4,) or not np.isfinite(s).all():
            raise ValueError(f"true_state = {true_state!r}: must be a finite (x, y, v, theta)")
        pose = (s[0], s[1], s[3])
        if (self.faults is not None or self.mode == "regions") and (
                isinstance(step, bool) or not isinstance(step, (int, np.integer)) or step < 0):
            raise ValueError(f"step = {step!r}: must be an integer >= 0")
        t0 = time.perf_counter()
        in_view = None
        if self.mode == "full":
            left, right = self.renderer.render(pose)
        elif self.early_out and (n := self.renderer.centres_in_view(pose)) < self.pipeline.min_landmarks:
            left = right = None   # a cheap bound on the whole markers is short already
            in_view = n
        else:
            left, right = self.renderer.frame(pose, int(_core.derive_seed(self._noise_seed, int(step)))), None
            in_view = len(left.whole_markers("left"))
        t_render = time.perf_counter() - t0
        if self.early_out and in_view is not None and in_view < self.pipeline.min_landmarks:
            # Fewer whole markers in the left image than a fix needs: no detector can find more, so
            # this frame gives no fix whatever the pipeline does (the frame's pixels are its own, so
            # skipping it changes no other frame).
            res = self.pipeline._early_out(in_view)
        elif self.faults is None:
            res = self.pipeline.localize(left, right)
        else:
            res = self.pipeline.localize(left, right, faults=self.faults, position=s[:2],
                                         seed=int(_core.derive_seed(self._fault_seed, int(step))))
        res.timings["render"] = t_render
        self.last, self.last_step = res, int(step)
        self.last_images = (left, right) if self.keep_images and self.mode == "full" else None
        self.last_frame = left if self.mode == "regions" else None
        self.stats["calls"] += 1
        self.stats[res.status] = self.stats.get(res.status, 0) + 1
        fs = self.fault_stats
        fs["observations"] += res.n_ranges + res.dropped
        fs["dropped"] += res.dropped
        fs["outliers"] += sum(bool(o.faults & OUTLIER) for o in res.observations)
        fs["misassociated"] += sum(bool(o.faults & MISASSOCIATED) for o in res.observations)
        fs["ranges_rejected"] += len(res.rejected)
        fs["faults_in_fix"] += len(res.faults_in_fix)
        if not res.ok:
            return None
        R = res.covariance + self.covariance_floor_m ** 2 * np.eye(2)
        return res.position.copy(), R

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
and every landmark's range and bearing (:class:`~safenav.vision.sighting.LandmarkSighting`)
so that a filter can use the ranges directly (``result.range_measurements()`` →
anchors, ranges, σ for :meth:`safenav.MeasurementModel.range`).

The fix is the position of the **left camera's centre** projected on the
ground: the rig's reference point (see :mod:`safenav.vision.render`).

The pipeline has one implementation per kind of input, both ending in one
shared step: :class:`~safenav.vision.full_frame.FullFramePipeline` (whole
stereo pairs, steps 1–4 as above: the paper's pipeline and the reference),
:class:`~safenav.vision.regions.RegionPipeline` (a renderer's
:class:`~safenav.vision.frame.StereoFrame`, region by region; ours) and
:class:`~safenav.vision.ranging.LandmarkRanging` (step 4's ranges and
bearings from a depth, landmark faults and step 5).  :class:`LanBLoc` builds
the three from one set of parameters and sends each input to its pipeline.

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

import math
import time
from typing import Mapping

import numpy as np

from .. import _core
from ..world import World
from .detect import Detector, FiducialDetector
from .frame import StereoFrame
from .full_frame import FullFramePipeline
from .ranging import PIPELINE_SGBM, LandmarkRanging, check_faults, check_finite
from .regions import RegionPipeline
from .render import StereoRenderer
from .rig import StereoRig
from .sighting import MISASSOCIATED, OUTLIER, STATUSES, LandmarkSighting, LanBLocResult

__all__ = ["LandmarkSighting", "LanBLocResult", "LanBLoc", "CameraLoopSource", "STATUSES", "MISASSOCIATED",
           "OUTLIER", "PIPELINE_SGBM", "FAULT_STREAM", "NOISE_STREAM"]

#: The random stream of the landmark faults under :class:`CameraLoopSource`'s seed
#: (``derive_seed(derive_seed(seed, FAULT_STREAM), step)`` per frame).
FAULT_STREAM = 1
#: The pixel-noise stream of :class:`CameraLoopSource`'s frames in region mode
#: (``derive_seed(derive_seed(seed, NOISE_STREAM), step)`` per frame).
NOISE_STREAM = 2


def scenario_camera(scenario, width, height, camera_height_m: float, kwargs: dict) -> tuple:
    """(rig, keyword arguments) of a camera loop built from a scenario: its
    camera (at its own resolution, or scaled to ``width`` px) and detection
    range as a :class:`StereoRig`; ``kwargs`` with the scenario's minimum
    landmark count and occlusion setting as defaults."""
    width = scenario.camera.image_width_px if width is None else width
    rig = StereoRig.from_camera(scenario.camera, width, height, camera_height_m=camera_height_m,
                                max_range_m=scenario.detection.max_range_m)
    kw = {"min_landmarks": max(3, scenario.detection.min_landmarks),
          "occlusion": getattr(scenario.detection, "occlusion", False), **kwargs}
    return rig, kw


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
        A :class:`~safenav.vision.rig.StereoRig` (rendered, rectified pairs), a
        :class:`~safenav.vision.stereo.RectifiedCamera`, a
        :class:`~safenav.vision.calibration.StereoCalibration` (pairs are rectified first)
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
        with it (see :meth:`~safenav.vision.ranging.LandmarkRanging.bearings_agree`); collinear anchors and large
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
    backend:
        ``"auto"`` (default), ``"python"`` or ``"core"``.  ``"core"``: whole
        pairs through the C++ front end
        (:class:`~safenav.vision.core_pipeline.CorePipeline`): with a
        fiducial detector, detection, refinement and ranging (corners or
        SGBM) in the core, then the shared last step; with another detector
        (a YOLO model) and ``ranging="sgbm"``, its boxes ranged in the core
        (the Python pipeline's SGBM ranging, bit for bit).  ``"auto"``: the
        core with the default detector (a ``detector`` given here keeps its
        own settings, which the core does not read, so it keeps the Python
        pipeline); the Python pipeline otherwise.  The two agree up to the
        OpenCV versions' detectors (:mod:`~safenav.vision.core_pipeline`).
        :attr:`backend` is the one chosen.  :meth:`localize_frame` is the
        Python region pipeline whatever the backend.
    trilateration:
        Keyword arguments for :func:`~safenav.vision.localization.trilaterate`.
    ranging:
        ``"sgbm"`` (the paper's dense stereo: the box median of SGBM
        disparities, :meth:`observe`) or ``"corners"`` (ours, fiducials only:
        the marker's refined corners found in both images, triangulated,
        :meth:`observe_corners`).
    corner_sigma_d:
        σ [px] of the marker centre's disparity from four corners, for
        ``σ_Z = Z²·σ/(f·B)`` (``"corners"``; the corner-noise model
        ``_core.corner_disparity_sigma``); default: the core's
        ``LanBLocSettings``.
    max_row_error_px:
        Largest row difference between a corner in the left and the right
        image (rectified: ideally 0); one corner beyond it is left out, two
        or more reject the pair (``_core.corner_disparity``); default: the
        core's ``LanBLocSettings``.
    detect_side_px, region_margin_px:
        On a :class:`~safenav.vision.frame.StereoFrame`: the marker side
        [px] at the pyramid level used for detection, and the margin around
        the markers' footprints (:meth:`localize_frame`).

    The parts are :attr:`ranger` (a :class:`~safenav.vision.ranging.LandmarkRanging`) and
    :attr:`pipelines` (``"full"``: a :class:`~safenav.vision.full_frame.FullFramePipeline`,
    ``"regions"``: a :class:`~safenav.vision.regions.RegionPipeline`); each setting above is
    readable on the pipeline as on the part that uses it (``lanbloc.sigma_d``).
    """

    def __init__(self, landmarks, camera, detector: Detector | None = None, *,
                 camera_height_m: float | None = None, pitch_rad: float | None = None, sigma_d: float = 0.5,
                 min_landmarks: int = 3, max_range_m: float = math.inf, box_shrink: float = 0.1,
                 row_band: bool = True, band_margin_px: int = 24, bearing_sigma_px: float = 1.0,
                 unknown_landmark: str = "error", resolve_ambiguity: bool = True, sgbm: Mapping | None = None,
                 trilateration: Mapping | None = None, ranging: str = "sgbm", corner_sigma_d: float | None = None,
                 max_row_error_px: float | None = None, detect_side_px: float = 48.0, region_margin_px: int = 8,
                 min_range_m: float = 2.5, min_correlation: float = 0.8, backend: str = "auto"):
        self.ranger = LandmarkRanging(
            landmarks, camera, camera_height_m=camera_height_m, pitch_rad=pitch_rad, sigma_d=sigma_d,
            min_landmarks=min_landmarks, max_range_m=max_range_m, box_shrink=box_shrink,
            bearing_sigma_px=bearing_sigma_px, unknown_landmark=unknown_landmark,
            resolve_ambiguity=resolve_ambiguity, sgbm=sgbm, trilateration=trilateration,
            corner_sigma_d=corner_sigma_d, max_row_error_px=max_row_error_px, min_range_m=min_range_m)
        if backend not in ("auto", "python", "core"):
            raise ValueError(f"backend = {backend!r}: must be 'auto', 'python' or 'core'")
        if backend == "auto":
            backend = "core" if detector is None else "python"
        if detector is None:
            detector = FiducialDetector(landmarks if isinstance(landmarks, World) else
                                        {k: k for k in self.ranger.landmarks})
        self.pipelines = {
            "full": FullFramePipeline(self.ranger, detector, ranging=ranging, row_band=row_band,
                                      band_margin_px=band_margin_px),
            "regions": RegionPipeline(self.ranger, detector, ranging=ranging, band_margin_px=band_margin_px,
                                      detect_side_px=detect_side_px, region_margin_px=region_margin_px,
                                      min_correlation=min_correlation)}
        if backend == "core":
            from .core_pipeline import CorePipeline
            self.pipelines["core"] = CorePipeline(self.ranger, detector, self.pipelines["full"].check_pair,
                                                  ranging=self.pipelines["full"].ranging, row_band=row_band,
                                                  band_margin_px=band_margin_px)
        self.backend = backend

    #: The settings read through from the parts, by part.
    _SETTINGS = {
        "ranger": ("landmarks", "camera", "matcher", "camera_height_m", "pitch_rad", "sigma_d", "min_landmarks",
                   "max_range_m", "box_shrink", "bearing_sigma_px", "unknown_landmark", "resolve_ambiguity",
                   "trilateration", "corner_sigma_d", "max_row_error_px", "min_range_m"),
        "full": ("detector", "ranging", "row_band", "band_margin_px"),
        "regions": ("detect_side_px", "region_margin_px", "min_correlation", "REFINE_SIDE_PX"),
    }

    def __getattr__(self, name: str):
        parts = self.__dict__
        for part, names in LanBLoc._SETTINGS.items():
            if name in names and "pipelines" in parts:
                return getattr(parts["ranger"] if part == "ranger" else parts["pipelines"][part], name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    # ---------------------------------------------------------------- stages (see the parts)
    def check_pair(self, left, right) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`FullFramePipeline.check_pair <safenav.vision.full_frame.FullFramePipeline.check_pair>`."""
        return self.pipelines["full"].check_pair(left, right)

    def disparity(self, left, right, boxes=()) -> np.ndarray:
        """:meth:`FullFramePipeline.disparity <safenav.vision.full_frame.FullFramePipeline.disparity>`."""
        return self.pipelines["full"].disparity(left, right, boxes)

    def observe(self, det, disparity: np.ndarray) -> LandmarkSighting:
        """:meth:`LandmarkRanging.observe <safenav.vision.ranging.LandmarkRanging.observe>`."""
        return self.ranger.observe(det, disparity)

    def observe_corners(self, det, right, refine_level: int = 0, reason: str = "") -> LandmarkSighting:
        """:meth:`LandmarkRanging.observe_corners <safenav.vision.ranging.LandmarkRanging.observe_corners>`."""
        return self.ranger.observe_corners(det, right, refine_level, reason)

    def apply_faults(self, observations, faults, position, seed: int) -> tuple[tuple[LandmarkSighting, ...], int]:
        """:meth:`LandmarkRanging.apply_faults <safenav.vision.ranging.LandmarkRanging.apply_faults>`."""
        return self.ranger.apply_faults(observations, faults, position, seed)

    # ---------------------------------------------------------------- a frame
    def localize(self, left, right, *, faults=None, position=None, seed: int = 0) -> LanBLocResult:
        """Run the pipeline on one stereo pair (raw if the camera needs rectification): the whole-frame
        pipeline (:meth:`FullFramePipeline.localize <safenav.vision.full_frame.FullFramePipeline.localize>`).

        ``left`` may also be a :class:`~safenav.vision.frame.StereoFrame` (with
        ``right=None``): then the region pipeline runs (:meth:`localize_frame`).

        ``faults``: landmark-level faults (a :class:`safenav.navigation.LandmarkFaults`) on
        the ranges before trilateration, with the vehicle's true ``position``
        and the frame's ``seed`` (see :meth:`apply_faults`); ``None``: none.
        """
        if isinstance(left, StereoFrame):
            if right is not None:
                raise ValueError("right must be None when left is a StereoFrame")
            return self.localize_frame(left, faults=faults, position=position, seed=seed)
        return self.pipelines["core" if self.backend == "core" else "full"].localize(
            left, right, faults=faults, position=position, seed=seed)

    def localize_frame(self, frame: StereoFrame, *, faults=None, position=None, seed: int = 0) -> LanBLocResult:
        """The pipeline on a :class:`~safenav.vision.frame.StereoFrame`, region by region (ours):
        :meth:`RegionPipeline.localize <safenav.vision.regions.RegionPipeline.localize>`."""
        return self.pipelines["regions"].localize(frame, faults=faults, position=position, seed=seed)

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

    Two modes:

    * ``"regions"`` (default): the renderer's :class:`~safenav.vision.frame.StereoFrame`,
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
    outlier test in the fixes or left unused because another range of the
    frame named their landmark too, and the faulty ranges that fixes used
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
        self.faults = check_faults(faults)
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
        self.covariance_floor_m = check_finite("covariance_floor_m", covariance_floor_m, nonneg=True)
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
        rig, kwargs = scenario_camera(scenario, width, height, camera_height_m, kwargs)
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
            res = self.pipeline.ranger.early_out(in_view)
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
        fs["observations"] += res.n_ranges + len(res.repeated) + res.dropped
        fs["dropped"] += res.dropped
        fs["outliers"] += sum(bool(o.faults & OUTLIER) for o in res.observations)
        fs["misassociated"] += sum(bool(o.faults & MISASSOCIATED) for o in res.observations)
        fs["ranges_rejected"] += len(res.rejected) + len(res.repeated)
        fs["faults_in_fix"] += len(res.faults_in_fix)
        if not res.ok:
            return None
        R = res.covariance + self.covariance_floor_m ** 2 * np.eye(2)
        return res.position.copy(), R

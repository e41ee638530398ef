"""Stereo ranging for LanBLoc [SafeNav §IV-A].

LanBLoc measures the distance from the vehicle to each recognised landmark
with stereo matching, then trilaterates (:mod:`safenav.vision.localization`).  This
module is the ranging half, in C++ over OpenCV:

* :class:`~safenav.vision.calibration.StereoCalibration` — ``K1, D1, K2, D2,
  R, T`` and the image size, exactly what ``cv2.stereoCalibrate`` returns
  (:mod:`safenav.vision.calibration`);
* :class:`RectifiedCamera` — the ideal rectified rig ``(f, cx, cy, B, doffs)``
  with ``Z = f·B / (d + doffs)`` (Middlebury's convention; ``doffs`` is the
  right principal column minus the left one);
* :class:`StereoMatcher` — ``stereoRectify`` + ``initUndistortRectifyMap``
  (maps cached), SGBM disparities (float pixels, NaN where invalid), depth,
  and :meth:`StereoMatcher.box_range`: the median depth of the valid pixels in
  a detection box with ``σ_Z ≈ Z²·σ_d / (f·B)`` (first-order propagation of
  the disparity noise σ_d through ``Z = f·B/(d + doffs)``).
  :meth:`StereoMatcher.for_depth_range` sizes SGBM's disparity search from
  the depths of interest (:func:`disparity_range`);
* :func:`~safenav.vision.scores.disparity_scores` — Middlebury-style scores
  of a disparity map against ground truth, counted two ways
  (:mod:`safenav.vision.scores`).

Images are ``uint8`` arrays ``(H, W)`` or ``(H, W, 3)``; boxes are
``(x_min, y_min, x_max, y_max)`` pixels (xyxy), covering the pixel columns
``x_min <= i < x_max`` and rows ``y_min <= j < y_max``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from .. import _core
from ..validation import as_array, declared
from .calibration import StereoCalibration
from .scores import MIDDLEBURY_THRESHOLDS, DisparityScores, disparity_scores

SgbmMode = _core.SgbmMode

__all__ = ["StereoCalibration", "RectifiedCamera", "StereoMatcher", "BoxRange", "SgbmMode", "SGBM_DEFAULTS",
           "disparity_range", "DISPARITY_MARGIN_PX", "DisparityScores", "disparity_scores", "MIDDLEBURY_THRESHOLDS"]

#: SGBM parameters and their defaults (OpenCV's names, snake_case).  ``P1 = P2
#: = 0`` selects OpenCV's recommended ``8·cn·block_size²`` and ``32·cn·block_size²``.
SGBM_DEFAULTS = dict(min_disparity=0, num_disparities=64, block_size=5, P1=0, P2=0, disp12_max_diff=1,
                     pre_filter_cap=63, uniqueness_ratio=10, speckle_window_size=100, speckle_range=2,
                     mode="sgbm")
_MODES = {"sgbm": SgbmMode.SGBM, "hh": SgbmMode.HH, "sgbm_3way": SgbmMode.SGBM_3WAY, "hh4": SgbmMode.HH4}


@dataclass(frozen=True)
class RectifiedCamera:
    """An ideal rectified rig: focal length ``f`` (px), principal point
    ``(cx, cy)`` of the left camera (the right one's is ``(cx + doffs, cy)``),
    ``baseline`` B (its unit is the depth unit) and image size.

    Depth from disparity: ``Z = f·B / (d + doffs)``.
    """

    f: float
    cx: float
    cy: float
    baseline: float
    doffs: float = 0.0
    width: int = 640
    height: int = 480

    def __post_init__(self):
        for name in ("f", "cx", "cy", "baseline", "doffs"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise ValueError(f"rectified camera {name} = {v!r} must be a number")
        for name in ("width", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                raise ValueError(f"rectified camera {name} = {v!r} must be an integer number of pixels")
        self._core().validate()

    def _core(self) -> _core.RectifiedCamera:
        c = _core.RectifiedCamera()
        for f in fields(self):
            setattr(c, f.name, getattr(self, f.name))
        return c

    @classmethod
    def _from_core(cls, c) -> "RectifiedCamera":
        return cls(f=c.f, cx=c.cx, cy=c.cy, baseline=c.baseline, doffs=c.doffs, width=c.width, height=c.height)

    @property
    def K(self) -> np.ndarray:
        """Intrinsics of the rectified left camera."""
        return np.array([[self.f, 0.0, self.cx], [0.0, self.f, self.cy], [0.0, 0.0, 1.0]])

    def depth_of(self, disparity) -> np.ndarray:
        """``Z = f·B / (d + doffs)`` elementwise (NaN where ``d + doffs <= 0``)."""
        d = np.asarray(disparity, dtype=np.float64)
        w = d + self.doffs
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(w > 0, self.f * self.baseline / w, np.nan)

    def disparity_of(self, depth) -> np.ndarray:
        """Inverse of :meth:`depth_of`: ``d = f·B / Z − doffs``."""
        return self.f * self.baseline / np.asarray(depth, dtype=np.float64) - self.doffs

    def resolvable_range(self, min_disparity: float = 1.0) -> float:
        """Largest depth whose ``d + doffs`` is still ``min_disparity`` pixels."""
        return self.f * self.baseline / float(min_disparity)


# ---------------------------------------------------------------------------
# disparity search range from geometry
# ---------------------------------------------------------------------------

#: Default margin of :func:`disparity_range` at the near end [px]: one pixel
#: so that the nearest depth's disparity is not the last one searched (SGBM
#: fits its sub-pixel parabola only between two searched neighbours), one for
#: calibration error.
DISPARITY_MARGIN_PX = 2


def _depth_arg(name: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} = {v!r} must be a number (metres)")
    return float(v)


def _int_arg(name: str, v, lo: int) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
        raise ValueError(f"{name} = {v!r} must be an integer >= {lo}")
    return int(v)


def _rectified_camera(camera, alpha: float) -> "RectifiedCamera":
    if isinstance(camera, RectifiedCamera):
        return camera
    if isinstance(camera, StereoMatcher):
        return camera.camera
    if isinstance(camera, StereoCalibration):
        # the rectified rig (f, B, doffs) as stereoRectify makes it for this alpha
        return StereoMatcher(camera, alpha=alpha).camera
    raise ValueError(f"camera must be a RectifiedCamera, a StereoCalibration or a StereoMatcher, "
                     f"got {type(camera).__name__}")


def disparity_range(camera, near_m, far_m=math.inf, *, block_size: int = SGBM_DEFAULTS["block_size"],
                    margin_px: int = DISPARITY_MARGIN_PX, alpha: float = 0.0) -> tuple[int, int]:
    """SGBM's ``(min_disparity, num_disparities)`` for the depths ``[near_m, far_m]``.

    A depth ``Z`` is seen at the disparity (the inverse of
    ``Z = f·B / (d + doffs)``)::

        d(Z) = f·B / Z − doffs                      (d(∞) = −doffs)

    and SGBM searches the integer disparities ``min_disparity ≤ d <
    min_disparity + num_disparities``.  So::

        min_disparity   = ⌊d(far_m)⌋                (⌊−doffs⌋ for far_m = ∞)
        d_max           = ⌈d(near_m)⌉ + margin_px
        num_disparities = 16·⌈(d_max − min_disparity + 1) / 16⌉

    rounded *up* to OpenCV's multiple of 16; every depth in ``[near_m,
    far_m]`` then has its disparity inside the search.  A fixed 64 instead
    caps the nearest depth at ``f·B / (63 + doffs)``: anything nearer is
    mismatched or left invalid.  ``margin_px`` (default
    :data:`DISPARITY_MARGIN_PX`) widens the near end only; depths beyond
    ``far_m`` fall outside the search and come back invalid or at the far
    bound.

    The search has a cost besides time: SGBM leaves the first
    ``min_disparity + num_disparities`` columns (and, for a negative
    ``min_disparity``, the last ``−min_disparity``) without a disparity.  A
    range that leaves fewer than ``block_size`` columns of the image raises
    ``ValueError`` (raise ``near_m``).

    The core computes it (``_core.disparity_search``, which the C++ LanBLoc
    front end's SGBM ranging uses too).

    ``camera`` is a :class:`RectifiedCamera`, a :class:`StereoMatcher` (its
    ``camera``) or a :class:`StereoCalibration` (the rectified rig that
    ``StereoMatcher(calibration, alpha=alpha)`` uses: ``doffs = 0`` there,
    zero disparity at infinity).  Depths are in the baseline's unit (metres).

    Raises ``ValueError`` naming the value when ``near_m`` is not finite and
    > 0, ``far_m`` is NaN or not > ``near_m``, or ``margin_px``/``block_size``
    are not integers ≥ 0 / odd ≥ 1.
    """
    near = _depth_arg("near_m", near_m)
    far = _depth_arg("far_m", far_m)
    if not (math.isfinite(near) and near > 0.0):
        raise ValueError(f"near_m = {near_m!r} must be finite and > 0")
    if math.isnan(far) or not far > near:
        raise ValueError(f"far_m = {far_m!r} must be > near_m = {near_m!r} (math.inf for no far limit)")
    margin = _int_arg("margin_px", margin_px, 0)
    block = _int_arg("block_size", block_size, 1)
    if block % 2 == 0:
        raise ValueError(f"block_size = {block_size!r} must be odd")
    base = _core.SgbmParams()
    base.block_size = block
    p = _core.disparity_search(_rectified_camera(camera, alpha)._core(), near, far, base, margin)
    return int(p.min_disparity), int(p.num_disparities)


# ---------------------------------------------------------------------------
# matching and ranging
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class BoxRange:
    """Range to a landmark from the disparities inside its detection box."""

    ok: bool
    range: float       #: median depth Z of the valid pixels (along the optical axis), NaN if not ok
    sigma: float       #: σ_Z ≈ Z²·σ_d / (f·B)
    disparity: float   #: median disparity d (px)
    n_valid: int       #: valid pixels in the box
    n_pixels: int      #: pixels in the box (clipped to the image)
    point: np.ndarray  #: box centre at depth Z, rectified left camera frame (x right, y down, z forward)
    reason: str        #: why there is no range ("" when ok)

    @property
    def distance(self) -> float:
        """Slant distance ‖point‖ from the left camera centre to the box centre."""
        return float(np.linalg.norm(self.point))

    @property
    def horizontal_distance(self) -> float:
        """``hypot(x, z)``: the distance in the camera's horizontal plane (level camera)."""
        return float(math.hypot(self.point[0], self.point[2]))

    @property
    def bearing(self) -> float:
        """Bearing of the box centre relative to the optical axis, counter-clockwise
        (to the left) positive, rad: ``atan2(−x, z)`` (level camera)."""
        return float(math.atan2(-self.point[0], self.point[2]))

    @property
    def sigma_horizontal(self) -> float:
        """σ of :attr:`horizontal_distance` (it scales with Z along the ray)."""
        return float(self.sigma * self.horizontal_distance / self.range) if self.ok else math.nan


def _image(name: str, img) -> np.ndarray:
    if not isinstance(img, np.ndarray):
        raise ValueError(f"{name} must be a numpy uint8 array, got {type(img).__name__}")
    if img.dtype != np.uint8:
        raise ValueError(f"{name} must have dtype uint8, got {img.dtype}")
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] not in (1, 3, 4)):
        raise ValueError(f"{name} must have shape (H, W) or (H, W, 1|3|4), got {img.shape}")
    if img.size == 0:
        raise ValueError(f"{name} is empty: shape {img.shape}")
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    return np.ascontiguousarray(img)


def _pair(left, right, lname="left", rname="right"):
    l, r = _image(lname, left), _image(rname, right)
    if l.shape != r.shape:
        raise ValueError(f"{lname} and {rname} images differ in shape: {l.shape} vs {r.shape}")
    return l, r


def _sgbm(params: dict) -> _core.SgbmParams:
    unknown = set(params) - set(SGBM_DEFAULTS)
    if unknown:
        raise ValueError(f"unknown SGBM parameter(s) {sorted(unknown)}; known: {sorted(SGBM_DEFAULTS)}")
    p = _core.SgbmParams()
    for k, v in {**SGBM_DEFAULTS, **params}.items():
        if k == "mode":
            if isinstance(v, str):
                if v.lower() not in _MODES:
                    raise ValueError(f"mode = {v!r} must be one of {sorted(_MODES)}")
                v = _MODES[v.lower()]
            elif not isinstance(v, SgbmMode):
                raise ValueError(f"mode = {v!r} must be one of {sorted(_MODES)}")
        elif isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise ValueError(f"SGBM parameter {k} = {v!r} must be an integer")
        setattr(p, k, v if k == "mode" else int(v))
    p.validate()
    return p


class StereoMatcher:
    """Rectification + SGBM + ranging for one stereo rig.

    ``StereoMatcher(calibration, alpha=0.0, **sgbm_params)`` with a
    :class:`StereoCalibration` rectifies with ``cv2.stereoRectify`` (zero
    disparity at infinity, ``alpha`` as in OpenCV: 0 keeps only valid pixels)
    and caches the ``initUndistortRectifyMap`` maps.  With a
    :class:`RectifiedCamera` (renderer output, Middlebury) the images are
    already rectified and :meth:`rectify` only validates and copies.

    ``sgbm_params`` are every ``cv2.StereoSGBM`` parameter in snake_case
    (see :data:`SGBM_DEFAULTS`); ``mode`` is ``"sgbm"``, ``"hh"``,
    ``"sgbm_3way"`` or ``"hh4"``.  Not thread-safe; use one per thread.
    """

    def __init__(self, calibration, *, alpha: float = 0.0, **sgbm_params):
        params = _sgbm(sgbm_params)
        if isinstance(calibration, StereoCalibration):
            self._m = _core.StereoMatcher(calibration._core(), params, float(alpha))
        elif isinstance(calibration, RectifiedCamera):
            self._m = _core.StereoMatcher(calibration._core(), params)
        else:
            raise ValueError(f"calibration must be a StereoCalibration or a RectifiedCamera, "
                             f"got {type(calibration).__name__}")
        self.calibration = calibration
        self.camera = RectifiedCamera._from_core(self._m.camera)

    @classmethod
    def for_depth_range(cls, calibration, near_m, far_m=math.inf, *, alpha: float = 0.0,
                        margin_px: int = DISPARITY_MARGIN_PX, **sgbm_params) -> "StereoMatcher":
        """A matcher whose disparity search covers the depths ``[near_m, far_m]``.

        ``min_disparity`` and ``num_disparities`` come from
        :func:`disparity_range` (``d = f·B/Z − doffs``; ``min_disparity =
        ⌊d(far_m)⌋``, ``num_disparities`` = 16·⌈(⌈d(near_m)⌉ + margin_px −
        min_disparity + 1)/16⌉); either one given in ``sgbm_params`` wins.
        For the pipeline: ``near_m`` is the nearest depth a landmark is ranged
        at, ``far_m`` the detection range (or ``math.inf``).  Other arguments
        are :class:`StereoMatcher`'s.
        """
        block = sgbm_params.get("block_size", SGBM_DEFAULTS["block_size"])
        lo, num = disparity_range(calibration, near_m, far_m, block_size=block, margin_px=margin_px, alpha=alpha)
        return cls(calibration, alpha=alpha, **{"min_disparity": lo, "num_disparities": num, **sgbm_params})

    @property
    def sgbm_params(self) -> dict:
        p = self._m.params
        out = {k: getattr(p, k) for k in SGBM_DEFAULTS if k != "mode"}
        out["mode"] = {v: k for k, v in _MODES.items()}[p.mode]
        return out

    @property
    def needs_rectification(self) -> bool:
        return self._m.needs_rectification

    @property
    def rectification(self) -> dict:
        """``R1, R2`` (3×3), ``P1, P2`` (3×4) and ``Q`` (4×4) as ``cv2.stereoRectify`` gives them."""
        return {k: getattr(self._m, k) for k in ("R1", "R2", "P1", "P2", "Q")}

    def rectify(self, left, right) -> tuple[np.ndarray, np.ndarray]:
        """Remap a raw pair into the rectified frame (bilinear; the maps are cached)."""
        return self._m.rectify(*_pair(left, right))

    def rectify_points(self, points, camera: str = "left") -> np.ndarray:
        """Map raw pixel coordinates ``(N, 2)`` of ``camera`` ("left"/"right") to rectified ones."""
        pts = as_array("points", points, (None, 2))
        if camera == "left":
            return self._m.rectify_points_left(pts)
        if camera == "right":
            return self._m.rectify_points_right(pts)
        raise ValueError(f"camera must be 'left' or 'right', got {camera!r}")

    def disparity(self, left_rect, right_rect) -> np.ndarray:
        """SGBM disparity ``(H, W)`` float32 pixels of a rectified pair, NaN where invalid."""
        return self._m.disparity(*_pair(left_rect, right_rect, "left_rect", "right_rect"))

    def compute(self, left, right) -> np.ndarray:
        """Rectify (when needed) and match a raw pair; returns the disparity."""
        if self.needs_rectification:
            left, right = self.rectify(left, right)
        return self.disparity(left, right)

    def depth(self, disparity) -> np.ndarray:
        """``Z = f·B / (d + doffs)`` (float32, NaN where invalid)."""
        return self._m.depth(self._disparity(disparity))

    def _disparity(self, disparity) -> np.ndarray:
        d = np.asarray(disparity)
        want = (self.camera.height, self.camera.width)
        if d.shape != want:
            raise ValueError(f"disparity must have shape {want}, got {d.shape}")
        if not np.issubdtype(d.dtype, np.floating):
            raise ValueError(f"disparity must be a float array, got dtype {d.dtype}")
        return np.ascontiguousarray(d, dtype=np.float32)

    def box_range(self, disparity, box, *, sigma_d: float = 0.5, min_valid_pixels: int = 20,
                  min_valid_fraction: float = 0.1, min_disparity: float = 1.0,
                  max_range: float = math.inf) -> BoxRange:
        """Range to the landmark in ``box = (x_min, y_min, x_max, y_max)``.

        The range is the median depth of the box's valid pixels.  No range
        (``ok=False`` with a ``reason``) when fewer than
        ``max(min_valid_pixels, min_valid_fraction·n_pixels)`` pixels are
        valid ("too few valid pixels"), when ``d + doffs`` at the median depth
        is below ``min_disparity`` pixels or the depth exceeds ``max_range``
        ("beyond resolvable range"), or when the box is outside the image.
        ``sigma_d`` is the disparity noise in pixels.
        """
        b = as_array("box", box, (4,))
        o = declared(_core.BoxRangeOptions, sigma_d=sigma_d, min_valid_pixels=min_valid_pixels,
                     min_valid_fraction=min_valid_fraction, min_disparity=min_disparity, max_range=max_range)
        r = self._m.box_range(self._disparity(disparity), *b, o)
        return BoxRange(ok=r.ok, range=r.range if r.ok else math.nan, sigma=r.sigma if r.ok else math.nan,
                        disparity=r.disparity, n_valid=r.n_valid, n_pixels=r.n_pixels,
                        point=np.array(r.point), reason=r.reason)

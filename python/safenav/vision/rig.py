"""The stereo rig of the camera loop: an ideal, already rectified pair
(:class:`StereoRig`: pinhole, same intrinsics ``K`` for both cameras,
baseline ``B`` along the camera x axis, camera height ``h``, a fixed pitch)
and the world → camera rotation (:func:`camera_rotation`).

Conventions (those of :mod:`safenav.vision.render`).  World: x east, y north,
z up; the heading θ is counter-clockwise from +x.  Camera: x right, y down,
z forward.  **The vehicle's position is the left camera's centre**, at height
``h``; the right camera sits ``B`` to its right.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["StereoRig", "camera_rotation", "as_pose", "check_positive"]


def check_positive(name, v, *, allow_zero=False):
    """``v`` as a float, if finite and > 0 (>= 0 with ``allow_zero``); else ``ValueError`` naming ``name``."""
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v) \
            or v < 0 or (v == 0 and not allow_zero):
        raise ValueError(f"{name} = {v!r}: must be a finite number {'>= 0' if allow_zero else '> 0'}")
    return float(v)


@dataclass(frozen=True)
class StereoRig:
    """An ideal rectified stereo rig on the vehicle.

    The defaults scale the scenario camera ([SafeNav-ext §V-A2]: 2560×1440 px,
    f = 1400 px, i.e. an 85° horizontal field of view, baseline 0.3 m) to
    640×480 px: f = 350 px.
    """

    width: int = 640                  #: image width [px]
    height: int = 480                 #: image height [px]
    focal_length_px: float = 350.0    #: f [px] (both axes)
    baseline_m: float = 0.3           #: B [m]
    camera_height_m: float = 1.5      #: h, camera centres above the ground [m]
    pitch_rad: float = 0.0            #: camera pitch, positive looks up [rad]
    max_range_m: float = 30.0         #: landmarks farther than this (3D) are not drawn [m]
    near_m: float = 0.2               #: near clipping depth [m]

    def __post_init__(self):
        for n in ("width", "height"):
            v = getattr(self, n)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 16:
                raise ValueError(f"{n} = {v!r}: must be an integer >= 16 [px]")
            object.__setattr__(self, n, int(v))
        for n in ("focal_length_px", "baseline_m", "camera_height_m", "max_range_m", "near_m"):
            object.__setattr__(self, n, check_positive(n, getattr(self, n)))
        p = self.pitch_rad
        if isinstance(p, bool) or not isinstance(p, (int, float, np.integer, np.floating)) or not abs(p) < 0.5:
            raise ValueError(f"pitch_rad = {p!r}: must be a finite angle with |pitch| < 0.5 rad")
        object.__setattr__(self, "pitch_rad", float(p))

    @classmethod
    def from_camera(cls, camera, width: int = 640, height: int | None = 480, *, camera_height_m: float = 1.5,
                    max_range_m: float = 30.0, pitch_rad: float = 0.0) -> "StereoRig":
        """The scenario's :class:`~safenav.scenario.CameraParams` scaled to ``width`` px (same field of view)."""
        s = width / camera.image_width_px
        h = int(round(camera.image_height_px * s)) if height is None else height
        return cls(width, h, camera.focal_length_px * s, camera.baseline_m, camera_height_m, pitch_rad,
                   max_range_m)

    @property
    def cx(self) -> float:
        return (self.width - 1) / 2.0

    @property
    def cy(self) -> float:
        return (self.height - 1) / 2.0

    @property
    def K(self) -> np.ndarray:
        f = self.focal_length_px
        return np.array([[f, 0.0, self.cx], [0.0, f, self.cy], [0.0, 0.0, 1.0]])

    @property
    def horizontal_fov_rad(self) -> float:
        return 2.0 * math.atan2(self.width / 2.0, self.focal_length_px)

    @property
    def fB(self) -> float:
        """f·B [px·m]: disparity d = f·B / Z."""
        return self.focal_length_px * self.baseline_m

    def calibration(self):
        """The matching :class:`safenav.vision.calibration.StereoCalibration` (no distortion, R = I,
        T = (−B, 0, 0))."""
        from .stereo import StereoCalibration
        K = self.K
        return StereoCalibration(K, np.zeros(5), K, np.zeros(5), np.eye(3), np.array([-self.baseline_m, 0.0, 0.0]),
                                 (self.width, self.height))

    def rectified_camera(self):
        """The rig as a :class:`safenav.vision.stereo.RectifiedCamera` (``Z = f·B/d``, doffs = 0): no rectification."""
        from .stereo import RectifiedCamera
        return RectifiedCamera(self.focal_length_px, self.cx, self.cy, self.baseline_m, 0.0, self.width,
                               self.height)

    def camera_centers(self, pose) -> tuple[np.ndarray, np.ndarray]:
        """World centres of the left and right cameras at ``pose = (x, y, θ)``."""
        x, y, th = as_pose(pose)
        left = np.array([x, y, self.camera_height_m])
        right = left + self.baseline_m * np.array([math.sin(th), -math.cos(th), 0.0])
        return left, right


def camera_rotation(theta: float, pitch: float = 0.0) -> np.ndarray:
    """World → camera rotation (rows: camera x = right, y = down, z = forward) for heading θ and pitch."""
    c, s, cp, sp = math.cos(theta), math.sin(theta), math.cos(pitch), math.sin(pitch)
    fwd = np.array([c * cp, s * cp, sp])
    right = np.array([s, -c, 0.0])
    down = np.cross(fwd, right)
    return np.stack([right, down, fwd])


def as_pose(pose) -> tuple[float, float, float]:
    """``pose`` as ``(x, y, θ)`` floats: a pose or a state ``(x, y, v, θ)``; ``ValueError`` naming it if not."""
    try:
        p = np.asarray(pose, dtype=float).ravel()
    except (TypeError, ValueError):
        raise ValueError(f"pose = {pose!r}: must be (x, y, theta)") from None
    if p.size not in (3, 4):
        raise ValueError(f"pose = {pose!r}: must be (x, y, theta) or a state (x, y, v, theta)")
    if p.size == 4:
        p = p[[0, 1, 3]]
    if not np.isfinite(p).all():
        raise ValueError(f"pose = {tuple(p)}: must be finite")
    return float(p[0]), float(p[1]), float(p[2])

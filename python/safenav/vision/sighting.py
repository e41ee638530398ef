"""What the LanBLoc pipeline makes of one frame [SafeNav §IV-A]: a
:class:`LandmarkSighting` per recognised landmark (its stereo range and
bearing) and the frame's :class:`LanBLocResult` (status, fix, covariance).

A *sighting* is the vision front end's account of one landmark in one stereo
pair (detection box, depth, slant and horizontal range, bearing).  It is not
the core's ``LandmarkObservation`` (``safenav/localizer.hpp``), the
timestamped range/bearing input of :meth:`safenav.guidance.Localizer.observe`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .detect import Detection
from .localization import LocalizationResult

__all__ = ["LandmarkSighting", "LanBLocResult", "STATUSES", "MISASSOCIATED", "OUTLIER", "REPEATED"]

#: Result statuses, in the order the pipeline can stop.
STATUSES = ("ok", "no_landmarks", "too_few_ranges", "degenerate", "did_not_converge")

#: Landmark fault flags of :attr:`LandmarkSighting.faults` (the core's ``LandmarkFaults`` flags).
MISASSOCIATED = 2
OUTLIER = 4
#: the reason's end for a range whose landmark another range of its frame names too (the core's words)
REPEATED = "seen twice in one frame: neither range is used"


@dataclass(frozen=True)
class LandmarkSighting:
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
    """The outcome of one LanBLoc frame (see :mod:`safenav.vision.lanbloc`)."""

    status: str
    reason: str
    position: np.ndarray                      #: (2,) [m]; NaN unless ok
    covariance: np.ndarray                    #: (2, 2) [m²]; NaN unless ok
    gdop: float
    observations: tuple[LandmarkSighting, ...]
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
    def repeated(self) -> tuple[LandmarkSighting, ...]:
        """The ranges left unused because another range of the frame names
        their landmark too (``LandmarkRanging.drop_repeated``)."""
        return tuple(o for o in self.observations if not o.ok and o.reason.endswith(REPEATED))

    @property
    def rejected(self) -> tuple[LandmarkSighting, ...]:
        """The ranges that the trilateration's outlier test rejected (empty unless ok)."""
        if not self.ok:
            return ()
        ranged = [o for o in self.observations if o.ok]
        return tuple(o for o, inlier in zip(ranged, self.localization.inliers) if not inlier)

    @property
    def faults_in_fix(self) -> tuple[LandmarkSighting, ...]:
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

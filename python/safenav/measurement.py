"""Measurement models ``z = h(x) + v``, ``v ~ N(0, R)`` (SafeNav eq. 10).

Each model gives ``predict`` (h), ``jacobian`` (H = ∂h/∂x) and an
angle-aware ``residual`` (angles wrapped to (−π, π]):

* ``position``      — ``(x, y)``, what LanBLoc outputs;
* ``range``         — ``‖p − ℓ_i‖`` to known landmarks;
* ``bearing``       — ``atan2(ℓ_y − y, ℓ_x − x) − θ``, relative to the heading;
* ``range_bearing`` — ``(r_1, b_1, r_2, b_2, …)``;
* ``speed_heading`` — IMU ``(v, θ)``.

The noise covariance R is kept block by block (one 1×1 block per row for the
range/bearing models built here), so a model over n landmarks costs O(n);
``R`` gives the dense matrix on request.
"""

from __future__ import annotations

import numpy as np

from . import _core
from .validation import as_array

MeasurementKind = _core.MeasurementKind
#: The error model of a position source (bias, walk, dropouts, white noise,
#: outliers; ``safenav/measurement.hpp``): ``PositionNoise.named(name)``.
PositionNoise = _core.PositionNoise

#: Default LanBLoc noise: the paper's RMSE in X and Y (the core's "lanbloc" profile).
LANBLOC_STD = tuple(float(s) for s in PositionNoise.named("lanbloc").std)


def _landmarks(landmarks) -> np.ndarray:
    lm = as_array("landmarks", landmarks, (None, 2))
    if lm.shape[0] == 0:
        raise ValueError("landmarks must hold at least one landmark, got 0")
    return lm


class MeasurementModel(_core.MeasurementModel):
    """A measurement model with Gaussian noise. Build one with the class methods."""

    @classmethod
    def position(cls, R=None) -> "MeasurementModel":
        R = np.diag(np.square(LANBLOC_STD)) if R is None else as_array("R", R, (2, 2))
        return cls(MeasurementKind.POSITION, R)

    @classmethod
    def speed_heading(cls, R) -> "MeasurementModel":
        return cls(MeasurementKind.SPEED_HEADING, as_array("R", R, (2, 2)))

    @classmethod
    def range(cls, landmarks, sigma: float) -> "MeasurementModel":
        """Ranges to ``landmarks`` with independent noise ``sigma`` per row (stored per row)."""
        lm = _landmarks(landmarks)
        return cls(MeasurementKind.RANGE, sigmas=np.full(len(lm), _positive("sigma", sigma)), landmarks=lm)

    @classmethod
    def bearing(cls, landmarks, sigma: float) -> "MeasurementModel":
        """Relative bearings to ``landmarks`` with independent noise ``sigma`` per row."""
        lm = _landmarks(landmarks)
        return cls(MeasurementKind.BEARING, sigmas=np.full(len(lm), _positive("sigma", sigma)), landmarks=lm)

    @classmethod
    def range_bearing(cls, landmarks, sigma_range: float, sigma_bearing: float) -> "MeasurementModel":
        """``(r_1, b_1, r_2, b_2, …)`` with independent noise per row."""
        lm = _landmarks(landmarks)
        sig = np.tile([_positive("sigma_range", sigma_range), _positive("sigma_bearing", sigma_bearing)], len(lm))
        return cls(MeasurementKind.RANGE_BEARING, sigmas=sig, landmarks=lm)

    def predict(self, x) -> np.ndarray:
        return super().predict(as_array("x", x, (4,)))

    def jacobian(self, x) -> np.ndarray:
        return super().jacobian(as_array("x", x, (4,)))

    def residual(self, z, zhat) -> np.ndarray:
        return super().residual(as_array("z", z, (self.dim,)), as_array("zhat", zhat, (self.dim,)))


def _positive(name, value) -> float:
    """``value`` as a float > 0, or a ValueError/TypeError that names it."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a number, got {type(value).__name__}")
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} = {value!r} must be > 0 and finite")
    return float(value)

"""Measurement models ``z = h(x) + v``, ``v ~ N(0, R)`` (SafeNav eq. 10).

Each model gives ``predict`` (h), ``jacobian`` (H = ∂h/∂x) and an
angle-aware ``residual`` (angles wrapped to (−π, π]):

* ``position``      — ``(x, y)``, what LanBLoc outputs;
* ``range``         — ``‖p − ℓ_i‖`` to known landmarks;
* ``bearing``       — ``atan2(ℓ_y − y, ℓ_x − x) − θ``, relative to the heading;
* ``range_bearing`` — ``(r_1, b_1, r_2, b_2, …)``;
* ``speed_heading`` — IMU ``(v, θ)``.
"""

from __future__ import annotations

import numpy as np

from . import _core
from ._checks import as_array

MeasurementKind = _core.MeasurementKind

# Default LanBLoc noise: the paper's RMSE 0.0142 m in X and 0.039 m in Y.
LANBLOC_STD = (0.0142, 0.039)


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
        lm = _landmarks(landmarks)
        return cls(MeasurementKind.RANGE, np.eye(len(lm)) * float(sigma) ** 2, lm) if sigma > 0 else _bad("sigma", sigma)

    @classmethod
    def bearing(cls, landmarks, sigma: float) -> "MeasurementModel":
        lm = _landmarks(landmarks)
        return cls(MeasurementKind.BEARING, np.eye(len(lm)) * float(sigma) ** 2, lm) if sigma > 0 else _bad("sigma", sigma)

    @classmethod
    def range_bearing(cls, landmarks, sigma_range: float, sigma_bearing: float) -> "MeasurementModel":
        lm = _landmarks(landmarks)
        if not sigma_range > 0:
            _bad("sigma_range", sigma_range)
        if not sigma_bearing > 0:
            _bad("sigma_bearing", sigma_bearing)
        sig = np.tile([float(sigma_range), float(sigma_bearing)], len(lm))
        return cls(MeasurementKind.RANGE_BEARING, np.diag(sig**2), lm)

    def predict(self, x) -> np.ndarray:
        return super().predict(as_array("x", x, (4,)))

    def jacobian(self, x) -> np.ndarray:
        return super().jacobian(as_array("x", x, (4,)))

    def residual(self, z, zhat) -> np.ndarray:
        return super().residual(as_array("z", z, (self.dim,)), as_array("zhat", zhat, (self.dim,)))


def _bad(name, value):
    raise ValueError(f"{name} = {value!r} must be > 0")

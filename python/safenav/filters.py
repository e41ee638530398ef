"""State estimation on the BMM: EKF, particle filter, extended information filter.

* :class:`Ekf` — SafeNav eqs. 10–14.  Prediction ``P = F P Fᵀ + Q`` (eq. 11)
  with ``Q = G Σ_ε Gᵀ``; update with an angle-aware residual (eq. 12), gain
  (eq. 13) and the Joseph form of eq. 14 ``P = (I−KH)P(I−KH)ᵀ + KRKᵀ`` (the
  paper prints the short form ``(I−KH)P``, which loses symmetry and positive
  definiteness in floating point).  Optional NIS gate.
* :class:`ParticleFilter` — the LanBLoc-BMM PF: particles follow the noisy
  BMM (eqs. 6–9), weights kept as log-weights, systematic resampling when
  ESS < threshold·N, weighted mean (circular for θ) and covariance.
* :class:`InformationFilter` — the extended information filter of the
  landmark placement paper [Placement §III-A], with any measurement model.

Per-step calls (``predict``/``update``) are for embedding; for whole
trajectories use :func:`filter_trajectory`, one C++ call that releases the GIL.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _core
from .validation import as_array, as_positive_int, as_seed
from .measurement import LANBLOC_STD
from .motion import BmmParams

FilterType = _core.FilterType
UpdateResult = _core.UpdateResult

_TYPES = {"ekf": FilterType.EKF, "pf": FilterType.PF, "eif": FilterType.EIF}


def _prior(x0, P0):
    return as_array("x0", x0, (4,)), as_array("P0", P0, (4, 4))


class _StepApi:
    def predict(self, u) -> None:
        """Predict one step with control ``u = (desired speed, heading change)``."""
        super().predict(as_array("u", u, (2,)))

    def update(self, model, z) -> UpdateResult:
        """Update with measurement ``z`` of ``model`` (a :class:`MeasurementModel`)."""
        return super().update(model, as_array("z", z, (model.dim,)))


class Ekf(_StepApi, _core.Ekf):
    """Extended Kalman filter on the BMM (SafeNav eqs. 10–14, Joseph form)."""

    def __init__(self, params: BmmParams, x0, P0, *, gate: float = 0.0):
        super().__init__(params, *_prior(x0, P0))
        self.gate = gate

    def set_state(self, x, P) -> None:
        """Reset the estimate to ``x`` (4,) with covariance ``P`` (4, 4)."""
        super().set_state(as_array("x", x, (4,)), as_array("P", P, (4, 4)))


class ParticleFilter(_StepApi, _core.ParticleFilter):
    """Regularised particle filter on the BMM: log-weights and systematic
    resampling when the ESS drops below ``resample_threshold`` * N; an update
    that would drop it there is instead the kernel update of the adaptive
    Gaussian mixture filter (Gaussian kernels of Musso et al. 2001's optimal
    bandwidth times ``bandwidth_scale``; 0 gives the plain SIR filter).  ``P``
    is the weighted covariance floored by ``covariance_floor`` (the kernel
    covariance of the unweighted cloud); ``sample_covariance`` is the
    unfloored one.  The equations and references are in the C++ header
    ``safenav/filters.hpp``."""

    def __init__(self, params: BmmParams, x0, P0, *, n_particles: int = 1000, seed: int = 0,
                 resample_threshold: float = 0.5, bandwidth_scale: float = 1.0):
        super().__init__(params, *_prior(x0, P0), as_positive_int("n_particles", n_particles),
                         as_seed("seed", seed), float(resample_threshold), float(bandwidth_scale))


class InformationFilter(_StepApi, _core.InformationFilter):
    """Extended information filter (information form) on the BMM."""

    def __init__(self, params: BmmParams, x0, P0):
        super().__init__(params, *_prior(x0, P0))


@dataclass(frozen=True)
class FilterResult:
    """Result of :func:`filter_trajectory`; row 0 is the prior."""

    states: np.ndarray       #: (N+1, 4) estimates (x, y, v, θ)
    covariances: np.ndarray  #: (N+1, 4, 4)
    nis: np.ndarray          #: (N,) NIS of each step's accepted updates (NaN if none)
    nis_dof: np.ndarray      #: (N,) chi-square degrees of freedom of ``nis``
    n_updates: int
    n_rejected: int
    n_resampled: int
    n_gaps: int              #: steps with no measurement (prediction only)


def filter_trajectory(controls, x0, P0, *, params: BmmParams | None = None, filter: str = "ekf",
                      position=None, position_cov=None, speed_heading=None, speed_heading_cov=None,
                      ranges=None, range_std: float = 1.0, bearings=None, bearing_std: float = 0.05,
                      landmarks=None, n_particles: int = 1000, seed: int = 0,
                      resample_threshold: float = 0.5, bandwidth_scale: float = 1.0,
                      gate: float = 0.0) -> FilterResult:
    """Filter a whole trajectory in one call.

    ``controls`` is ``(N, 2)``.  Each measurement stream is optional and has
    one row per step, measured after that step's prediction: ``position``
    ``(N, 2)`` and ``speed_heading`` ``(N, 2)`` use a full NaN row for a gap;
    ``ranges``/``bearings`` ``(N, K)`` to ``landmarks`` ``(K, 2)`` use NaN for
    a landmark not seen.  ``filter`` is ``"ekf"``, ``"pf"`` or ``"eif"``.
    """
    if filter not in _TYPES:
        raise ValueError(f"filter must be one of {sorted(_TYPES)}, got {filter!r}")
    u = as_array("controls", controls, (None, 2))
    n = u.shape[0]
    x0, P0 = _prior(x0, P0)
    st = _core.MeasurementStream()
    if position is not None:
        st.position = as_array("position", position, (n, 2), allow_nan=True)
        st.position_cov = (np.diag(np.square(LANBLOC_STD)) if position_cov is None
                           else as_array("position_cov", position_cov, (2, 2)))
    if speed_heading is not None:
        if speed_heading_cov is None:
            raise ValueError("speed_heading_cov is required with speed_heading")
        st.speed_heading = as_array("speed_heading", speed_heading, (n, 2), allow_nan=True)
        st.speed_heading_cov = as_array("speed_heading_cov", speed_heading_cov, (2, 2))
    if ranges is not None or bearings is not None:
        if landmarks is None:
            raise ValueError("landmarks (K, 2) are required with ranges or bearings")
        lm = as_array("landmarks", landmarks, (None, 2))
        st.landmarks = lm
        if ranges is not None:
            st.ranges = as_array("ranges", ranges, (n, lm.shape[0]), allow_nan=True)
            st.range_std = float(range_std)
        if bearings is not None:
            st.bearings = as_array("bearings", bearings, (n, lm.shape[0]), allow_nan=True)
            st.bearing_std = float(bearing_std)
    for name, v in (("range_std", range_std), ("bearing_std", bearing_std)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} = {v!r} must be finite and > 0")
    opt = _core.FilterOptions()
    opt.type = _TYPES[filter]
    opt.n_particles = as_positive_int("n_particles", n_particles)
    opt.seed = as_seed("seed", seed)
    opt.resample_threshold = float(resample_threshold)
    opt.bandwidth_scale = float(bandwidth_scale)
    opt.gate_probability = float(gate)
    run = _core.run_filter(params if params is not None else BmmParams(), opt, x0, P0, u, st)
    return FilterResult(
        states=run.states, covariances=run.covariances.reshape(-1, 4, 4), nis=run.nis, nis_dof=run.nis_dof,
        n_updates=run.n_updates, n_rejected=run.n_rejected, n_resampled=run.n_resampled, n_gaps=run.n_gaps)

"""Trajectory metrics of [SafeNav §V-B] and filter consistency statistics.

* ADE [SafeNav-ext eq. 21] — mean point-wise distance; trajectories must have equal length.
* FDE [SafeNav-ext eq. 22] — distance between final points; lengths may differ.
* Percent path-length error [SafeNav-ext eq. 23] — lengths may differ.
* WRS [SafeNav eq. 18] and AWRS [SafeNav-ext eq. 20] — risk of deviating from a central path.
  The buffer of half-width ``d_max`` is cut into equal zones per side with
  weights ``w_j`` (2, 4, 6, 8); in zone j, ``WRS = d·(d/w_j)``; at or beyond
  ``d_max``, ``WRS = d_max·(d_max/w_max)``.  This is the formula as the paper
  prints it.  Note that it *falls* at each zone border (d²/w_j → d²/w_{j+1}),
  so a point just inside zone 2 scores lower than one just inside zone 1's
  outer edge; we keep it as written and call it the paper's WRS.
* NEES and NIS with their two-sided chi-square acceptance intervals.
* :class:`TrajectoryScore` — the one accumulator of a trajectory's scores
  against the truth (ADE, FDE, RMSE, NEES, share outside 3σ), fed pose by pose;
  the simulator's trials and :func:`safenav.replay.score` both use it.

Distances do not overflow in their squares (``std::hypot``; coordinates beyond
2^500 are scaled by a power of two, which is exact), so any distance that is
representable comes back finite; one beyond 1.8e308 raises ``ValueError``
naming the points.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy import stats

from . import _core
from .validation import as_array, as_positive_int

RiskZones = _core.RiskZones
TrajectoryScore = _core.TrajectoryScore


def _pts(name, p):
    return as_array(name, p, (None, 2))


def ade(estimate, truth) -> float:
    """Average displacement error (ext eq. 21)."""
    return _core.ade(_pts("estimate", estimate), _pts("truth", truth))


def fde(estimate, truth) -> float:
    """Final displacement error (ext eq. 22)."""
    return _core.fde(_pts("estimate", estimate), _pts("truth", truth))


def path_length(path) -> float:
    return _core.path_length(_pts("path", path))


def path_length_error_percent(estimate, truth) -> float:
    """|L_est − L_true| / L_true × 100 (ext eq. 23)."""
    return _core.path_length_error_percent(_pts("estimate", estimate), _pts("truth", truth))


def distance_to_path(points, path) -> np.ndarray:
    """Deviation d_i of each point from the nearest point of the central path (eq. 17)."""
    return _core.distance_to_path(_pts("points", points), _pts("path", path))


def wrs(points, path, zones: RiskZones | None = None) -> np.ndarray:
    """Weighted risk score of each point (eq. 18)."""
    return _core.wrs(_pts("points", points), _pts("path", path), zones or RiskZones())


def wrs_of_deviation(deviation, zones: RiskZones | None = None) -> np.ndarray:
    """Eq. 18 applied to deviations directly."""
    d = as_array("deviation", np.atleast_1d(deviation), (None,))
    return _core.wrs_deviation(d, zones or RiskZones())


def awrs(points, path, zones: RiskZones | None = None) -> float:
    """Average weighted risk score (ext eq. 20)."""
    return _core.awrs(_pts("points", points), _pts("path", path), zones or RiskZones())


def nees(estimates, truth, covariances, *, angle_index: int | None = 3) -> np.ndarray:
    """Normalised estimation error squared ``eᵀ P⁻¹ e`` per time step.

    ``estimates``/``truth`` are ``(N, n)``, ``covariances`` ``(N, n, n)``; the
    error at ``angle_index`` is wrapped (``None`` for no angle)."""
    est = as_array("estimates", estimates, (None, None))
    n = est.shape[1]
    tru = as_array("truth", truth, est.shape)
    cov = as_array("covariances", covariances, (est.shape[0], n, n))
    return _core.nees(est, tru, cov.reshape(est.shape[0], n * n), -1 if angle_index is None else angle_index)


#: Largest dof·n_runs that chi2_interval accepts: far beyond any NEES test
#: (4 states × 10⁴ runs = 4·10⁴), and scipy's quantile stays fast below it.
MAX_CHI2_DOF = 10**9


def chi2_interval(dof: int, n_runs: int = 1, probability: float = 0.95) -> tuple[float, float]:
    """Two-sided acceptance interval for the average of ``n_runs`` chi-square(dof) values.

    For NEES averaged over M Monte Carlo runs: M·ANEES ~ χ²(M·n) (Bar-Shalom, Li
    & Kirubarajan, 2001, section 5.4).  ``dof`` and ``n_runs`` are positive
    integers with ``dof·n_runs <= MAX_CHI2_DOF``; ``probability`` is in (0, 1)."""
    dof, n_runs = as_positive_int("dof", dof), as_positive_int("n_runs", n_runs)
    if dof * n_runs > MAX_CHI2_DOF:
        raise ValueError(f"dof·n_runs = {dof}·{n_runs} exceeds {MAX_CHI2_DOF}")
    if isinstance(probability, bool) or not isinstance(probability, (int, float, np.integer, np.floating)):
        raise TypeError(f"probability must be a number, got {type(probability).__name__}")
    if not 0.0 < probability < 1.0:
        raise ValueError(f"probability = {probability!r} must be in (0, 1)")
    alpha = 1.0 - probability
    lo = stats.chi2.ppf(alpha / 2, dof * n_runs) / n_runs
    hi = stats.chi2.ppf(1 - alpha / 2, dof * n_runs) / n_runs
    return float(lo), float(hi)


@dataclass(frozen=True)
class TrajectoryMetrics:
    """The paper's accuracy and risk metrics for one estimated trajectory."""

    ade: float
    fde: float
    awrs: float
    path_length_error_percent: float

    def as_dict(self) -> dict:
        return asdict(self)


def evaluate(estimate, truth, path=None, zones: RiskZones | None = None) -> TrajectoryMetrics:
    """ADE, FDE, AWRS and % path-length error of ``estimate`` against ``truth``.

    AWRS is measured against ``path`` (the central safe path), by default the
    ground-truth trajectory, as in [SafeNav-ext §V-A3(iii)] (= [SafeNav-conf §V-A.2(iii)])."""
    est, tru = _pts("estimate", estimate), _pts("truth", truth)
    central = tru if path is None else _pts("path", path)
    return TrajectoryMetrics(ade=ade(est, tru), fde=fde(est, tru), awrs=awrs(est, central, zones),
                             path_length_error_percent=path_length_error_percent(est, tru))

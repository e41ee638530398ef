"""LanBLoc position fixes from landmark anchors [SafeNav-ext §IV-A].

LanBLoc "utilizes the recognized landmarks as anchor nodes for trilateration
... with further position optimization".  The paper gives no algorithm; ours
(C++/Eigen):

* :func:`trilaterate` — ranges ``r_i = ‖p − a_i‖ + v_i``, ``v_i ~ N(0, σ_i²)``:
  a linear least-squares start (unknowns ``x, y, s = ‖p‖²`` from
  ``2a_iᵀp − s = ‖a_i‖² − r_i²``), then weighted Gauss–Newton with
  Levenberg–Marquardt damping on ``Σ ((r_i − ‖p − a_i‖)/σ_i)²``.  The
  covariance is ``(Jᵀ W J)⁻¹`` (``W = diag(σ_i⁻²)``) at the solution; GDOP is
  ``sqrt(trace((GᵀG)⁻¹))`` with ``G`` the unit line-of-sight rows.
* The covariance where the cost is not quadratic (ours; the likelihood-based
  region of Bates & Watts 1988, ch. 6): along each principal axis of
  ``(Jᵀ W J)⁻¹`` the cost minimised over the other axis (its profile) must
  rise by ``χ²₂(profile_probability)`` (9.21 at 0.99) where the Gaussian's
  contour at that probability is.  Where it rises by less than that over
  1.1 — anchors nearly in line with the position, an anchor close to it, so
  that the cost's valley curves — the axis is widened until it does.  With
  three anchors nearly in line with the position, the nearest 1.2–2.2 m
  away and the others 11–22 m, the linear covariance put 10–32 % of the
  fixes outside its 99 % ellipse; the widened one 0.9–4.5 %.  Well-spread
  anchors keep ``(Jᵀ W J)⁻¹`` exactly.  ``profile_probability=0`` turns it
  off (docs/lanbloc.md).
* :func:`triangulate_bearings` — absolute bearings
  ``β_i = atan2(a_iy − y, a_ix − x) + v_i`` (relative bearings plus a known
  heading), linear start from the bearing lines, same refinement.
* Outliers (when there are more measurements than the minimal set: >= 4
  ranges, >= 3 bearings, and the full fit leaves a normalised residual above
  ``outlier_threshold``): every minimal set (3 ranges / 2 bearings; at most
  ``max_subsets``, else that many drawn with ``seed``) is solved, the one
  with the largest consensus (ties: lowest χ²) wins, and the fit is redone on
  its consensus until the inlier set is stable.  If another consensus set
  as large fits a position more than 3σ away within ``ambiguity_margin``
  in χ² (e.g. four ranges with one bad, where two triples each fit a
  point), the outliers cannot be told apart and the fix is ``degenerate``
  ("ambiguous outliers", naming both choices).
* Explicit failure instead of a wrong point: ``too_few`` (fewer than the
  minimal set), ``degenerate`` (collinear anchors, a second minimum such as
  the mirror image across the anchors' line that fits within
  ``ambiguity_margin`` in χ², GDOP above ``max_gdop``, parallel bearing lines,
  a bearing pointing away from its anchor) and ``did_not_converge``.
* :func:`horizontal_range` — slant range to a landmark at a known height →
  horizontal range for 2D trilateration (landmarks and cameras have heights).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _core
from ..validation import as_array, declared

LocalizationStatus = _core.LocalizationStatus

__all__ = ["LocalizationResult", "LocalizationStatus", "trilaterate", "triangulate_bearings", "horizontal_range"]


@dataclass(frozen=True)
class LocalizationResult:
    """A position fix and its uncertainty (NaN unless ``status == "ok"``)."""

    status: str               #: "ok", "too_few", "degenerate" or "did_not_converge"
    position: np.ndarray      #: (2,)
    covariance: np.ndarray    #: (2, 2) (Jᵀ W J)⁻¹ of the weighted normal equations, widened to the cost's profile
    gdop: float               #: geometric dilution of precision
    chi2: float               #: Σ (residual/σ)² over the inliers
    inliers: np.ndarray       #: (n,) bool
    iterations: int
    reason: str               #: why it failed; when ok, "" or a note (outliers rejected)
    #: ranges: |χ²| between the solution and its mirror minimum, inf where none;
    #: the fix is refused as ambiguous where it is at most ``ambiguity_margin``
    ambiguity_gap: float = float("inf")

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def _options(outlier_threshold, reject_outliers, max_iterations, tolerance, max_gdop, ambiguity_margin,
             min_crossing_angle, max_subsets, seed, profile_probability) -> _core.LocalizationOptions:
    o = declared(_core.LocalizationOptions, outlier_threshold=outlier_threshold, reject_outliers=reject_outliers,
                 max_iterations=max_iterations, tolerance=tolerance, max_gdop=max_gdop,
                 ambiguity_margin=ambiguity_margin, min_crossing_angle=min_crossing_angle, max_subsets=max_subsets,
                 profile_probability=profile_probability)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**64:
        raise ValueError(f"seed must be an integer in [0, 2**64), got {seed!r}")
    o.seed = int(seed)
    o.validate()
    return o


def _inputs(anchors, z, zname, sigmas):
    a = as_array("anchors", anchors, (None, 2))
    zz = as_array(zname, z, (a.shape[0],))
    s = np.asarray(sigmas, dtype=np.float64) if not np.isscalar(sigmas) else None
    if s is None or s.ndim == 0:
        s = np.full(a.shape[0], float(sigmas))
    s = as_array("sigmas", s, (a.shape[0],))
    return a, zz, s


def _result(r) -> LocalizationResult:
    return LocalizationResult(status=str(r.status), position=np.array(r.position), covariance=np.array(r.covariance),
                              gdop=float(r.gdop), chi2=float(r.chi2), inliers=np.array(r.inliers, dtype=bool),
                              iterations=int(r.iterations), reason=r.reason,
                              ambiguity_gap=float(r.ambiguity_gap))


def trilaterate(anchors, ranges, sigmas=1.0, *, outlier_threshold: float = 3.0, reject_outliers: bool = True,
                max_iterations: int = 100, tolerance: float = 1e-12, max_gdop: float = 100.0,
                ambiguity_margin: float = 9.0, max_subsets: int = 500, seed: int = 0,
                profile_probability: float = 0.99) -> LocalizationResult:
    """Position from ranges to known anchors.

    ``anchors`` ``(n, 2)``, ``ranges`` ``(n,)`` (>= 0), ``sigmas`` ``(n,)`` or
    a scalar (the ranges' standard deviations).  ``outlier_threshold`` is in
    units of σ.  See the module docstring for the method and the statuses.
    Malformed input (shapes, NaN, negative ranges, σ <= 0) raises ``ValueError``.
    """
    a, r, s = _inputs(anchors, ranges, "ranges", sigmas)
    o = _options(outlier_threshold, reject_outliers, max_iterations, tolerance, max_gdop, ambiguity_margin,
                 1e-2, max_subsets, seed, profile_probability)
    return _result(_core.trilaterate(a, r, s, o))


def triangulate_bearings(anchors, bearings, sigmas=0.01, *, heading: float | None = None,
                         outlier_threshold: float = 3.0, reject_outliers: bool = True, max_iterations: int = 100,
                         tolerance: float = 1e-12, max_gdop: float = 100.0, min_crossing_angle: float = 1e-2,
                         max_subsets: int = 500, seed: int = 0, profile_probability: float = 0.99
                         ) -> LocalizationResult:
    """Position from bearings to known anchors (>= 2).

    ``bearings`` are absolute (world frame, rad, counter-clockwise from +x,
    from the vehicle towards each anchor); with ``heading`` given they are
    relative to it and ``heading`` is added.  ``sigmas`` in rad.  For bearings
    GDOP is ``sqrt(trace((GᵀG)⁻¹))`` divided by the mean range (``G`` the
    bearing gradients), i.e. position error per range per radian.
    """
    a, b, s = _inputs(anchors, bearings, "bearings", sigmas)
    if heading is not None:
        if not math.isfinite(heading):
            raise ValueError(f"heading = {heading!r} is not finite")
        b = b + float(heading)
    o = _options(outlier_threshold, reject_outliers, max_iterations, tolerance, max_gdop, 9.0,
                 min_crossing_angle, max_subsets, seed, profile_probability)
    return _result(_core.triangulate_bearings(a, b, s, o))


def horizontal_range(slant_range, landmark_height, camera_height=0.0, sigma=None):
    """Horizontal range ``sqrt(s² − Δh²)`` from a slant range ``s`` to a
    landmark point at ``landmark_height`` seen from ``camera_height``.

    Broadcasts over arrays.  With ``sigma`` (σ of the slant range) returns
    ``(range, sigma_range)`` with ``σ_h = σ·s/h`` (first order); a slant range
    shorter than ``|Δh|`` (possible with noise) gives range 0 and σ_h = σ.
    Non-finite or negative input raises ``ValueError``.
    """
    s = np.asarray(slant_range, dtype=np.float64)
    dh = np.asarray(landmark_height, dtype=np.float64) - np.asarray(camera_height, dtype=np.float64)
    for name, v in (("slant_range", s), ("height difference", dh)):
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{name} has non-finite values: {v!r}")
    if np.any(s < 0):
        raise ValueError(f"slant_range must be >= 0, got {s!r}")
    with np.errstate(over="ignore", invalid="ignore"):
        h = np.sqrt(np.maximum(s * s - dh * dh, 0.0))
    if not np.all(np.isfinite(h)):  # s² or Δh² overflowed: the same in units of s (no overflow)
        with np.errstate(divide="ignore", invalid="ignore"):
            q = np.where(s > 0, dh / np.where(s > 0, s, 1.0), np.inf)
            h = np.where(np.isfinite(h), h, s * np.sqrt(np.maximum(1.0 - np.minimum(q * q, 1.0), 0.0)))
    out = h if h.ndim else float(h)
    if sigma is None:
        return out
    sg = np.asarray(sigma, dtype=np.float64)
    if not np.all(np.isfinite(sg) & (sg > 0)):
        raise ValueError(f"sigma must be finite and > 0, got {sg!r}")
    with np.errstate(divide="ignore", invalid="ignore"):
        sh = np.where(h > 0, sg * s / np.where(h > 0, h, 1.0), sg)
    return out, (sh if sh.ndim else float(sh))

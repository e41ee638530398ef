// Private: argument and result checks shared by the filters in this folder.
#pragma once

#include <algorithm>
#include <cmath>

#include <string>

#include "safenav/filters.hpp"

namespace safenav {

/// Throws when the NIS yᵀS⁻¹y of an update overflows (a measurement ~1e308 from
/// the prediction): called before any state changes.
void check_nis(double nis, const char* filter, MeasurementKind kind);
/// Throws std::invalid_argument unless log det S is finite: an innovation
/// covariance that is not positive definite in double precision (a spread of
/// the particles, or a state, beyond ~1e150) makes the update meaningless.
void check_log_det_s(double log_det_s, const char* filter, MeasurementKind kind);
/// log det S = 2 Σ log L_ii from the Cholesky factor's diagonal: one log of
/// the product where that is a normal number (the EKF's hot path), else the sum of logs.
template <class Diagonal>
inline double log_det_from_cholesky(const Diagonal& d) {
  const double p = d.prod();
  return 2.0 * ((p > 1e-300 && p < 1e300) ? std::log(p) : d.array().log().sum());
}
/// Symmetric to rounding: no entry differs from its transpose by more than
/// 1e-9 of the matrix's largest entry.  (Relative to the matrix, not to the
/// entry: an off-diagonal that cancels to ~1e-11 of the diagonal, as a
/// trilaterated fix's can, carries the diagonal's rounding.)  The one rule of
/// every covariance check (check_covariance, check_cov2, GaussianNoise).
template <class M>
inline bool symmetric_to_rounding(const M& P) {
  const double scale = std::max(1e-300, P.cwiseAbs().maxCoeff());
  return (P - P.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * scale;
}
/// A 2×2 noise covariance: finite, symmetric, positive definite, checked
/// without allocating; the message starts with `what`.
void check_cov2(const Eigen::Matrix2d& R, const char* what);
/// Throws unless x0 is finite and P0 a valid covariance.
void check_prior(const State& x0, const StateCov& P0, const char* xname = "x0", const char* pname = "P0");

}  // namespace safenav

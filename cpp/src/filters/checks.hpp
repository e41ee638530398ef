// Private: argument and result checks shared by the filters in this folder.
#pragma once

#include <string>

#include "safenav/filters.hpp"

namespace safenav {

/// Throws when the NIS yᵀS⁻¹y of an update overflows (a measurement ~1e308 from
/// the prediction): called before any state changes.
void check_nis(double nis, const char* filter, MeasurementKind kind);
/// A 2×2 noise covariance: finite, symmetric, positive definite, checked
/// without allocating; the message starts with `what`.
void check_cov2(const Eigen::Matrix2d& R, const char* what);
/// Throws unless x0 is finite and P0 a valid covariance.
void check_prior(const State& x0, const StateCov& P0, const char* xname = "x0", const char* pname = "P0");

}  // namespace safenav

// Private: the localizer's start from ranges, the rigid-transform fit
// (safenav/localizer.hpp, "Initialization").
#pragma once

#include <vector>

#include <Eigen/Core>

namespace safenav::detail {

/// One buffered range: the motion integral's position (qx, qy) at its time,
/// the landmark (ax, ay), the range z and its σ s.
struct RangeObs {
  double qx, qy, ax, ay, z, s;
};

/// Fits the rigid transform th = (X, Y, φ) from the motion integral's frame to
/// the world to the ranges (ours, after ref.py's _init_from_data): minimises
/// Σ (z − (1+k₀)‖T(q) − a‖)²/s², Gauss–Newton from 16 headings × 5 positions,
/// residuals > 3σ dropped, refitted.  Returns false when no fit is found;
/// else th, the inlier range residual RMS and th's covariance C = (JᵀJ)⁻¹.
bool fit_transform(const std::vector<RangeObs>& obs, double k0, Eigen::Vector3d& th, double& rms,
                   Eigen::Matrix3d& C);

}  // namespace safenav::detail

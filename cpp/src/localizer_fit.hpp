// Private: the localizer's start from data, the rigid-transform fit
// (safenav/localizer.hpp, "Initialization").
#pragma once

#include <limits>
#include <vector>

#include <Eigen/Core>

namespace safenav::detail {

/// One buffered landmark observation: the motion integral's pose (qx, qy, qθ)
/// at its time, the landmark (ax, ay), the range (NaN: not measured) with its
/// σ and the bearing (NaN: not measured) with its σ.
struct FitObs {
  double qx, qy, qth, ax, ay;
  double range = std::numeric_limits<double>::quiet_NaN(), range_std = 1.0;
  double bearing = std::numeric_limits<double>::quiet_NaN(), bearing_std = 1.0;
};

/// One buffered heading measurement (IMU): the world heading θ with its σ at
/// a time when the motion integral's heading was qθ.
struct FitHeading {
  double qth, theta, std;
};

/// The fit of th = (X, Y, φ): the inlier residual RMS of the ranges [m] (NaN
/// without ranges), the normalised RMS √(Σe²/m) of all inlier rows, the
/// number of inlier rows and of bearing or heading rows among them, and th's
/// covariance C = (JᵀJ)⁻¹ in the normalised rows.
struct FitResult {
  Eigen::Vector3d th = Eigen::Vector3d::Zero();
  double range_rms = std::numeric_limits<double>::quiet_NaN();
  double normalised_rms = std::numeric_limits<double>::quiet_NaN();
  int rows = 0, angle_rows = 0;
  int all_rows = 0;  ///< inliers and outliers
  /// Another start reached a transform > 5σ away whose cost is within
  /// χ²₃(0.99) = 11.34 of the best: the data do not single out one pose.
  bool ambiguous = false;
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
};

/// Fits the rigid transform th = (X, Y, φ) from the motion integral's frame to
/// the world (a point q maps to T(q) = (X, Y) + R(φ)q, a heading qθ to qθ + φ)
/// to the ranges, bearings and headings (ours, after ref.py's
/// _init_from_data): minimises Σ e² over the normalised residuals
///   range    e = (z − h_r)/σ_r,  h_r = predict_range(T(q), k₀, 0)  [SafeNav eq. 10]
///   bearing  e = wrap(z − h_β)/σ_b, h_β = predict_bearing(T(q), qθ + φ)  [Placement §III-A]
///   heading  e = wrap(θ − qθ − φ)/σ
/// (the one landmark model, safenav/measurement.hpp), by Gauss–Newton from 16
/// headings × 5 positions (plus, with bearings or headings, the position that
/// the newest range+bearing gives at each heading, and the heading an IMU
/// gives); residuals > 3σ dropped, refitted.  Returns false when no fit is
/// found, JᵀJ is singular (degenerate geometry) or the fit is ambiguous.
bool fit_transform(const std::vector<FitObs>& obs, const std::vector<FitHeading>& headings, double k0,
                   FitResult& out);

}  // namespace safenav::detail

// safenav/trilateration.hpp — LanBLoc position fixes from landmark anchors
// ([SafeNav-ext §IV-A]: "recognized landmarks as anchor nodes for
// trilateration ... with further position optimization"; the LanBLoc paper
// itself is not among our sources, see docs/paper_map.md).
//
//  * trilateration from >= 3 ranges r_i = ‖p − a_i‖ + v_i, v_i ~ N(0, σ_i²):
//    linear least squares start, then weighted Gauss–Newton with
//    Levenberg–Marquardt damping; covariance (Jᵀ W J)⁻¹ of the normal
//    equations, widened where the cost's profile is flatter than its
//    quadratic model (profile_probability); GDOP; outlier rejection (exhaustive or sampled minimal sets,
//    then consensus refit) when >= 4 ranges;
//  * bearing triangulation from >= 2 absolute bearings
//    β_i = atan2(a_iy − y, a_ix − x) + v_i (same machinery).
//
// Geometry that does not determine the position (fewer anchors than needed,
// collinear anchors, a mirror solution that fits as well, parallel bearing
// lines) returns an explicit status instead of a point.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>
#include <Eigen/Core>

#include "safenav/types.hpp"

namespace safenav {

enum class LocalizationStatus {
  Ok,              ///< position and covariance are valid
  TooFew,          ///< fewer measurements (or inliers) than the minimal set
  Degenerate,      ///< the geometry does not determine the position
  DidNotConverge,  ///< the iteration did not converge
};

const char* to_string(LocalizationStatus status);

struct LocalizationOptions {
  /// A measurement is an outlier when |residual| / σ exceeds this.
  double outlier_threshold = 3.0;
  /// Whether to reject outliers (only when there are more measurements than
  /// the minimal set: >= 4 ranges, >= 3 bearings).
  bool reject_outliers = true;
  /// Gauss–Newton/LM iteration limit and relative step tolerance.
  int max_iterations = 100;
  double tolerance = 1e-12;
  /// GDOP above this is reported as degenerate geometry.
  double max_gdop = 100.0;
  /// A second (mirror) solution, or a second consensus set of outliers as
  /// large as the chosen one, whose weighted cost χ² is within this margin of
  /// the best one at a position more than 3σ away makes the fix ambiguous
  /// (degenerate).  0 keeps only exact ties ambiguous.
  double ambiguity_margin = 9.0;
  /// The covariance's probability contour (ours): along each principal axis
  /// of (Jᵀ W J)⁻¹ the cost minimised over the other axis (its profile) must
  /// rise by the χ²₂ quantile at this probability where the Gaussian's
  /// contour is; where it rises by less than that over 1.1 (a curved valley:
  /// anchors nearly in line with the position, an anchor close to it) that
  /// axis is widened until it does.  0 = the linear (Jᵀ W J)⁻¹ alone.
  double profile_probability = 0.99;
  /// Bearings: lines that cross at less than this angle (rad) are parallel.
  double min_crossing_angle = 1e-2;
  /// Minimal sets tried for outlier rejection: all of them when there are at
  /// most this many, otherwise this many drawn with `seed`.
  int max_subsets = 500;
  std::uint64_t seed = 0;

  void validate() const;
};

using Anchors = Points2;

struct LocalizationResult {
  LocalizationStatus status = LocalizationStatus::TooFew;
  Eigen::Vector2d position = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Constant(std::numeric_limits<double>::quiet_NaN());
  double gdop = std::numeric_limits<double>::quiet_NaN();
  double chi2 = std::numeric_limits<double>::quiet_NaN();  ///< Σ (r_i/σ_i)² over inliers
  Eigen::Array<bool, Eigen::Dynamic, 1> inliers;             ///< one per measurement
  int iterations = 0;
  /// Ranges: |χ²| between the solution and the second minimum (the
  /// reflection across the anchors' line), +inf where none was found.  The
  /// fix is refused as ambiguous where it is at most ambiguity_margin.
  double ambiguity_gap = std::numeric_limits<double>::infinity();
  std::string reason;  ///< why it failed; when ok, empty or a note (outliers rejected)

  bool ok() const { return status == LocalizationStatus::Ok; }
};

/// Trilateration from ranges to anchors (n×2), ranges (n) and their standard
/// deviations (n).  Throws std::invalid_argument on malformed input
/// (mismatched sizes, non-finite values, negative ranges, σ <= 0).
LocalizationResult trilaterate(const Eigen::Ref<const Anchors>& anchors, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                               const Eigen::Ref<const Eigen::VectorXd>& sigmas,
                               const LocalizationOptions& options = LocalizationOptions());

/// Triangulation from absolute bearings (world frame, rad, from the vehicle to
/// each anchor; add the known heading to relative bearings first).
/// GDOP for bearings is sqrt(trace((GᵀG)⁻¹)) / mean range with G_i the
/// bearing gradient, i.e. metres of position error per metre of range per
/// radian of bearing error.
LocalizationResult triangulate_bearings(const Eigen::Ref<const Anchors>& anchors,
                                        const Eigen::Ref<const Eigen::VectorXd>& bearings,
                                        const Eigen::Ref<const Eigen::VectorXd>& sigmas,
                                        const LocalizationOptions& options = LocalizationOptions());

/// Which of `ranges` share their landmark (`key(element)`) with another one
/// (ours): a landmark seen twice in one frame means that at least one of the
/// two sightings is another landmark's (a wrong match), and nothing in the
/// frame tells which, so neither may be used.  Two ranges to one anchor also
/// leave trilateration a mirror ambiguity that its fit cannot see.
template <class T, class Key>
std::vector<char> repeated_landmarks(const std::vector<T>& ranges, Key key) {
  const std::size_t n = ranges.size();
  std::vector<char> repeated(n, 0);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j)
      if (key(ranges[i]) == key(ranges[j])) repeated[i] = repeated[j] = 1;
  return repeated;
}

/// Removes the repeated_landmarks() of `ranges`, the others in their order;
/// returns how many were removed.
template <class T, class Key>
int drop_repeated_landmarks(std::vector<T>& ranges, Key key) {
  const std::vector<char> repeated = repeated_landmarks(ranges, key);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    if (repeated[i]) continue;
    if (kept != i) ranges[kept] = std::move(ranges[i]);
    ++kept;
  }
  const int removed = static_cast<int>(ranges.size() - kept);
  ranges.resize(kept);
  return removed;
}

}  // namespace safenav

// Private: the localizer's start from data, the rigid-transform fit
// (safenav/localizer.hpp, "Initialization").
#pragma once

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace safenav::detail {

/// A landmark observation kept for initialization from data (NaN: not measured).
struct BufferedObs {
  double t;
  int row;  // landmark row
  double range, range_std, bearing, bearing_std;
};

/// An IMU heading kept for initialization from data.
struct BufferedHeading {
  double t, theta, std;
};

/// The motion integral's pose (x, y, θ) at time t from `track` ((t, x, y, θ)
/// at each motion input, ≥ 2 rows), interpolated (the heading by its wrapped
/// change) and held at the ends.
Eigen::Vector3d odo_at(const std::vector<Eigen::Vector4d>& track, double t);

/// What the buffered data of the window hold, for the start rules.
struct StartWindow {
  double path = 0.0;                      ///< motion integral's path in the window [m]
  std::vector<int> ranged, beared, both;  ///< distinct landmark rows with a range, a bearing, both at once
  int headings = 0;                       ///< IMU headings
  bool angles = false;                    ///< any bearing or heading
  /// The most distinct landmarks seen in any window so far (for reason()).
  struct Most {
    int ranged = 0, beared = 0, both = 0;
  };
};

/// The window of the observations and headings at or before t_now.
StartWindow start_window(const std::vector<Eigen::Vector4d>& track, const std::vector<BufferedObs>& obs,
                         const std::vector<BufferedHeading>& headings, double t_now);

/// The start rules (localizer.hpp, "Initialization"): (a) range and bearing
/// of 2 landmarks; (b) a heading and range and bearing of 1; (c) bearings of
/// 3 landmarks, or of 2 after min_path of motion; (d) ranges of min_beacons
/// after min_path.  Updates `most` and writes what the window holds and what
/// a start needs into `why`.
bool start_rules(const StartWindow& w, double window, double min_path, int min_beacons, StartWindow::Most& most,
                 std::string& why);

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
/// headings × 5 positions around the landmarks' centroid (with a
/// range+bearing: × the centroid and the position that the newest
/// range+bearing gives at that heading; with an IMU heading, its φ too);
/// residuals > 3σ dropped, refitted.  Returns false when no fit is
/// found, JᵀJ is singular (degenerate geometry) or the fit is ambiguous.
bool fit_transform(const std::vector<FitObs>& obs, const std::vector<FitHeading>& headings, double k0,
                   FitResult& out);

}  // namespace safenav::detail

// safenav/metrics.hpp — trajectory metrics of [SafeNav §V-B]: ADE, FDE and
// percent path-length error [SafeNav-ext eqs. 21–23]; plus the filter
// consistency statistics NEES and NIS; and TrajectoryScore, the one
// accumulator of a trajectory's scores that the simulator (navigation.hpp)
// and the replay of logs (python/safenav/replay.py) feed pose by pose.  WRS [SafeNav eq. 18] and AWRS
// [SafeNav-ext eq. 20] measure a trajectory against the safe corridor:
// corridor.hpp.  Citations follow docs/paper_map.md.
#pragma once

#include <limits>
#include <vector>
#include <Eigen/Core>

#include "safenav/types.hpp"

namespace safenav {

/// Throws std::invalid_argument unless `points` has at least `min_rows` rows,
/// all finite; the message names `what` and the first bad point.
void check_points(const Eigen::Ref<const Points2>& points, const char* what, Eigen::Index min_rows = 1);

/// Power-of-two factor 2^−e that brings coordinates as large as `max_abs`
/// below 1 when they exceed 2^500, else 1.  Distances computed on points
/// scaled by it cannot overflow in their squares, and scaling by a power of
/// two is exact, so results in the ordinary range keep every bit.
double overflow_scale(double max_abs);

/// Mean of finite values without overflow in the sum (values near 1.8e308).
double finite_mean(const Eigen::Ref<const Eigen::VectorXd>& values);

/// ADE = (1/N) Σ ‖Ŷ_t − Y_t‖ [SafeNav-ext eq. 21].  Both trajectories must have the same
/// number of points (the definition pairs them by time).
double ade(const Eigen::Ref<const Points2>& estimate, const Eigen::Ref<const Points2>& truth);
/// FDE = ‖Ŷ_tf − Y_tf‖ [SafeNav-ext eq. 22].  Lengths may differ: only final points are used.
double fde(const Eigen::Ref<const Points2>& estimate, const Eigen::Ref<const Points2>& truth);
/// Polyline length Σ ‖p_{i+1} − p_i‖.
double path_length(const Eigen::Ref<const Points2>& path);
/// |L_est − L_true| / L_true × 100 [SafeNav-ext eq. 23].  Lengths may differ.
double path_length_error_percent(const Eigen::Ref<const Points2>& estimate,
                                 const Eigen::Ref<const Points2>& truth);

/// NEES_k = e_kᵀ P_k⁻¹ e_k per row, e = estimate ⊖ truth (θ residual wrapped
/// when `angle_index` ≥ 0).  errors: N×n, covariances: N×(n·n) row-major.
Eigen::VectorXd nees(const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>& estimates,
                     const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>& truth,
                     const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>& covariances,
                     int angle_index = -1);

/// Per-trial metrics [SafeNav-ext eqs. 20–23], each named by what it compares
/// against (as evo's results name their reference): `path_*` and `goal_*` take
/// the safe path as ground truth (see Navigator::run), `truth_*` the true
/// vehicle.
struct TrialMetrics {
  double path_ade = 0.0;        ///< ext eq. 21: mean distance of the estimate to the safe path (our reading)
  double goal_fde = 0.0;        ///< ext eq. 22: final estimate vs the destination
  double path_error_percent = 0.0;  ///< ext eq. 23: |L_est − L_path| / L_path · 100
  double awrs = 0.0;            ///< ext eq. 20: mean WRS of the estimated trajectory (eq. 18, about the safe path)
  double awrs_true = 0.0;       ///< mean WRS of the true trajectory
  double truth_ade = 0.0;       ///< mean ‖estimate − truth‖
  double truth_fde = 0.0;       ///< final ‖estimate − truth‖
  double max_deviation = 0.0;   ///< largest deviation of the true vehicle from the safe path [m]
  // Safety (ours): what the true vehicle met, and whether the filter knew its error.
  double min_clearance = 0.0;   ///< least distance of the true track to an obstacle or forbidden hazard [m] (+inf: none)
  double hazard_time = 0.0;     ///< time with the true vehicle inside a hazard [s]
  double hazard_length = 0.0;   ///< Σ_k length of the true track inside hazard k [m]
  double exposure = 0.0;        ///< Σ_k risk_k · length inside hazard k [m] (PathSafety::exposure of the track)
  double nees = 0.0;            ///< mean NEES eᵀP⁻¹e of the 4-state estimate (4 when consistent), over the steps whose P is positive definite
  double outside_3sigma = 0.0;  ///< fraction of steps with the truth outside the estimate's 3σ position ellipse (or a singular P_xy)
};

/// The one accumulator of an estimated trajectory's scores, fed pose by pose
/// in time order: against the truth, ADE and FDE [SafeNav-ext eqs. 21–22]
/// with the truth as reference, the position RMSE, the mean NEES
/// eᵀP⁻¹e (Bar-Shalom et al. 2001, §5.4) and the share of poses with the
/// truth outside the 3σ position ellipse; for the simulator also the risk
/// (AWRS [SafeNav-ext eq. 20] of the estimate and of the truth, deviation)
/// and safety (clearance, hazards) of the true track.  Sums run in pose
/// order.  No allocation per pose within the capacity given.
class TrajectoryScore {
 public:
  /// Room for `capacity` poses.
  explicit TrajectoryScore(Eigen::Index capacity = 0);

  /// One pose: estimated position p̂ with covariance P_xy, true position p.
  /// Throws std::invalid_argument when p̂ or p is not finite.  A P_xy that is
  /// not positive definite gives the pose no position NEES and counts it
  /// outside 3σ.
  void add(const Eigen::Vector2d& estimate, const Eigen::Matrix2d& P_xy, const Eigen::Vector2d& truth);
  /// One pose of the state (x, y, v, θ): the position scores as above, and
  /// the state NEES (θ residual wrapped) when P is positive definite.
  void add(const State& estimate, const StateCov& P, const State& truth);
  /// The simulator's risk terms of the last pose: the true vehicle's
  /// deviation from the safe path [m] and the WRS [SafeNav eq. 18] of the
  /// truth and of the estimate.
  void add_risk(double truth_deviation, double truth_wrs, double estimate_wrs);
  /// A clearance of the true track [m] (the least one is kept).
  void add_clearance(double clearance);
  /// One true step's hazard terms: its length and exposure inside hazards,
  /// and whether it ended inside one (adding `dt` seconds).
  void add_hazard(double length, double exposure, bool inside, double dt);

  Eigen::Index size() const { return n_; }
  /// The estimated positions so far, in order (size() rows).
  Eigen::Ref<const Points2> estimates() const { return points_.topRows(n_); }
  double length() const { return length_; }  ///< Σ‖p̂_k − p̂_{k−1}‖ [m]
  double min_clearance() const { return min_clearance_; }  ///< +inf before the first add_clearance
  double truth_ade() const;        ///< mean ‖p̂ − p‖ (NaN without poses)
  double truth_fde() const;        ///< ‖p̂ − p‖ of the last pose (NaN without poses)
  double truth_rmse() const;       ///< √(mean ‖p̂ − p‖²) (NaN without poses)
  double nees() const;             ///< mean state NEES over the poses with one (NaN: none)
  double position_nees() const;    ///< mean position NEES (2 degrees of freedom; NaN: none)
  int nees_poses() const { return nees_n_; }              ///< poses with a state NEES
  int position_nees_poses() const { return pos_nees_n_; }  ///< poses with a position NEES
  double outside_3sigma() const;   ///< share of poses outside the 3σ position ellipse (NaN without poses)
  /// The truth, consistency, risk and safety fields of `m`; path_ade,
  /// goal_fde and path_error_percent need the path and are left as they are.
  void fill(TrialMetrics& m) const;

 private:
  void add_position(const Eigen::Vector2d& estimate, const Eigen::Matrix2d& P_xy, const Eigen::Vector2d& truth);

  Points2 points_;
  Eigen::Index n_ = 0;
  double length_ = 0.0, error_sum_ = 0.0, error2_sum_ = 0.0, last_error_ = 0.0;
  double nees_sum_ = 0.0, pos_nees_sum_ = 0.0;
  int nees_n_ = 0, pos_nees_n_ = 0, outside_ = 0;
  double wrs_estimate_ = 0.0, wrs_truth_ = 0.0, max_deviation_ = 0.0;
  double min_clearance_ = std::numeric_limits<double>::infinity();
  double hazard_time_ = 0.0, hazard_length_ = 0.0, exposure_ = 0.0;
};

}  // namespace safenav

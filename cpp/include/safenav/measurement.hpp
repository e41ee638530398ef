// safenav/measurement.hpp — measurement models z = h(x) + v, v ~ N(0, R)
// ([SafeNav eq. 10]; the bearing model is the sensor of [Placement §III-A];
// range and range+bearing are ours, for real data; see docs/paper_map.md).
//
// Every model has the same form (as in GTSAM): a prediction h(x), an analytic
// Jacobian H = ∂h/∂x, and an angle-aware residual z − h(x).
#pragma once

#include <string>
#include <vector>
#include <Eigen/Core>

#include "safenav/motion.hpp"

namespace safenav {

enum class MeasurementKind {
  Position,      ///< z = (x, y)                               — LanBLoc output
  Range,         ///< z_i = ‖p − ℓ_i‖                          — one row per landmark
  Bearing,       ///< z_i = wrap(atan2(ℓ_iy − y, ℓ_ix − x) − θ) — relative bearing
  RangeBearing,  ///< z = (r_1, b_1, r_2, b_2, …)
  SpeedHeading,  ///< z = (v, θ)                               — IMU speed and heading
};

const char* to_string(MeasurementKind kind);

using Landmarks = Points2;

/// Gaussian measurement noise N(0, R) with a block-diagonal R, validated
/// once: each block must be finite, symmetric and positive definite.  R is
/// stored block by block with each block's Cholesky factor, so a model with
/// one independent row per landmark costs O(n), not O(n²), in memory and
/// work (a dense n×n matrix made MeasurementModel.range on 10⁴ landmarks
/// take over a minute).
class GaussianNoise {
 public:
  GaussianNoise() = default;
  /// One dense block R.
  explicit GaussianNoise(const Eigen::MatrixXd& R, const char* what = "R");
  /// R = diag(sigmas²): one 1×1 block per row.
  static GaussianNoise Sigmas(const Eigen::VectorXd& sigmas, const char* what = "sigmas");
  int dim() const { return dim_; }
  /// The dense R (dim()² doubles, built on each call).
  Eigen::MatrixXd cov() const;
  /// Squared Mahalanobis norm yᵀ R⁻¹ y.
  double mahalanobis2(const Eigen::Ref<const Eigen::VectorXd>& y) const;
  /// Y ← L⁻¹ Y with R = L Lᵀ (each column of Y a residual), block by block.
  void whiten(Eigen::Ref<Eigen::MatrixXd> Y) const;
  /// The noise of rows `rows`, in that order.  Rows of one block must be
  /// consecutive in `rows`, so that no correlation is lost.
  GaussianNoise subset(const std::vector<int>& rows) const;

 private:
  struct Block {
    int start;          // first row of the block in R
    Eigen::MatrixXd R;  // the block
    Eigen::MatrixXd L;  // its lower Cholesky factor
  };
  void add_block(const Eigen::MatrixXd& R, const char* what);
  size_t block_of(int row) const;
  std::vector<Block> blocks_;
  int dim_ = 0;
};

/// A measurement model with its noise.  Landmarks are used by the Range,
/// Bearing and RangeBearing kinds only.
class MeasurementModel {
 public:
  MeasurementModel(MeasurementKind kind, GaussianNoise noise, Landmarks landmarks = Landmarks());

  static MeasurementModel position(const Eigen::Matrix2d& R);
  static MeasurementModel speed_heading(const Eigen::Matrix2d& R);
  static MeasurementModel range(const Landmarks& landmarks, double sigma);
  static MeasurementModel bearing(const Landmarks& landmarks, double sigma);
  static MeasurementModel range_bearing(const Landmarks& landmarks, double sigma_range, double sigma_bearing);

  MeasurementKind kind() const { return kind_; }
  int dim() const { return dim_; }
  const GaussianNoise& noise() const { return noise_; }
  const Landmarks& landmarks() const { return landmarks_; }
  /// True for the components of z that are angles (wrapped residuals).
  bool is_angle(int i) const;

  /// h(x), written into zhat (size dim()).  Throws std::invalid_argument when
  /// a range/bearing landmark coincides with the vehicle position (undefined).
  void predict(const State& x, Eigen::Ref<Eigen::VectorXd> zhat) const;
  Eigen::VectorXd predict(const State& x) const;
  /// h(x) and H = ∂h/∂x together (dim() and dim()×4), from one evaluation.
  void predict(const State& x, Eigen::Ref<Eigen::VectorXd> zhat, Eigen::Ref<Eigen::MatrixXd> H) const;
  /// H = ∂h/∂x (dim()×4), analytic.
  void jacobian(const State& x, Eigen::Ref<Eigen::MatrixXd> H) const;
  Eigen::MatrixXd jacobian(const State& x) const;
  /// y = z − ẑ with angle components wrapped to (−π, π].
  void residual(const Eigen::Ref<const Eigen::VectorXd>& z, const Eigen::Ref<const Eigen::VectorXd>& zhat,
                Eigen::Ref<Eigen::VectorXd> y) const;
  /// Validate a measurement vector: right size and finite.
  void check(const Eigen::Ref<const Eigen::VectorXd>& z) const;

  /// Same model restricted to a subset of landmarks (for streams with gaps).
  MeasurementModel subset(const std::vector<int>& landmark_rows) const;

 private:
  MeasurementKind kind_;
  GaussianNoise noise_;
  Landmarks landmarks_;
  int dim_;
};

}  // namespace safenav

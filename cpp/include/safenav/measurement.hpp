// safenav/measurement.hpp — measurement models z = h(x) + v, v ~ N(0, R)
// ([SafeNav eq. 10]; the bearing model is the sensor of [Placement §III-A];
// range and range+bearing are ours, for real data; see docs/paper_map.md).
//
// Every model has the same form (as in GTSAM): a prediction h(x), an analytic
// Jacobian H = ∂h/∂x, and an angle-aware residual z − h(x).
#pragma once

#include <cmath>
#include <cstdint>
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

/// n states as the columns of a 4 × n matrix, read in place with any strides:
/// a particle filter's columns (inner stride: the distance between its state
/// columns, outer stride 1), an augmented state's first four rows, one State.
using StatesView =
    Eigen::Map<const Eigen::Matrix<double, 4, Eigen::Dynamic>, 0, Eigen::Stride<Eigen::Dynamic, Eigen::Dynamic>>;

// ---------------------------------------------------------------------------
// The landmark observation model, written once.  In GTSAM's form (a factor's
// evaluateError with optional Jacobians) it returns the prediction h and, when
// asked, one row of ∂h/∂state by state block: the pose (x, y, θ; the speed v
// never enters), the range scale k and the observed landmark's range bias b_j.
//
//   range    r = (1 + k)·ρ + b_j,  ρ = ‖a − p‖   [SafeNav eq. 10]; k, b_j are
//            augmented states (ours, safenav/augmented.hpp), 0 in the plain model
//   bearing  β = atan2(a_y − y, a_x − x) − θ      [Placement §III-A], relative,
//            counter-clockwise, unwrapped (residuals wrap z − β)
//
// The EKF, the augmented EKF and PF, the particle filter's likelihood (through
// MeasurementModel), the EIF, the online Localizer and trilateration /
// triangulation (safenav/trilateration.hpp) all evaluate these two functions.

/// Below this squared distance a landmark is "at" the vehicle: range and
/// bearing Jacobians are undefined there.
constexpr double kMinLandmarkDistance2 = 1e-18;

/// Landmark a seen from the position p: the offset a − p, q = ‖a − p‖² and
/// ρ = √q (std::hypot when q overflows, so any representable distance comes back).
struct LandmarkGeometry {
  double dx, dy;  ///< a − p
  double q;       ///< dx² + dy²
  double r;       ///< ρ
  /// The offset is finite (false when a − p overflows).
  bool finite() const { return std::isfinite(dx) && std::isfinite(dy); }
  /// Range and bearing Jacobians are defined (the landmark is not at p).
  bool defined() const { return !(q < kMinLandmarkDistance2); }
};

inline LandmarkGeometry landmark_geometry(double px, double py, double ax, double ay) {
  const double dx = ax - px, dy = ay - py;
  const double q = dx * dx + dy * dy;
  return {dx, dy, q, std::isfinite(q) ? std::sqrt(q) : std::hypot(dx, dy)};
}

/// One row of ∂h/∂state of a landmark observation, by state block.
struct LandmarkJacobian {
  double x = 0.0, y = 0.0, theta = 0.0;  ///< pose block (∂h/∂v = 0)
  double k = 0.0;                        ///< range scale
  double b = 0.0;                        ///< the landmark's range bias b_j
};

/// r = (1 + k)·ρ + b; ∂r/∂(x, y) = −(1 + k)(a − p)/ρ, ∂r/∂k = ρ, ∂r/∂b = 1.
/// Needs g.defined() for H.  With k = b = 0 this is the plain range ρ, exactly.
inline double predict_range(const LandmarkGeometry& g, double k, double b, LandmarkJacobian* H = nullptr) {
  const double s = 1.0 + k;
  if (H) {
    H->x = s * -g.dx / g.r;
    H->y = s * -g.dy / g.r;
    H->theta = 0.0;
    H->k = g.r;
    H->b = 1.0;
  }
  return s * g.r + b;
}

/// β = atan2(dy, dx) − θ; ∂β/∂(x, y) = (dy, −dx)/q, ∂β/∂θ = −1.  Needs g.defined() for H.
inline double predict_bearing(const LandmarkGeometry& g, double theta, LandmarkJacobian* H = nullptr) {
  if (H) {
    H->x = g.dy / g.q;
    H->y = -g.dx / g.q;
    H->theta = -1.0;
    H->k = H->b = 0.0;
  }
  return std::atan2(g.dy, g.dx) - theta;
}

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
  /// Y.col(i) = z ⊖ h(x_i) for the states x_i = states.col(i) (Y: dim() × n):
  /// the values of predict() and residual() for each state.  The kinds that
  /// observe two state components (position, speed and heading) read them
  /// without a call per state (direct_residuals).
  void residuals(const Eigen::Ref<const Eigen::VectorXd>& z, const StatesView& states,
                 Eigen::Ref<Eigen::MatrixXd> Y) const;
  /// residuals() of a kind that observes two state components, which needs no
  /// model: position z ⊖ (x, y), speed and heading z ⊖ (v, θ) with θ's
  /// residual wrapped.  Throws std::invalid_argument for a landmark kind.
  static void direct_residuals(MeasurementKind kind, const Eigen::Ref<const Eigen::VectorXd>& z,
                               const StatesView& states, Eigen::Ref<Eigen::MatrixXd> Y);
  /// direct_residuals() of one state.
  static Eigen::Vector2d direct_residual(MeasurementKind kind, const Eigen::Vector2d& z, const State& x);
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

// ---------------------------------------------------------------------------
// Position noise: the error model of a position source

/// The draws a noise model takes: standard normals and uniforms in [0, 1).
/// RandomSourceOf adapts a generator; a vehicle program may pass its own.
class RandomSource {
 public:
  virtual ~RandomSource() = default;
  virtual double normal() = 0;
  virtual double uniform() = 0;
};

/// A RandomSource over a generator G with normal() and uniform() members.
template <class G>
class RandomSourceOf final : public RandomSource {
 public:
  explicit RandomSourceOf(G& g) : g_(g) {}
  double normal() override { return g_.normal(); }
  double uniform() override { return g_.uniform(); }

 private:
  G& g_;
};

/// The error model of a position source at the measurement level: LanBLoc
/// with the paper's RMSE ([SafeNav §IV-A]), or an emulated baseline
/// (DeepLoc-GPS, DeepLoc-EKF-GPS, Sensor Fusion: error profiles we chose,
/// DESIGN.md decision 8).  A trial draws a bias b ~ N(0, bias_std² I) once
/// (Trial); then each fix
///   1. walks the bias: b += N(0, bias_walk_std² I);
///   2. is lost with probability dropout_probability;
///   3. is z = p + b + w, w ~ N(0, diag(std²));
///   4. with probability outlier_probability gets an extra N(0, outlier_std² I).
/// A term whose σ or probability is 0 draws nothing.  Filters are told
/// reported_cov().  The named profiles (named(), names()) are declared once,
/// here; Python and the synthetic data set use them.
struct PositionNoise {
  using Fixes = Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>;

  std::string name = "lanbloc";
  std::string label = "LanBLoc";        ///< for tables
  Eigen::Vector2d std{0.0142, 0.039};   ///< σ of w in X and Y [m]; LanBLoc's RMSE [SafeNav §IV-A]
  double bias_std = 0.0;                ///< σ of the per-trial bias [m]
  double bias_walk_std = 0.0;           ///< σ of the bias's random walk per fix [m]
  double outlier_probability = 0.0;     ///< in [0, 1]
  double outlier_std = 0.0;             ///< σ of an outlier's extra error [m]
  double dropout_probability = 0.0;     ///< a fix is lost at random with this probability, in [0, 1]
  bool needs_landmarks = true;          ///< a fix needs ≥ min_landmarks landmarks in view (the navigation loop checks)
  bool emulated = false;                ///< an emulated error profile, not the real method
  std::string note;                     ///< what the profile stands for

  /// The named profile `name` (one of names()); std::invalid_argument otherwise.
  static PositionNoise named(const std::string& name);
  /// The named profiles, LanBLoc first.
  static std::vector<std::string> names();

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
  /// The R filters are told: diag(std²) + (bias_std² + outlier_probability·outlier_std²) I.
  /// The bias walk is left out (it has no stationary variance).
  Eigen::Matrix2d reported_cov() const;

  /// One trial's state: the bias, drawn on construction, and its walk.
  /// Keeps a pointer to its PositionNoise, which must outlive it.
  class Trial {
   public:
    Trial(const PositionNoise& noise, RandomSource& rng);
    /// The next fix of a vehicle at p, into z (steps 1–4 above); false
    /// when the fix is lost.
    bool sample(const Eigen::Vector2d& p, RandomSource& rng, Eigen::Vector2d& z);
    const Eigen::Vector2d& bias() const { return bias_; }

   private:
    const PositionNoise* noise_;
    Eigen::Vector2d bias_ = Eigen::Vector2d::Zero();
  };

  /// The fixes of one trial at the true positions `truth` (one row per fix),
  /// drawn from the core's generator seeded with `seed` (the navigation loop
  /// seeds its sensors with derive_seed(trial_seed, 1)); NaN rows are lost
  /// fixes.  Validates the profile first.
  Fixes sample(const Eigen::Ref<const Fixes>& truth, std::uint64_t seed) const;
};

/// Landmark-level faults (ours; the papers model none): what goes wrong with
/// single landmark observations before LanBLoc's trilateration sees them.
/// Each observation of a landmark in view, independently and in this order:
///   1. is missed (a failed detection) with probability dropout_probability;
///   2. carries another landmark's id with probability misassociation_probability
///      (a wrong match): the range is still to the true landmark, and the id
///      is drawn uniformly among the other landmarks within `confusion_range`
///      of the vehicle (or among all others when none is);
///   3. is an outlier with probability outlier_probability: its range is off
///      by ±outlier_magnitude (sign drawn uniformly).
/// A probability of 0 draws nothing, so a fault-free model draws no numbers.
struct LandmarkFaults {
  double dropout_probability = 0.0;        ///< in [0, 1]
  double outlier_probability = 0.0;        ///< in [0, 1]
  double outlier_magnitude = 5.0;          ///< |range error| of an outlier [m], > 0
  double misassociation_probability = 0.0; ///< in [0, 1]

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
  /// Whether any fault can happen.
  bool any() const { return dropout_probability > 0 || outlier_probability > 0 || misassociation_probability > 0; }

  /// What happened to one observation (bit flags).
  enum Fault : unsigned { kDropped = 1u, kMisassociated = 2u, kOutlier = 4u };
  /// One landmark observation: the landmark's row in the map (the id it
  /// carries, after faults), its range, and the faults applied.
  struct Observation {
    int row = 0;
    double range = 0.0;
    unsigned faults = 0;
  };
  /// Applies the faults to `obs` (true rows and ranges of the landmarks seen
  /// by a vehicle at p) in place: dropped observations are removed (counted
  /// in `dropped` when given), others get their flags.  `landmarks` is the
  /// map (rows = ids).  Draws from rng in observation order.
  void apply(std::vector<Observation>& obs, const Landmarks& landmarks, const Eigen::Vector2d& p,
             double confusion_range, RandomSource& rng, int* dropped = nullptr) const;
};

}  // namespace safenav

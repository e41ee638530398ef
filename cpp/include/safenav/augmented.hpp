// safenav/augmented.hpp — the EKF of [SafeNav eqs. 10–14] over the BMM
// state (x, y, v, θ) [SafeNav eqs. 3–9] augmented with optional sensor-error
// states:
//
//   k     range scale:            r = (1 + k)·‖p − a_j‖ + b_j + n
//   β     heading-rate bias:      θ' = θ + clip(Δθ) − β·Δt     [rad/s]
//   b_j   per-landmark range bias (one per map row j)
//
// The augmented states are ours, not the paper's.  Why: on the Plaza range
// data sets the ranges read ≈ 7 % long (r ≈ 1.0695·‖p − a‖ against the
// ground truth), which a filter without k cannot absorb (it rejects half the
// ranges and diverges); Plaza2's gyro has a bias of −0.0053 rad/s, which the
// low heading process noise that Plaza1 wants cannot follow without β.  Each
// augmented state is a random walk with σ per √s.
//
// State order: (x, y, v, θ, [k], [β], [b_0 … b_{K−1}]).
// After construction predict and the updates allocate nothing.
// Only Eigen and std types appear here.
#pragma once

#include <cstdint>
#include <memory>

#include <Eigen/Core>

#include "safenav/filters.hpp"
#include "safenav/motion.hpp"

namespace safenav {

/// Which augmented states are on, their prior (mean, σ) and random walk
/// (σ per √s).  Off by default; the values are those tuned on Plaza1.
struct AugmentedStates {
  bool range_scale = false;              ///< estimate k (r = (1+k)·ρ + b)
  double scale_prior = 0.07;             ///< k₀, the prior mean of k
  double scale_std = 0.02;               ///< σ of k₀
  double scale_walk = 1e-5;              ///< random walk of k [1/√s]
  bool heading_rate_bias = false;        ///< estimate β (θ' = θ + clip(Δθ) − β·Δt)
  double heading_rate_bias_prior = 0.0;  ///< β₀ [rad/s]
  double heading_rate_bias_std = 0.01;   ///< σ of β₀ [rad/s]
  double heading_rate_bias_walk = 1e-5;  ///< random walk of β [rad/s/√s]
  bool range_bias = false;               ///< estimate b_j, one per landmark
  double range_bias_std = 0.3;           ///< σ of b_j's prior (mean 0) [m]
  double range_bias_walk = 1e-3;         ///< random walk of b_j [m/√s]

  bool any() const { return range_scale || heading_rate_bias || range_bias; }
  /// Throws std::invalid_argument naming the first field out of its declared range.
  void validate() const;
};

/// EKF over (x, y, v, θ, [k], [β], [b_j]):
///  predict: x̂ = f(x̂, u), P = F P Fᵀ + Q                      [SafeNav eq. 11]
///           f = the BMM of [SafeNav eqs. 3–9] over dt (Bmm::with_step) with
///           θ' = θ + clip(Δθ) − β·dt (ours); Q = G Σ_ε Gᵀ (dt/Δt) plus
///           σ_walk²·dt on each augmented state (ours)
///  update:  y = z ⊖ h(x̂), S = H P Hᵀ + R                      [SafeNav eq. 12]
///           K = P Hᵀ S⁻¹                                      [SafeNav eq. 13]
///           x̂ = x̂ + K y, P = (I−KH) P (I−KH)ᵀ + K R Kᵀ        [SafeNav eq. 14], Joseph form
/// Every update is gated on its own, as Ekf::set_gate.
class AugmentedEkf {
 public:
  /// `n_landmarks` rows of the map (one b_j each when range_bias is on).
  /// The augmented part of the prior is `augment`'s (means, σ²), independent
  /// of (x0, P0).
  AugmentedEkf(const BmmParams& params, const AugmentedStates& augment, int n_landmarks, const State& x0,
               const StateCov& P0);

  /// The 4-state marginal (x, y, v, θ) and its covariance.
  const State& x() const { return x4_; }
  const StateCov& P() const { return P4_; }
  /// The full augmented mean and covariance (size() entries).
  const Eigen::VectorXd& augmented() const { return x_; }
  const Eigen::MatrixXd& augmented_cov() const { return P_; }
  /// Replace the full state; throws unless sizes match, x finite, P a covariance.
  void set_state(const Eigen::VectorXd& x, const Eigen::MatrixXd& P);

  int size() const { return n_; }
  int n_landmarks() const { return n_landmarks_; }
  /// Index of k, β, b_row in the augmented state, or −1 when that state is off.
  int scale_index() const { return ik_; }
  int heading_rate_bias_index() const { return ig_; }
  int range_bias_index(int landmark_row) const;
  const AugmentedStates& augment() const { return augment_; }
  const Bmm& model() const { return bmm_; }

  /// NIS gate, as Ekf::set_gate: 0 disables it.
  void set_gate(double probability);
  double gate() const { return gate_probability_; }

  /// Eq. 11 over dt seconds with the bias-corrected heading change.
  void predict(const Control& u, double dt);
  /// The last predict's full transition F = [F₄ Fβ 0; 0 I] and process
  /// noise Q = diag(G Σ_ε Gᵀ, σ_walk²·dt) (size() × size(); identity and zero
  /// before any predict), as predict applied them: P' = F P Fᵀ + Q.  For a
  /// Rauch–Tung–Striebel smoother (safenav/smoother.hpp).  Resizes F and Q.
  void last_transition(Eigen::MatrixXd& F, Eigen::MatrixXd& Q) const;
  /// predict's model at the full state x instead of the estimate: x1 = f(x, u)
  /// over dt, its F and Q (as last_transition's), for an iterated smoother that
  /// re-linearises about its own trajectory (safenav/smoother.hpp).  x, x1 of
  /// size() entries, F and Q size() × size() (std::invalid_argument otherwise).
  void transition(const Eigen::Ref<const Eigen::VectorXd>& x, const Control& u, double dt,
                  Eigen::Ref<Eigen::VectorXd> x1, Eigen::Ref<Eigen::MatrixXd> F, Eigen::Ref<Eigen::MatrixXd> Q) const;
  /// r = (1+k)·‖p − a‖ + b_row, with variance σ_r² (eqs. 12–14).
  UpdateResult update_range(int landmark_row, const Eigen::Vector2d& landmark, double r, double variance);
  /// Relative bearing atan2(a − p) − θ (counter-clockwise, wrapped); not affected by k, b.
  UpdateResult update_bearing(int landmark_row, const Eigen::Vector2d& landmark, double bearing, double variance);
  /// z = (range, bearing) with 2×2 covariance R.
  UpdateResult update_range_bearing(int landmark_row, const Eigen::Vector2d& landmark, const Eigen::Vector2d& z,
                                    const Eigen::Matrix2d& R);
  /// A position fix z with covariance R (H = [I₂ 0]).
  UpdateResult update_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R);
  /// IMU z = (v, θ) with covariance R (H = [0 0 1 0; 0 0 0 1], angle wrapped).
  UpdateResult update_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R);

 private:
  void check_row(int row, const char* what) const;
  /// The landmark model (safenav/measurement.hpp) at x̂: fills H_'s row `r` and returns h.
  LandmarkGeometry geometry(const Eigen::Vector2d& a, const char* what) const;
  void set_row(int r, int landmark_row, const LandmarkJacobian& J);
  double range_row(int row, const Eigen::Vector2d& a, int r);
  double bearing_row(int row, const Eigen::Vector2d& a, int r);
  template <int M>
  UpdateResult apply(const Eigen::Matrix<double, M, 1>& y, const Eigen::Matrix<double, M, M>& R,
                     MeasurementKind kind);
  void sync4();
  /// Adds the augmented states' random walks over dt to P's diagonal (eq. 11's Q, augmented part).
  void add_walks(Eigen::Ref<Eigen::MatrixXd> P, double dt) const;
  /// Eq. 11's f at (x4, β) over dt with its F₄, G, ∂f/∂β and Σ_ε (the one motion model of predict and transition).
  State step(const State& x4, double beta, const Control& u, double dt, Eigen::Matrix4d& F4, Eigen::Matrix4d& G,
             Eigen::Vector4d& Fb, Eigen::Matrix4d& noise) const;

  Bmm bmm_;
  AugmentedStates augment_;
  int n_landmarks_ = 0;
  int n_ = 4, ik_ = -1, ig_ = -1, ib0_ = -1;
  Eigen::VectorXd x_;
  Eigen::MatrixXd P_;
  State x4_;
  StateCov P4_;
  double gate_probability_ = 0.0;
  double gate_threshold_[3] = {0.0, 0.0, 0.0};  // by measurement dimension (1, 2)
  // Scratch, sized at construction.
  Eigen::Matrix<double, 4, Eigen::Dynamic> JP_;  // rows 0..3 of F P
  Eigen::Matrix<double, 2, Eigen::Dynamic> H_;
  // The Kalman update's (cpp/src/filters/kalman_update.hpp): P Hᵀ, K, K R, A Hᵀ; P'; x'.
  Eigen::Matrix<double, Eigen::Dynamic, 2> PHt_, K_, KR_, AHt_;
  Eigen::MatrixXd P1_;
  Eigen::VectorXd x1_;
  // The last predict's F₄, Fβ, G, Σ_ε and dt (last_transition()).
  Eigen::Vector4d last_Fb_ = Eigen::Vector4d::Zero();
  Eigen::Matrix4d last_F4_ = Eigen::Matrix4d::Identity(), last_G_ = Eigen::Matrix4d::Zero(),
                  last_noise_ = Eigen::Matrix4d::Zero();
  double last_dt_ = 0.0;
};

/// Particle filter over the same augmented state (the PF counterpart of
/// AugmentedEkf; the paper prints no PF equations): each particle moves by
/// the noisy BMM (Bmm::transition over dt, at θ − β·dt) and each augmented
/// state by its random walk; weights multiply by the Gaussian likelihood of
/// r = (1+k)·ρ + b_j etc. (log space), systematic resampling when
/// ESS < resample_threshold·N.  With bandwidth_scale > 0 each resampling is
/// regularised over the whole augmented state, d = state_size() (Musso et
/// al.'s post-regularised PF; the references are at ParticleFilter in
/// safenav/filters.hpp): x_i ← m + a(x_i − m) + d_i − d̄, d_i = L ε_i, d̄
/// their mean (the jitter moves no mean), a = √(1 − h²) (Liu & West's
/// shrinkage), L Lᵀ = P_k + (g − 1)·Σ₊, the kernel h²Σ⁻ of the cloud before
/// the update conditioned on z by statistical linearisation, P_k = h²Σ⁻ −
/// h⁴C_xy(h²C_yy + R)⁻¹C_xyᵀ (Musso et al. use h² times the weighted
/// posterior covariance, ~0 when the weights degenerate), plus the Monte
/// Carlo variance that resampling loses, Σ₊ the weighted posterior
/// covariance and g = ESS/(ESS − 1) with the lineages' ESS (as
/// ParticleFilter's).  This keeps the
/// slowly varying k, β, b_j from collapsing onto a few values (their random
/// walks are far too small to restore diversity).  The weights stay those of
/// the SIR filter (ParticleFilter's kernel update is not used here).
/// covariance() is g·sample_covariance() floored, as ParticleFilter's.  Gate as
/// ParticleFilter::set_gate: the NIS of the weighted-mean prediction
/// (S = weighted covariance of the particles' residuals + R).  A plain
/// scalar loop; predict and the updates allocate nothing after construction
/// except the regularisation after a resampling (a few small matrices).
class AugmentedParticleFilter {
 public:
  /// bandwidth_scale ∈ [0, 10] as ParticleFilter's (0: no regularisation).
  AugmentedParticleFilter(const BmmParams& params, const AugmentedStates& augment, int n_landmarks,
                          const State& x0, const StateCov& P0, int n_particles, std::uint64_t seed,
                          double resample_threshold = 0.5, double bandwidth_scale = 1.0);
  ~AugmentedParticleFilter();
  AugmentedParticleFilter(AugmentedParticleFilter&&) noexcept;
  AugmentedParticleFilter& operator=(AugmentedParticleFilter&&) noexcept;
  /// Copies (the generator's state included); assignment reuses this filter's storage.
  AugmentedParticleFilter(const AugmentedParticleFilter&);
  AugmentedParticleFilter& operator=(const AugmentedParticleFilter&);

  int size() const;        ///< particles
  int state_size() const;  ///< entries of the augmented state
  int scale_index() const;
  int heading_rate_bias_index() const;
  void set_gate(double probability);
  double gate() const;

  void predict(const Control& u, double dt);
  UpdateResult update_range(int landmark_row, const Eigen::Vector2d& landmark, double r, double variance);
  UpdateResult update_bearing(int landmark_row, const Eigen::Vector2d& landmark, double bearing, double variance);
  UpdateResult update_range_bearing(int landmark_row, const Eigen::Vector2d& landmark, const Eigen::Vector2d& z,
                                    const Eigen::Matrix2d& R);
  UpdateResult update_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R);
  UpdateResult update_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R);

  /// Weighted mean (circular for θ) of (x, y, v, θ).
  State mean() const;
  /// The reported covariance of (x, y, v, θ): g·sample_covariance() (the Monte Carlo
  /// error of the weighted mean, ParticleFilter's g) floored by covariance_floor().
  StateCov covariance() const;
  /// The weighted covariance of (x, y, v, θ), unfloored.
  StateCov sample_covariance() const;
  /// h²·C_u over (x, y, v, θ) (C_u: the unweighted covariance of the particles).
  StateCov covariance_floor() const;
  /// The kernel bandwidth h (dimensionless, in [0, 1]).
  double bandwidth() const;
  /// Weighted mean of the full augmented state (θ circular).
  Eigen::VectorXd augmented() const;
  /// Particles (state_size() × N, one per column) and normalised weights.
  const Eigen::MatrixXd& particles() const;
  Eigen::VectorXd weights() const;
  double ess() const;
  int resample_count() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace safenav

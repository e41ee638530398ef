// safenav/filters.hpp — EKF [SafeNav eqs. 10–14], particle filter (the
// LanBLoc-BMM(PF) rows of [SafeNav-ext Tables II–III]; the paper prints no PF
// equations) and extended information filter (the EIF of [Placement §III-A],
// which prints none either) over the BMM state (x, y, v, θ).
// Citations follow docs/paper_map.md.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>
#include <Eigen/Core>

#include "safenav/measurement.hpp"
#include "safenav/motion.hpp"

namespace safenav {

/// Outcome of one measurement update.
struct UpdateResult {
  bool accepted = true;  ///< false when rejected by the NIS gate
  double nis = 0.0;      ///< normalised innovation squared yᵀ S⁻¹ y
  int dim = 0;           ///< measurement dimension (chi-square degrees of freedom)
  /// log det S of that S: with the NIS, the innovation's log-likelihood
  /// −½(nis + log det S + dim·log 2π) (noise identification; NaN if unknown).
  double log_det_s = std::numeric_limits<double>::quiet_NaN();
};

/// Validate a covariance: finite, symmetric (relative tolerance 1e-9) and
/// positive definite.  Throws std::invalid_argument naming `what`.
void check_covariance(const Eigen::MatrixXd& P, const char* what);

/// Chi-square quantile, used to turn a gate probability into an NIS threshold.
double chi2_quantile(double probability, int dof);

/// The last prediction's linearisation (eq. 11): x' ≈ f(x̂, u) + F (x − x̂),
/// P' = F P Fᵀ + Q with Q = G Σ_ε Gᵀ.  A Rauch–Tung–Striebel smoother
/// (safenav/smoother.hpp) reads F from here instead of linearising again.
struct EkfTransition {
  Eigen::Matrix4d F = Eigen::Matrix4d::Identity();
  Eigen::Matrix4d Q = Eigen::Matrix4d::Zero();
  double dt = 0.0;  ///< [s]; 0 before the first predict
};

/// Extended Kalman filter on the BMM.
///  predict: x̂ = f(x̂, u), P = F P Fᵀ + Q                      [SafeNav eq. 11]
///  update:  y = z ⊖ h(x̂), S = H P Hᵀ + R                      [SafeNav eq. 12]
///           K = P Hᵀ S⁻¹                                      [SafeNav eq. 13]
///           x̂ = x̂ + K y, P = (I−KH) P (I−KH)ᵀ + K R Kᵀ        [SafeNav eq. 14], Joseph form
class Ekf {
 public:
  Ekf(const BmmParams& params, const State& x0, const StateCov& P0);

  const State& x() const { return x_; }
  const StateCov& P() const { return P_; }
  const Bmm& model() const { return bmm_; }
  void set_state(const State& x, const StateCov& P);

  /// NIS gate: updates whose NIS exceeds the chi-square quantile at this
  /// probability are rejected.  0 (default) disables the gate.
  void set_gate(double probability);
  double gate() const { return gate_probability_; }

  void predict(const Control& u);
  /// Eq. 11 over a step of dt seconds (timestamped inputs): the BMM of
  /// Bmm::with_step(dt).  predict(u, model().params().dt) equals predict(u).
  void predict(const Control& u, double dt);
  /// F and Q of the last predict that stood (identity and zero before any).
  EkfTransition last_transition() const;
  UpdateResult update(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z);
  /// A position fix z with its own covariance R (eqs. 12–14 with H = [I₂ 0]).
  UpdateResult update_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R);
  /// Eqs. 12–14 from a linearisation made by the caller (one landmark
  /// observation, say): residual y = z ⊖ h(x̂) with angles wrapped, H = ∂h/∂x
  /// at x̂ and the noise R, for m = 1 or 2 rows.  `kind` names the
  /// measurement in errors.  Gated like update(); no allocation.
  UpdateResult update_linearized(const Eigen::Matrix<double, 1, 1>& y, const Eigen::Matrix<double, 1, 4>& H,
                                 const Eigen::Matrix<double, 1, 1>& R, MeasurementKind kind);
  UpdateResult update_linearized(const Eigen::Vector2d& y, const Eigen::Matrix<double, 2, 4>& H,
                                 const Eigen::Matrix2d& R, MeasurementKind kind);

 private:
  void predict_with(const Bmm& bmm, const Control& u);
  /// x̂, P ← x, P unless an entry overflowed (then throws, naming the step and keeping the old state).
  void commit(const State& x, const StateCov& P, const char* step);
  template <int M>
  UpdateResult update_fixed(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z);
  template <int M>
  UpdateResult apply(const Eigen::Matrix<double, M, 1>& y, const Eigen::Matrix<double, M, 4>& H,
                     const Eigen::Matrix<double, M, M>& R, MeasurementKind kind);
  bool gate_rejects(double nis, int dim);

  Bmm bmm_;
  State x_;
  StateCov P_;
  // The last predict's F, G, diag Σ_ε and step (last_transition()).
  Eigen::Matrix4d last_F_ = Eigen::Matrix4d::Identity(), last_G_ = Eigen::Matrix4d::Zero();
  Eigen::Vector4d last_sigma2_ = Eigen::Vector4d::Zero();
  double last_dt_ = 0.0;
  double gate_probability_ = 0.0;
  std::vector<double> gate_thresholds_;  // chi-square quantile per measurement dimension
};

/// Particle filter on the BMM with log-weights, systematic resampling and
/// regularisation.  The paper prints no PF equations.  bandwidth_scale = 0
/// gives the bootstrap (SIR) filter of [Gordon, Salmond & Smith 1993]:
///
///  predict: every particle through the noisy BMM [SafeNav eqs. 3–9]
///  update:  log w_i += log p(z | x_i); resample (systematic) when
///           ESS = 1/Σw² < resample_threshold·N
///
/// The default (bandwidth_scale = c > 0) is a regularised PF.  An update whose
/// SIR weights keep ESS ≥ resample_threshold·N is the SIR update above;
/// otherwise the particles are the centres of Gaussian kernels, as in the
/// regularised PF of [Musso,
/// Oudjane & Le Gland 2001, "Improving regularised particle filters", ch. 12
/// of Doucet, de Freitas & Gordon (eds.), Sequential Monte Carlo Methods in
/// Practice], and the update is that of the adaptive Gaussian mixture filter
/// [Stordal, Karlsen, Nævdal, Skaug & Vallès 2011, "Bridging the ensemble
/// Kalman filter and particle filters", Comput. Geosci. 15:293–305]:
///
///  bandwidth: h = c·(4/(N(d+2)))^{1/(d+4)}, d = 4: Musso et al.'s optimal
///             Gaussian-kernel bandwidth h_opt at c = 1; per update the
///             smallest h_u ∈ [h, 1] whose kernel weights keep ESS ≥
///             resample_threshold·N (Stordal et al.'s adaptive bandwidth;
///             h_u = 1 is the ensemble Kalman update, flat kernel weights)
///  kernels:   N(c_i, h_u²Σ⁻), c_i = m + a(x_i − m), a = √(1 − h_u²) [Liu &
///             West 2001, ch. 10 of the same book]: the mixture keeps the
///             cloud's mean m and covariance Σ⁻ (weighted, before the update)
///  update:    S_h = h_u²C_yy + R, K = h_u²C_xh S_h⁻¹, P_k = h_u²Σ⁻ − K S_h Kᵀ,
///             with C_yy, C_xh the weighted covariances of the residuals
///             y_i = z ⊖ h(x_i) and of x with h(x) (statistical linearisation
///             over the particles, exact for the position and IMU models);
///             y_c,i = ȳ + a(y_i − ȳ), log w_i += −½ y_c,iᵀ S_h⁻¹ y_c,i,
///             centre c_i + K y_c,i; resample when ESS < resample_threshold·N
///             (systematic), and then redraw from P_k + (g − 1)·Σ_c, Σ_c the
///             weighted covariance of the updated centres (below); each
///             particle is redrawn from its kernel: + d_i − Σ w_j d_j,
///             d_i = L T(ε_i − ε̄), L Lᵀ = P_k, T moment-matching the draws
///             (weighted mean 0, weighted covariance I exactly)
///  Monte Carlo error: the weighted covariance P̂ about the weighted mean m̂
///             has expectation (1 − Σw²)·P; the missing P/ESS is the
///             covariance of m̂'s Monte Carlo error, which resampling turns
///             into an error of the mean that no later update sees.  With
///             g = ESS/(ESS − 1) (ESS of the lineages, 1/Σ_a W_a², W_a the
///             weight of the descendants of one particle of the last
///             resampling: copies move together), g·P̂ is put back into the
///             redraw at each resampling and into the report
///  gain error: P_k += 2E, E = Σ_x|h·tr(A C_yy)/n, the covariance that a
///             gain made of sampled moments takes beyond the Gaussian update
///             (regularise.hpp, gain_sampling_excess; n the prior lineage
///             ESS): once for the spread it takes, once for the error it
///             adds to the mean.  At h_u = 1 (a = 0) every kernel has the one
///             centre m + Kȳ: the particles are redrawn from g·P_k + 2E with
///             uniform weights (the mixture is one Gaussian; exact)
///  IMU:       an update that does not see the position (SpeedHeading) is
///             the ensemble Kalman update with perturbed observations
///             [Burgers, van Leeuwen & Evensen 1998, Mon. Wea. Rev. 126]:
///             x_i ← x_i + K(y_i + η_i), K = C_xh S⁻¹, S = C_yy + R, η_i ~
///             N(0, R) moment-matched (weighted mean 0, covariance R, no
///             covariance with the state): the weights stay and the
///             weighted covariance becomes Σ − K S Kᵀ exactly
///  predict:   the process noise draws are moment-matched the same way
///             (covariance I, none with the state), so that no sampled
///             correlation of position with (v, θ) reaches the next IMU gain
///  report:    P = gP̂ + (h²C_u − gP̂)₊ (⪰ gP̂ and ⪰ h²C_u), C_u the
///             particles' unweighted covariance
///
/// Why: with LanBLoc fixes (σ ≈ 1–4 cm) after a few steps without one, the
/// SIR likelihood is far narrower than the particle spacing; one or two
/// particles take all the weight and the reported covariance collapses
/// (mean NEES 1e11–1e16 in the navigation loop).  Each kernel here is
/// weighted by its own predictive likelihood (S_h ⪰ R) and moved toward z
/// by K, so a fix narrower than the cloud, or beyond it, moves the cloud
/// instead of selecting one particle, and the redraw keeps the cloud from
/// collapsing after resampling.  In dead reckoning (the IMU's speed and
/// heading every step, no fix) the IMU weights say almost nothing about
/// position, yet each weigh-and-resample cycle with a fixed h turned
/// ~P/ESS of the position spread into a random walk of the mean: the cloud
/// shrank while the error grew (NEES 12–24 in the loop at 500 particles,
/// from runs that waited hundreds of steps for a fix).  The adaptive h
/// moves the cloud instead of reweighting it, the moment-matched redraw
/// moves no mean, and g puts back what resampling still loses.  What was
/// left (NEES 6–7.5 on the long gaps at 500 particles; position variance
/// 0.75 of the EKF's after 200 IMU-only steps) was the sampled gain: the
/// cloud's chance correlations of position with (v, θ), ~σ/√N from the
/// process noise and the weights, made each IMU update take position
/// variance and move the mean at random.  The IMU's ensemble update, the
/// moment-matched process noise and E remove or put back that part.
/// Where this departs from the references: Musso et al. regularise after
/// resampling only, with kernel h²·(weighted posterior covariance), which
/// is ~0 when the weights are degenerate; the kernel update is used only
/// when the SIR weights would degenerate (the sampled cross-covariances of
/// statistical linearisation bias the variances of weakly observed
/// components low, so it is kept for the updates that need it); the
/// kernel centres are shrunk (Liu & West) so that the mixture does not
/// inflate the covariance by (1 + h²) per update; the reported covariance
/// is floored by the unweighted cloud's kernel covariance, which the
/// particles cannot resolve below.  The lineage ESS, the moment
/// matching, the factor 2 on E and the uniform weights after an h_u = 1
/// update are ours.
///
/// A run is fixed by its seed: the same numbers on every x86-64 CPU, with or
/// without AVX2 (its hot loops have an AVX2 copy chosen at run time that
/// rounds exactly like the baseline one), unless the core is built with
/// SAFENAV_NATIVE (the compiler may then fuse multiply-adds).
class ParticleFilter {
 public:
  /// Particles are drawn from N(x0, P0) with the given seed.  bandwidth_scale
  /// c ∈ [0, 10] multiplies the optimal kernel bandwidth (0: no regularisation).
  ParticleFilter(const BmmParams& params, const State& x0, const StateCov& P0, int n_particles,
                 std::uint64_t seed, double resample_threshold = 0.5, double bandwidth_scale = 1.0);
  ~ParticleFilter();
  ParticleFilter(ParticleFilter&&) noexcept;
  ParticleFilter& operator=(ParticleFilter&&) noexcept;
  /// Copies (the generator's state included: a copy goes on exactly as the original).
  ParticleFilter(const ParticleFilter&);
  /// Copies the state into this filter's storage (no allocation for the same number of particles).
  ParticleFilter& operator=(const ParticleFilter&);

  int size() const;
  /// Propagate every particle through the noisy BMM [SafeNav eqs. 6–9].
  void predict(const Control& u);
  /// The same over a step of dt seconds (Bmm::with_step).
  void predict(const Control& u, double dt);
  /// NIS gate, as Ekf::set_gate: an update whose NIS (of the weighted-mean
  /// prediction) exceeds the chi-square quantile leaves the weights as they
  /// were and returns accepted = false.  0 (default) disables it.
  void set_gate(double probability);
  double gate() const;
  /// The update of the class comment (SIR or regularised).  Returns the NIS of the
  /// weighted-mean prediction (for diagnostics); resample_count() counts the
  /// resamplings.
  UpdateResult update(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z);
  /// Effective sample size 1/Σw².
  double ess() const;
  int resample_count() const;
  /// Weighted mean (circular mean for θ).
  State mean() const;
  /// The reported covariance: the weighted covariance (angle-wrapped
  /// deviations) times g = ESS/(ESS − 1) of the lineages, floored by
  /// covariance_floor() (see the class comment; the SIR filter reports the
  /// weighted covariance alone).
  StateCov covariance() const;
  /// The same about a given mean (saves recomputing mean()).
  StateCov covariance(const State& about) const;
  /// The weighted covariance of the particles, unfloored.
  StateCov sample_covariance() const;
  /// The floor h²·C_u (C_u: the unweighted covariance of the particles); 0 when h = 0.
  StateCov covariance_floor() const;
  /// The kernel bandwidth h (dimensionless, in [0, 1]).
  double bandwidth() const;
  /// Particles as N×4 (x, y, v, θ) and normalised weights.
  Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> particles() const;
  Eigen::VectorXd weights() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Extended information filter (information form Y = P⁻¹, y = Y x̂), as used
/// with bearing measurements in [Placement §III-A] (standard equations; the
/// paper prints none).
///  predict: x̂ = Y⁻¹y, P⁻ = F Y⁻¹ Fᵀ + Q, Y = (P⁻)⁻¹, y = Y f(x̂, u)
///  update:  Y += Hᵀ R⁻¹ H,  y += Hᵀ R⁻¹ (z ⊖ h(x̂) + H x̂)
class InformationFilter {
 public:
  InformationFilter(const BmmParams& params, const State& x0, const StateCov& P0);
  const Eigen::Vector4d& information_vector() const { return y_; }
  const Eigen::Matrix4d& information_matrix() const { return Y_; }
  State x() const;
  StateCov P() const;
  void predict(const Control& u);
  UpdateResult update(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z);

 private:
  Bmm bmm_;
  Eigen::Vector4d y_;
  Eigen::Matrix4d Y_;
};

// ---------------------------------------------------------------------------
// Batch filtering of a whole trajectory.
// ---------------------------------------------------------------------------

/// Measurements aligned with the N control steps: row k is measured after
/// the k-th prediction.  Each stream is optional (0 rows = absent).  A row of
/// NaN (position, speed_heading) or a NaN entry (ranges, bearings: landmark not
/// seen) marks a gap; any other non-finite value is an error.
struct MeasurementStream {
  RowMatrixX2 position;                          ///< N×2 LanBLoc fixes
  Eigen::Matrix2d position_cov = Eigen::Matrix2d::Identity();
  RowMatrixX2 speed_heading;                     ///< N×2 IMU (v, θ)
  Eigen::Matrix2d speed_heading_cov = Eigen::Matrix2d::Identity();
  RowMatrixXd ranges;                            ///< N×K ranges to `landmarks`
  double range_std = 1.0;
  RowMatrixXd bearings;                          ///< N×K relative bearings to `landmarks`
  double bearing_std = 0.05;
  Landmarks landmarks;                           ///< K×2

  /// Throws std::invalid_argument naming the stream, row and value at fault.
  void validate(int n_steps) const;
};

enum class FilterType { Ekf, ParticleFilter, InformationFilter };

struct FilterOptions {
  FilterType type = FilterType::Ekf;
  int n_particles = 1000;
  double resample_threshold = 0.5;
  std::uint64_t seed = 0;
  double gate_probability = 0.0;  ///< EKF NIS gate (0 = off)
  /// Particle filter regularisation: the kernel bandwidth is bandwidth_scale
  /// times the optimal h_opt = (4/(N(d+2)))^{1/(d+4)} of Musso et al. 2001
  /// (dimensionless, [0, 10]; 0: the plain SIR filter, no jitter and no
  /// covariance floor).  See ParticleFilter.
  double bandwidth_scale = 1.0;
  /// Throws std::invalid_argument naming the first bad field, each name
  /// prefixed with `prefix` (e.g. "settings.filter.").
  void validate(const std::string& prefix = "filter.") const;
};

/// Result of a batch run: estimate after each step's updates (row 0 = prior).
struct FilterRun {
  RowMatrixX4 states;        ///< (N+1)×4
  RowMatrixX16 covariances;  ///< (N+1)×16, row-major 4×4
  Eigen::VectorXd nis;       ///< NIS summed over the step's accepted updates (NaN if none)
  Eigen::VectorXi nis_dof;   ///< degrees of freedom of that NIS
  int n_updates = 0;
  int n_rejected = 0;
  int n_resampled = 0;
  int n_gaps = 0;            ///< steps with no measurement at all (prediction only)
};

/// Filter a whole trajectory in one call (controls N×2 plus a measurement stream).
FilterRun run_filter(const BmmParams& params, const FilterOptions& options, const State& x0,
                     const StateCov& P0, const Eigen::Ref<const RowMatrixX2>& controls,
                     const MeasurementStream& stream);

}  // namespace safenav

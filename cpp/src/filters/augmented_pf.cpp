// The particle-filter counterpart of AugmentedEkf (safenav/augmented.hpp):
// the bootstrap filter over (x, y, v, θ, [k], [β], [b_j]), regularised after
// each resampling as ParticleFilter (regularise.hpp; the method is documented
// at ParticleFilter in safenav/filters.hpp), with d = the augmented state's size.
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "checks.hpp"
#include "regularise.hpp"
#include "../errors.hpp"
#include "../rng.hpp"
#include "safenav/augmented.hpp"

namespace safenav {

namespace {

std::string num(double v) { return detail::num(v, 12); }

void check_variance(double variance, const char* what) {
  if (!(std::isfinite(variance) && variance > 0.0))
    throw std::invalid_argument(std::string("AugmentedParticleFilter ") + what + " update: variance = " +
                                num(variance) + " must be finite and > 0");
}

void check_finite2(const Eigen::Vector2d& z, const char* what) {
  if (!z.allFinite())
    throw std::invalid_argument(std::string("AugmentedParticleFilter ") + what + " update: z = (" + num(z[0]) +
                                ", " + num(z[1]) + ") is not finite");
}

}  // namespace

struct AugmentedParticleFilter::Impl {
  Bmm bmm;
  AugmentedStates aug;
  int K = 0, n = 4, ik = -1, ig = -1, ib0 = -1, N = 0;
  detail::Rng rng;
  double resample_threshold = 0.5;
  Eigen::MatrixXd X, X_next;                 // n × N particles
  Eigen::VectorXd logw, w;                   // log-weights and normalised weights
  Eigen::VectorXd ll;                        // scratch: −log-likelihood of each particle
  Eigen::Matrix<double, 2, Eigen::Dynamic> Y;  // residuals of an update
  double gate_probability = 0.0, thr[3] = {0.0, 0.0, 0.0};
  double ess = 0.0;
  int n_resampled = 0;
  double h = 0.0;                            // kernel bandwidth (0: plain SIR)
  // Regularisation scratch, sized at construction.
  Eigen::VectorXd w_prior, m_prior, m_post, dev, eps;
  Eigen::MatrixXd Sigma, Pk, L;
  Eigen::Matrix<double, Eigen::Dynamic, 2> Cxy;
  std::vector<int> ancestor;                 // the particle each one descends from at the last resampling
  mutable Eigen::VectorXd lineage_w;         // scratch: the weight of each lineage

  /// The particles' vehicle states (the first four rows of X), MeasurementModel::residuals' view.
  StatesView states() const { return StatesView(X.data(), 4, N, Eigen::Stride<Eigen::Dynamic, Eigen::Dynamic>(X.outerStride(), 1)); }
  mutable Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es;
  mutable Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> es4;

  Impl(const BmmParams& p, const AugmentedStates& a, std::uint64_t seed) : bmm(p), aug(a), rng(seed) {}

  void allocate() {
    X.resize(n, N);
    X_next.resize(n, N);
    Y.resize(2, N);
    logw = Eigen::VectorXd::Constant(N, -std::log(static_cast<double>(N)));
    ll.resize(N);
    w = Eigen::VectorXd::Constant(N, 1.0 / N);
    ess = N;
    w_prior.resize(N);
    m_prior.resize(n);
    m_post.resize(n);
    dev.resize(n);
    eps.resize(n);
    Sigma.resize(n, n);
    Pk.resize(n, n);
    L.resize(n, n);
    Cxy.resize(n, 2);
    es = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(n);
    ancestor.resize(N);
    for (int i = 0; i < N; ++i) ancestor[i] = i;
    lineage_w.resize(N);
  }

  /// Mean of the full state under weights u (θ circular).
  void weighted_mean(const Eigen::VectorXd& u, Eigen::VectorXd& m) const {
    m.noalias() = X * u;
    double c = 0.0, s = 0.0;
    for (int i = 0; i < N; ++i) {
      c += u[i] * std::cos(X(kTheta, i));
      s += u[i] * std::sin(X(kTheta, i));
    }
    m[kTheta] = std::atan2(s, c);
  }

  /// dev = X.col(i) − m, θ wrapped.
  void deviation(int i, const Eigen::VectorXd& m) {
    dev = X.col(i) - m;
    dev[kTheta] = wrap_angle(dev[kTheta]);
  }

  /// Σ⁻ and C_xy over the prior weights (Y holds M residual rows; ȳ their prior-weighted mean).
  template <int M>
  void prior_moments(const Eigen::Matrix<double, M, 1>& ybar) {
    weighted_mean(w_prior, m_prior);
    Sigma.setZero();
    Cxy.setZero();
    for (int i = 0; i < N; ++i) {
      deviation(i, m_prior);
      Sigma.noalias() += (w_prior[i] * dev) * dev.transpose();
      Cxy.leftCols<M>().noalias() += (w_prior[i] * dev) * (Y.template block<M, 1>(0, i) - ybar).transpose();
    }
  }

  /// After a resampling: x_i ← m + a(x_i − m) + d_i − d̄, d_i = L ε_i, d̄ their
  /// mean (centred: the jitter moves no mean; regularise.hpp), v clamped to
  /// [v_min, v_max], θ wrapped.  X_next (the set before resampling) is scratch.
  void regularise() {
    detail::psd_factor(Pk, es, L);
    const double a = std::sqrt(std::max(0.0, 1.0 - h * h));
    const double vmax = bmm.params().max_speed;
    for (int i = 0; i < N; ++i) {
      for (int r = 0; r < n; ++r) eps[r] = rng.normal();
      X_next.col(i).noalias() = L * eps;
    }
    const Eigen::VectorXd dbar = X_next.rowwise().mean();
    for (int i = 0; i < N; ++i) {
      deviation(i, m_post);
      X.col(i) = m_post + a * dev + X_next.col(i) - dbar;
      X(kV, i) = std::clamp(X(kV, i), bmm.params().min_speed(), vmax);
      X(kTheta, i) = wrap_angle(X(kTheta, i));
    }
  }

  /// The lineages' effective sample size 1/Σ_a W_a² (W_a: the weight of the
  /// descendants of particle a of the last resampling; ParticleFilter's).
  double lineage_ess() const {
    lineage_w.setZero();
    for (int i = 0; i < N; ++i) lineage_w[ancestor[i]] += w[i];
    return 1.0 / lineage_w.squaredNorm();
  }

  /// The weighted covariance of the full state about the weighted mean (θ wrapped) into Sigma.
  void posterior_covariance() {
    weighted_mean(w, m_post);
    Sigma.setZero();
    for (int i = 0; i < N; ++i) {
      deviation(i, m_post);
      Sigma.noalias() += (w[i] * dev) * dev.transpose();
    }
  }

  void check_row(int row, const char* what) const {
    if (row < 0 || row >= K)
      throw std::invalid_argument(std::string("AugmentedParticleFilter ") + what + ": landmark row " +
                                  std::to_string(row) + " is not in [0, " + std::to_string(K) + ")");
  }

  void normalise() {
    const double mx = logw.maxCoeff();
    double sum = 0.0;
    for (int i = 0; i < N; ++i) sum += (w[i] = std::exp(logw[i] - mx));
    double s2 = 0.0;
    const double ls = mx + std::log(sum);
    for (int i = 0; i < N; ++i) {
      w[i] /= sum;
      logw[i] -= ls;
      s2 += w[i] * w[i];
    }
    ess = 1.0 / s2;
  }

  /// Systematic resampling: pointers (j + U)/N, j = 0..N−1.
  void resample() {
    const double U = rng.uniform();
    double c = w[0];
    int i = 0;
    for (int j = 0; j < N; ++j) {
      const double u = (j + U) / N;
      while (u > c && i < N - 1) c += w[++i];
      X_next.col(j) = X.col(i);
      ancestor[j] = i;
    }
    X.swap(X_next);
    logw.setConstant(-std::log(static_cast<double>(N)));
    w.setConstant(1.0 / N);
    ess = N;
    ++n_resampled;
  }

  /// Gate on the NIS of the weighted-mean residual, then weight by the likelihood (Y filled for M rows).
  template <int M>
  UpdateResult weigh(const Eigen::Matrix<double, M, M>& R, MeasurementKind kind) {
    using VecM = Eigen::Matrix<double, M, 1>;
    using MatMM = Eigen::Matrix<double, M, M>;
    VecM ybar = VecM::Zero();
    for (int i = 0; i < N; ++i) ybar += w[i] * Y.template block<M, 1>(0, i);
    MatMM S = R;
    for (int i = 0; i < N; ++i) {
      const VecM d = Y.template block<M, 1>(0, i) - ybar;
      S += w[i] * d * d.transpose();
    }
    UpdateResult res;
    res.dim = M;
    // A residual spread that overflows (a measurement ~1e154 from the
    // particles) would give S = inf and a NIS of 0: refuse it, as check_nis.
    if (!(S.allFinite() && ybar.allFinite())) check_nis(std::numeric_limits<double>::infinity(), "AugmentedParticleFilter", kind);
    const Eigen::LDLT<MatMM> ldlt(S);
    res.nis = ybar.dot(ldlt.solve(ybar));
    res.log_det_s = ldlt.vectorD().array().log().sum();
    check_nis(res.nis, "AugmentedParticleFilter", kind);
    check_log_det_s(res.log_det_s, "AugmentedParticleFilter", kind);
    if (gate_probability > 0.0 && res.nis > thr[M]) {
      res.accepted = false;
      return res;
    }
    if (h > 0.0) w_prior = w;
    const MatMM Ri = R.inverse();
    for (int i = 0; i < N; ++i) {
      const VecM y = Y.template block<M, 1>(0, i);
      ll[i] = 0.5 * y.dot(Ri * y);
    }
    // Every log-likelihood finite, and one particle's at least representable
    // against the others, before the weights change.
    if (!ll.allFinite())
      throw std::invalid_argument(std::string("AugmentedParticleFilter ") + to_string(kind) +
                                  " update: a particle's log-likelihood overflows (the measurement is too far "
                                  "from the particles for its covariance)");
    logw -= ll;
    normalise();
    if (ess < resample_threshold * N) {
      if (h > 0.0) {  // the prior cloud's kernel conditioned on z (regularise.hpp)
        prior_moments<M>(ybar);
        const MatMM Cyy = S - R;
        Pk = detail::conditioned_kernel(Sigma, Eigen::MatrixXd(Cxy.leftCols<M>()), Eigen::MatrixXd(Cyy),
                                        Eigen::MatrixXd(R), h);
        // + the Monte Carlo variance that resampling would lose (monte_carlo_gain)
        posterior_covariance();
        Pk += (detail::monte_carlo_gain(lineage_ess()) - 1.0) * Sigma;
      }
      resample();
      if (h > 0.0) regularise();
    }
    return res;
  }

  /// The landmark observation model (safenav/measurement.hpp) at particle i.
  double range_h(int i, int row, const Eigen::Vector2d& a) const {
    const double k = ik >= 0 ? X(ik, i) : 0.0, b = ib0 >= 0 ? X(ib0 + row, i) : 0.0;
    return predict_range(landmark_geometry(X(kX, i), X(kY, i), a.x(), a.y()), k, b);
  }
  double bearing_h(int i, const Eigen::Vector2d& a) const {
    return predict_bearing(landmark_geometry(X(kX, i), X(kY, i), a.x(), a.y()), X(kTheta, i));
  }
};

AugmentedParticleFilter::AugmentedParticleFilter(const BmmParams& params, const AugmentedStates& augment,
                                                 int n_landmarks, const State& x0, const StateCov& P0,
                                                 int n_particles, std::uint64_t seed, double resample_threshold,
                                                 double bandwidth_scale)
    : impl_(std::make_unique<Impl>(params, augment, seed)) {
  Impl& I = *impl_;
  I.aug.validate();
  if (n_landmarks < 0)
    throw std::invalid_argument("AugmentedParticleFilter: n_landmarks = " + std::to_string(n_landmarks) + " must be >= 0");
  if (n_particles < 1)
    throw std::invalid_argument("AugmentedParticleFilter: n_particles = " + std::to_string(n_particles) + " must be >= 1");
  if (!(std::isfinite(resample_threshold) && resample_threshold >= 0.0 && resample_threshold <= 1.0))
    throw std::invalid_argument("AugmentedParticleFilter: resample_threshold = " + num(resample_threshold) +
                                " must be in [0, 1]");
  if (!(std::isfinite(bandwidth_scale) && bandwidth_scale >= 0.0 && bandwidth_scale <= 10.0))
    throw std::invalid_argument("AugmentedParticleFilter: bandwidth_scale = " + num(bandwidth_scale) +
                                " must be in [0, 10] (0: no regularisation)");
  check_prior(x0, P0);
  I.K = n_landmarks;
  I.N = n_particles;
  I.resample_threshold = resample_threshold;
  int n = 4;
  if (I.aug.range_scale) I.ik = n++;
  if (I.aug.heading_rate_bias) I.ig = n++;
  if (I.aug.range_bias) {
    I.ib0 = n;
    n += n_landmarks;
  }
  I.n = n;
  I.h = detail::kernel_bandwidth(I.N, n, bandwidth_scale);
  I.allocate();
  const Eigen::Matrix4d L = P0.llt().matrixL();
  for (int i = 0; i < I.N; ++i) {
    Eigen::Vector4d z;
    for (int r = 0; r < 4; ++r) z[r] = I.rng.normal();
    I.X.col(i).head<4>() = x0 + L * z;
    I.X(kTheta, i) = wrap_angle(I.X(kTheta, i));
    if (I.ik >= 0) I.X(I.ik, i) = I.aug.scale_prior + I.aug.scale_std * I.rng.normal();
    if (I.ig >= 0) I.X(I.ig, i) = I.aug.heading_rate_bias_prior + I.aug.heading_rate_bias_std * I.rng.normal();
    for (int j = 0; I.ib0 >= 0 && j < n_landmarks; ++j) I.X(I.ib0 + j, i) = I.aug.range_bias_std * I.rng.normal();
  }
}

AugmentedParticleFilter::~AugmentedParticleFilter() = default;
AugmentedParticleFilter::AugmentedParticleFilter(AugmentedParticleFilter&&) noexcept = default;
AugmentedParticleFilter& AugmentedParticleFilter::operator=(AugmentedParticleFilter&&) noexcept = default;
AugmentedParticleFilter::AugmentedParticleFilter(const AugmentedParticleFilter& o)
    : impl_(std::make_unique<Impl>(*o.impl_)) {}
AugmentedParticleFilter& AugmentedParticleFilter::operator=(const AugmentedParticleFilter& o) {
  if (this != &o) *impl_ = *o.impl_;
  return *this;
}

int AugmentedParticleFilter::size() const { return impl_->N; }
int AugmentedParticleFilter::state_size() const { return impl_->n; }
int AugmentedParticleFilter::scale_index() const { return impl_->ik; }
int AugmentedParticleFilter::heading_rate_bias_index() const { return impl_->ig; }
double AugmentedParticleFilter::gate() const { return impl_->gate_probability; }
double AugmentedParticleFilter::ess() const { return impl_->ess; }
int AugmentedParticleFilter::resample_count() const { return impl_->n_resampled; }
const Eigen::MatrixXd& AugmentedParticleFilter::particles() const { return impl_->X; }
Eigen::VectorXd AugmentedParticleFilter::weights() const { return impl_->w; }

void AugmentedParticleFilter::set_gate(double probability) {
  if (!(std::isfinite(probability) && probability >= 0.0 && probability < 1.0))
    throw std::invalid_argument("gate probability = " + num(probability) + " must be in [0, 1) (0 disables the gate)");
  impl_->gate_probability = probability;
  if (probability > 0.0) {
    impl_->thr[1] = chi2_quantile(probability, 1);
    impl_->thr[2] = chi2_quantile(probability, 2);
  }
}

void AugmentedParticleFilter::predict(const Control& u, double dt) {
  Impl& I = *impl_;
  if (!(std::isfinite(dt) && dt > 0.0))
    throw std::invalid_argument("AugmentedParticleFilter predict: dt = " + num(dt) + " s must be finite and > 0");
  if (!u.allFinite())
    throw std::invalid_argument("AugmentedParticleFilter predict: control (" + num(u[0]) + ", " + num(u[1]) +
                                ") is not finite");
  const Bmm step = I.bmm.is_nominal_step(dt) ? I.bmm : I.bmm.with_step(dt);
  const Eigen::Vector4d sigma = step.noise_cov().diagonal().cwiseSqrt();
  const double sq = std::sqrt(dt);
  for (int i = 0; i < I.N; ++i) {
    State xs = I.X.col(i).head<4>();
    if (I.ig >= 0) xs[kTheta] -= I.X(I.ig, i) * dt;
    Eigen::Vector4d eps;
    for (int r = 0; r < 4; ++r) eps[r] = sigma[r] * I.rng.normal();
    I.X.col(i).head<4>() = step.transition(xs, u, eps);  // eqs. 6, 7, 9 at θ − β·dt
    if (I.ik >= 0) I.X(I.ik, i) += I.aug.scale_walk * sq * I.rng.normal();
    if (I.ig >= 0) I.X(I.ig, i) += I.aug.heading_rate_bias_walk * sq * I.rng.normal();
    for (int j = 0; I.ib0 >= 0 && j < I.K; ++j) I.X(I.ib0 + j, i) += I.aug.range_bias_walk * sq * I.rng.normal();
  }
}

UpdateResult AugmentedParticleFilter::update_range(int row, const Eigen::Vector2d& a, double r, double variance) {
  Impl& I = *impl_;
  I.check_row(row, "range update");
  if (!a.allFinite()) throw std::invalid_argument("AugmentedParticleFilter range update: the landmark position is not finite");
  if (!std::isfinite(r)) throw std::invalid_argument("AugmentedParticleFilter range update: r = " + num(r) + " is not finite");
  check_variance(variance, "range");
  for (int i = 0; i < I.N; ++i) I.Y(0, i) = r - I.range_h(i, row, a);
  return I.weigh<1>(Eigen::Matrix<double, 1, 1>(variance), MeasurementKind::Range);
}

UpdateResult AugmentedParticleFilter::update_bearing(int row, const Eigen::Vector2d& a, double bearing, double variance) {
  Impl& I = *impl_;
  I.check_row(row, "bearing update");
  if (!a.allFinite()) throw std::invalid_argument("AugmentedParticleFilter bearing update: the landmark position is not finite");
  if (!std::isfinite(bearing))
    throw std::invalid_argument("AugmentedParticleFilter bearing update: bearing = " + num(bearing) + " is not finite");
  check_variance(variance, "bearing");
  for (int i = 0; i < I.N; ++i) I.Y(0, i) = wrap_angle(bearing - I.bearing_h(i, a));
  return I.weigh<1>(Eigen::Matrix<double, 1, 1>(variance), MeasurementKind::Bearing);
}

UpdateResult AugmentedParticleFilter::update_range_bearing(int row, const Eigen::Vector2d& a, const Eigen::Vector2d& z,
                                                           const Eigen::Matrix2d& R) {
  Impl& I = *impl_;
  I.check_row(row, "range-bearing update");
  if (!a.allFinite()) throw std::invalid_argument("AugmentedParticleFilter range-bearing update: the landmark position is not finite");
  check_finite2(z, "range-bearing");
  check_cov2(R, "AugmentedParticleFilter range-bearing update:");
  for (int i = 0; i < I.N; ++i) {
    I.Y(0, i) = z[0] - I.range_h(i, row, a);
    I.Y(1, i) = wrap_angle(z[1] - I.bearing_h(i, a));
  }
  return I.weigh<2>(R, MeasurementKind::RangeBearing);
}

UpdateResult AugmentedParticleFilter::update_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  Impl& I = *impl_;
  check_finite2(z, "position");
  check_cov2(R, "AugmentedParticleFilter position update:");
  MeasurementModel::direct_residuals(MeasurementKind::Position, z, I.states(), I.Y);
  return I.weigh<2>(R, MeasurementKind::Position);
}

UpdateResult AugmentedParticleFilter::update_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  Impl& I = *impl_;
  check_finite2(z, "speed-heading");
  check_cov2(R, "AugmentedParticleFilter speed-heading update:");
  MeasurementModel::direct_residuals(MeasurementKind::SpeedHeading, z, I.states(), I.Y);
  return I.weigh<2>(R, MeasurementKind::SpeedHeading);
}

State AugmentedParticleFilter::mean() const {
  const Impl& I = *impl_;
  State m = State::Zero();
  double c = 0.0, s = 0.0;
  for (int i = 0; i < I.N; ++i) {
    m.head<3>() += I.w[i] * I.X.col(i).head<3>();
    c += I.w[i] * std::cos(I.X(kTheta, i));
    s += I.w[i] * std::sin(I.X(kTheta, i));
  }
  m[kTheta] = std::atan2(s, c);
  return m;
}

StateCov AugmentedParticleFilter::sample_covariance() const {
  const Impl& I = *impl_;
  const State m = mean();
  StateCov P = StateCov::Zero();
  for (int i = 0; i < I.N; ++i) {
    State d = I.X.col(i).head<4>() - m;
    d[kTheta] = wrap_angle(d[kTheta]);
    P += I.w[i] * d * d.transpose();
  }
  return P;
}

StateCov AugmentedParticleFilter::covariance_floor() const {
  // h²·C_u: the unweighted covariance of (x, y, v, θ) about the unweighted mean (θ circular).
  const Impl& I = *impl_;
  State m = State::Zero();
  double c = 0.0, s = 0.0;
  for (int i = 0; i < I.N; ++i) {
    m.head<3>() += I.X.col(i).head<3>();
    c += std::cos(I.X(kTheta, i));
    s += std::sin(I.X(kTheta, i));
  }
  m.head<3>() /= I.N;
  m[kTheta] = std::atan2(s, c);
  StateCov C = StateCov::Zero();
  for (int i = 0; i < I.N; ++i) {
    State d = I.X.col(i).head<4>() - m;
    d[kTheta] = wrap_angle(d[kTheta]);
    C += d * d.transpose();
  }
  return (I.h * I.h / I.N) * C;
}

StateCov AugmentedParticleFilter::covariance() const {
  const StateCov P = sample_covariance();
  if (impl_->h <= 0.0) return P;
  const double g = detail::monte_carlo_gain(impl_->lineage_ess());  // regularise.hpp
  return detail::loewner_floor(StateCov(g * P), covariance_floor(), impl_->es4);
}

double AugmentedParticleFilter::bandwidth() const { return impl_->h; }

Eigen::VectorXd AugmentedParticleFilter::augmented() const {
  const Impl& I = *impl_;
  Eigen::VectorXd m = I.X * I.w;
  m.head<4>() = mean();
  return m;
}

}  // namespace safenav

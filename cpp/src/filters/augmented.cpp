// EKF over the BMM with augmented sensor-error states (safenav/augmented.hpp).
#include "safenav/augmented.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

#include "checks.hpp"
#include "kalman_update.hpp"
#include "../errors.hpp"
#include "../rng.hpp"
#include "safenav/params.hpp"

namespace safenav {

namespace {

std::string num(double v) { return detail::num(v, 12); }

void check_variance(double variance, const char* what) {
  if (!(std::isfinite(variance) && variance > 0.0))
    throw std::invalid_argument(std::string("AugmentedEkf ") + what + " update: variance = " + num(variance) +
                                " must be finite and > 0");
}

void check_finite2(const Eigen::Vector2d& z, const char* what) {
  if (!z.allFinite())
    throw std::invalid_argument(std::string("AugmentedEkf ") + what + " update: z = (" + num(z[0]) + ", " +
                                num(z[1]) + ") is not finite");
}

}  // namespace

AugmentedEkf::AugmentedEkf(const BmmParams& params, const AugmentedStates& augment, int n_landmarks,
                           const State& x0, const StateCov& P0)
    : bmm_(params), augment_(augment), n_landmarks_(n_landmarks) {
  augment_.validate();
  if (n_landmarks < 0)
    throw std::invalid_argument("AugmentedEkf: n_landmarks = " + std::to_string(n_landmarks) + " must be >= 0");
  check_prior(x0, P0);
  int n = 4;
  if (augment_.range_scale) ik_ = n++;
  if (augment_.heading_rate_bias) ig_ = n++;
  if (augment_.range_bias) {
    ib0_ = n;
    n += n_landmarks;
  }
  n_ = n;
  x_ = Eigen::VectorXd::Zero(n);
  P_ = Eigen::MatrixXd::Zero(n, n);
  x_.head<4>() = x0;
  x_[kTheta] = wrap_angle(x0[kTheta]);
  P_.topLeftCorner<4, 4>() = P0;
  if (ik_ >= 0) {
    x_[ik_] = augment_.scale_prior;
    P_(ik_, ik_) = augment_.scale_std * augment_.scale_std;
  }
  if (ig_ >= 0) {
    x_[ig_] = augment_.heading_rate_bias_prior;
    P_(ig_, ig_) = augment_.heading_rate_bias_std * augment_.heading_rate_bias_std;
  }
  for (int j = 0; ib0_ >= 0 && j < n_landmarks; ++j) P_(ib0_ + j, ib0_ + j) = augment_.range_bias_std * augment_.range_bias_std;
  if (!P_.allFinite() || P_.diagonal().minCoeff() <= 0.0)
    throw std::invalid_argument("AugmentedEkf: every augmented state needs a prior sigma > 0 (augment.*_std)");
  JP_.resize(4, n);
  H_.resize(2, n);
  PHt_.resize(n, 2);
  K_.resize(n, 2);
  KR_.resize(n, 2);
  AHt_.resize(n, 2);
  P1_.resize(n, n);
  x1_.resize(n);
  sync4();
}

void AugmentedEkf::sync4() {
  x4_ = x_.head<4>();
  P4_ = P_.topLeftCorner<4, 4>();
}

void AugmentedEkf::set_state(const Eigen::VectorXd& x, const Eigen::MatrixXd& P) {
  if (x.size() != n_ || P.rows() != n_ || P.cols() != n_)
    throw std::invalid_argument("AugmentedEkf.set_state: x must have " + std::to_string(n_) + " entries and P be " +
                                std::to_string(n_) + "x" + std::to_string(n_) + ", got " + std::to_string(x.size()) +
                                " and " + std::to_string(P.rows()) + "x" + std::to_string(P.cols()));
  for (int i = 0; i < n_; ++i)
    if (!std::isfinite(x[i])) throw std::invalid_argument("AugmentedEkf.set_state: x[" + std::to_string(i) + "] = " + num(x[i]) + " is not finite");
  check_covariance(P, "AugmentedEkf.set_state P");
  x_ = x;
  x_[kTheta] = wrap_angle(x_[kTheta]);
  P_ = P;
  sync4();
}

int AugmentedEkf::range_bias_index(int landmark_row) const {
  check_row(landmark_row, "range_bias_index");
  return ib0_ >= 0 ? ib0_ + landmark_row : -1;
}

void AugmentedEkf::check_row(int row, const char* what) const {
  if (row < 0 || row >= n_landmarks_)
    throw std::invalid_argument(std::string("AugmentedEkf ") + what + ": landmark row " + std::to_string(row) +
                                " is not in [0, " + std::to_string(n_landmarks_) + ")");
}

void AugmentedEkf::set_gate(double probability) {
  if (!(std::isfinite(probability) && probability >= 0.0 && probability < 1.0))
    throw std::invalid_argument("gate probability = " + num(probability) + " must be in [0, 1) (0 disables the gate)");
  gate_probability_ = probability;
  if (probability > 0.0) {
    gate_threshold_[1] = chi2_quantile(probability, 1);
    gate_threshold_[2] = chi2_quantile(probability, 2);
  }
}

void AugmentedEkf::predict(const Control& u, double dt) {
  // Eq. 11.  The BMM (eqs. 3–9) of Bmm::with_step(dt) evaluated at θ − β·dt
  // gives θ' = θ + clip(Δθ) − β·dt and p' moving along that θ' (eq. 7), with
  // F₄ = ∂f/∂(x, y, v, θ) and G = ∂f/∂ε; then ∂f/∂β = −dt·∂f/∂θ.
  if (!(std::isfinite(dt) && dt > 0.0))
    throw std::invalid_argument("AugmentedEkf predict: dt = " + num(dt) + " s must be finite and > 0");
  const Bmm step = bmm_.is_nominal_step(dt) ? bmm_ : bmm_.with_step(dt);
  const double beta = ig_ >= 0 ? x_[ig_] : 0.0;
  State xs = x4_;
  xs[kTheta] = x4_[kTheta] - beta * dt;
  Eigen::Matrix4d F4, G;
  const State x1 = step.linearize(xs, u, &F4, &G);
  const Eigen::Vector4d Fb = -dt * F4.col(kTheta);  // ∂f/∂β
  // F = [F₄ Fβ 0; 0 I]: only rows 0..3 change.  JP = rows 0..3 of F P.
  JP_.noalias() = F4 * P_.topRows<4>();
  if (ig_ >= 0) JP_.noalias() += Fb * P_.row(ig_);
  Eigen::Matrix4d TL = JP_.leftCols<4>() * F4.transpose();
  if (ig_ >= 0) TL.noalias() += JP_.col(ig_) * Fb.transpose();
  TL.noalias() += G * step.noise_cov() * G.transpose();
  TL = 0.5 * (TL + TL.transpose()).eval();
  if (!(TL.allFinite() && JP_.allFinite() && x1.allFinite()))
    throw std::invalid_argument("AugmentedEkf predict: the predicted state or covariance is not finite (dt = " +
                                num(dt) + ", u = (" + num(u[0]) + ", " + num(u[1]) + "))");
  // Commit: the right part of rows 0..3 (and its transpose) is JP's, the
  // augmented block keeps P plus its random walks.
  const int na = n_ - 4;
  if (na > 0) {
    P_.topRightCorner(4, na) = JP_.rightCols(na);
    P_.bottomLeftCorner(na, 4) = JP_.rightCols(na).transpose();
  }
  P_.topLeftCorner<4, 4>() = TL;
  if (ik_ >= 0) P_(ik_, ik_) += augment_.scale_walk * augment_.scale_walk * dt;
  if (ig_ >= 0) P_(ig_, ig_) += augment_.heading_rate_bias_walk * augment_.heading_rate_bias_walk * dt;
  if (ib0_ >= 0)
    for (int j = 0; j < n_landmarks_; ++j)
      P_(ib0_ + j, ib0_ + j) += augment_.range_bias_walk * augment_.range_bias_walk * dt;
  x_.head<4>() = x1;
  sync4();
}

LandmarkGeometry AugmentedEkf::geometry(const Eigen::Vector2d& a, const char* what) const {
  const LandmarkGeometry g = landmark_geometry(x_[kX], x_[kY], a.x(), a.y());
  if (!g.finite())
    throw std::invalid_argument(std::string("AugmentedEkf ") + what + " update: the landmark (" + num(a.x()) + ", " +
                                num(a.y()) + ") is farther than 1.8e308 from the estimate");
  if (!g.defined())
    throw std::domain_error(std::string("AugmentedEkf ") + what +
                            " update: the estimate is at the landmark (Jacobian undefined)");
  return g;
}

void AugmentedEkf::set_row(int r, int landmark_row, const LandmarkJacobian& J) {
  // The model's Jacobian by state block, into row r of H (∂h/∂v = 0, other b_j 0).
  H_.row(r).setZero();
  H_(r, kX) = J.x;
  H_(r, kY) = J.y;
  H_(r, kTheta) = J.theta;
  if (ik_ >= 0) H_(r, ik_) = J.k;
  if (ib0_ >= 0) H_(r, ib0_ + landmark_row) = J.b;
}

double AugmentedEkf::range_row(int row, const Eigen::Vector2d& a, int r) {
  const LandmarkGeometry g = geometry(a, "range");
  LandmarkJacobian J;
  const double h = predict_range(g, ik_ >= 0 ? x_[ik_] : 0.0, ib0_ >= 0 ? x_[ib0_ + row] : 0.0, &J);
  set_row(r, row, J);
  return h;
}

double AugmentedEkf::bearing_row(int row, const Eigen::Vector2d& a, int r) {
  const LandmarkGeometry g = geometry(a, "bearing");
  LandmarkJacobian J;
  const double h = predict_bearing(g, x_[kTheta], &J);
  set_row(r, row, J);
  return h;
}

template <int M>
UpdateResult AugmentedEkf::apply(const Eigen::Matrix<double, M, 1>& y, const Eigen::Matrix<double, M, M>& R,
                                 MeasurementKind kind) {
  // [SafeNav eqs. 12–14] in Joseph form: the update shared with Ekf (kalman_update.hpp), in scratch sized once.
  const auto rejects = [this](double nis, int) { return gate_probability_ > 0.0 && nis > gate_threshold_[M]; };
  const UpdateResult res = kalman_update<M>("AugmentedEkf", kind, x_, P_, y, H_.template topRows<M>(), R, rejects,
                                            KalmanWork{PHt_, K_, KR_, AHt_, P1_, x1_});
  if (!res.accepted) return res;
  if (!(P1_.allFinite() && x1_.allFinite()))
    throw std::invalid_argument(std::string("AugmentedEkf ") + to_string(kind) +
                                " update: the updated state or covariance is not finite");
  x_.swap(x1_);
  P_.swap(P1_);
  sync4();
  return res;
}

UpdateResult AugmentedEkf::update_range(int landmark_row, const Eigen::Vector2d& landmark, double r, double variance) {
  check_row(landmark_row, "range update");
  if (!landmark.allFinite()) throw std::invalid_argument("AugmentedEkf range update: the landmark position is not finite");
  if (!std::isfinite(r)) throw std::invalid_argument("AugmentedEkf range update: r = " + num(r) + " is not finite");
  check_variance(variance, "range");
  const double h = range_row(landmark_row, landmark, 0);
  return apply<1>(Eigen::Matrix<double, 1, 1>(r - h), Eigen::Matrix<double, 1, 1>(variance), MeasurementKind::Range);
}

UpdateResult AugmentedEkf::update_bearing(int landmark_row, const Eigen::Vector2d& landmark, double bearing,
                                          double variance) {
  check_row(landmark_row, "bearing update");
  if (!landmark.allFinite()) throw std::invalid_argument("AugmentedEkf bearing update: the landmark position is not finite");
  if (!std::isfinite(bearing)) throw std::invalid_argument("AugmentedEkf bearing update: bearing = " + num(bearing) + " is not finite");
  check_variance(variance, "bearing");
  const double h = bearing_row(landmark_row, landmark, 0);
  return apply<1>(Eigen::Matrix<double, 1, 1>(wrap_angle(bearing - h)), Eigen::Matrix<double, 1, 1>(variance),
                  MeasurementKind::Bearing);
}

UpdateResult AugmentedEkf::update_range_bearing(int landmark_row, const Eigen::Vector2d& landmark,
                                                const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  check_row(landmark_row, "range-bearing update");
  if (!landmark.allFinite()) throw std::invalid_argument("AugmentedEkf range-bearing update: the landmark position is not finite");
  check_finite2(z, "range-bearing");
  check_cov2(R, "AugmentedEkf range-bearing update:");
  const double hr = range_row(landmark_row, landmark, 0);
  const double hb = bearing_row(landmark_row, landmark, 1);
  return apply<2>(Eigen::Vector2d(z[0] - hr, wrap_angle(z[1] - hb)), R, MeasurementKind::RangeBearing);
}

UpdateResult AugmentedEkf::update_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  check_finite2(z, "position");
  check_cov2(R, "AugmentedEkf position update:");
  H_.setZero();
  H_(0, kX) = 1.0;
  H_(1, kY) = 1.0;
  return apply<2>(Eigen::Vector2d(z[0] - x_[kX], z[1] - x_[kY]), R, MeasurementKind::Position);
}

UpdateResult AugmentedEkf::update_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  check_finite2(z, "speed-heading");
  check_cov2(R, "AugmentedEkf speed-heading update:");
  H_.setZero();
  H_(0, kV) = 1.0;
  H_(1, kTheta) = 1.0;
  return apply<2>(Eigen::Vector2d(z[0] - x_[kV], wrap_angle(z[1] - x_[kTheta])), R, MeasurementKind::SpeedHeading);
}

// ---------------------------------------------------------------------------
// AugmentedParticleFilter

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

  Impl(const BmmParams& p, const AugmentedStates& a, std::uint64_t seed) : bmm(p), aug(a), rng(seed) {}

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
    check_nis(res.nis, "AugmentedParticleFilter", kind);
    if (gate_probability > 0.0 && res.nis > thr[M]) {
      res.accepted = false;
      return res;
    }
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
    if (ess < resample_threshold * N) resample();
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
                                                 int n_particles, std::uint64_t seed, double resample_threshold)
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
  I.X.resize(n, I.N);
  I.X_next.resize(n, I.N);
  I.Y.resize(2, I.N);
  I.logw = Eigen::VectorXd::Constant(I.N, -std::log(static_cast<double>(I.N)));
  I.ll.resize(I.N);
  I.w = Eigen::VectorXd::Constant(I.N, 1.0 / I.N);
  I.ess = I.N;
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
  for (int i = 0; i < I.N; ++i) I.Y.col(i) = z - I.X.col(i).head<2>();
  return I.weigh<2>(R, MeasurementKind::Position);
}

UpdateResult AugmentedParticleFilter::update_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  Impl& I = *impl_;
  check_finite2(z, "speed-heading");
  check_cov2(R, "AugmentedParticleFilter speed-heading update:");
  for (int i = 0; i < I.N; ++i) {
    I.Y(0, i) = z[0] - I.X(kV, i);
    I.Y(1, i) = wrap_angle(z[1] - I.X(kTheta, i));
  }
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

StateCov AugmentedParticleFilter::covariance() const {
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

Eigen::VectorXd AugmentedParticleFilter::augmented() const {
  const Impl& I = *impl_;
  Eigen::VectorXd m = I.X * I.w;
  m.head<4>() = mean();
  return m;
}

}  // namespace safenav

#include "safenav/filters.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <boost/math/distributions/chi_squared.hpp>
#include <cmath>
#include <functional>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "rng.hpp"

namespace safenav {

// --------------------------------------------------------------------------
// helpers
// --------------------------------------------------------------------------

void check_covariance(const Eigen::MatrixXd& P, const char* what) {
  std::ostringstream os;
  if (P.rows() != P.cols()) {
    os << what << " must be square, got " << P.rows() << "x" << P.cols();
    throw std::invalid_argument(os.str());
  }
  if (!P.allFinite()) {
    os << what << " has non-finite entries:\n" << P;
    throw std::invalid_argument(os.str());
  }
  const double scale = std::max(1e-300, P.cwiseAbs().maxCoeff());
  if ((P - P.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
    os << what << " is not symmetric:\n" << P;
    throw std::invalid_argument(os.str());
  }
  Eigen::LLT<Eigen::MatrixXd> llt(P);
  if (llt.info() != Eigen::Success) {
    os << what << " is not positive definite:\n" << P;
    throw std::invalid_argument(os.str());
  }
}

double chi2_quantile(double probability, int dof) {
  if (!(probability > 0.0 && probability < 1.0)) {
    std::ostringstream os;
    os << "chi-square probability = " << probability << " must be in (0, 1)";
    throw std::invalid_argument(os.str());
  }
  if (dof < 1) throw std::invalid_argument("chi-square degrees of freedom must be >= 1, got " + std::to_string(dof));
  return boost::math::quantile(boost::math::chi_squared(dof), probability);
}

namespace {
void check_gate(double p) {
  if (!(std::isfinite(p) && p >= 0.0 && p < 1.0)) {
    std::ostringstream os;
    os << "gate probability = " << p << " must be in [0, 1) (0 disables the gate)";
    throw std::invalid_argument(os.str());
  }
}
void check_prior(const State& x0, const StateCov& P0, const char* xname = "x0", const char* pname = "P0") {
  check_finite_state(x0, xname);
  check_covariance(P0, pname);
}
}  // namespace

// --------------------------------------------------------------------------
// EKF
// --------------------------------------------------------------------------

Ekf::Ekf(const BmmParams& params, const State& x0, const StateCov& P0) : bmm_(params) {
  check_prior(x0, P0);
  x_ = x0;
  x_[kTheta] = wrap_angle(x_[kTheta]);
  P_ = P0;
}

void Ekf::set_state(const State& x, const StateCov& P) {
  check_prior(x, P, "x", "P");
  x_ = x;
  x_[kTheta] = wrap_angle(x_[kTheta]);
  P_ = P;
}

void Ekf::set_gate(double probability) {
  check_gate(probability);
  gate_probability_ = probability;
  gate_thresholds_.clear();
}

bool Ekf::gate_rejects(double nis, int dim) {
  if (gate_probability_ <= 0.0) return false;
  if (static_cast<int>(gate_thresholds_.size()) <= dim) gate_thresholds_.resize(dim + 1, -1.0);
  double& t = gate_thresholds_[dim];
  if (t < 0.0) t = chi2_quantile(gate_probability_, dim);
  return nis > t;
}

void Ekf::predict(const Control& u) {
  // Eq. 11: x̂ = f(x̂, u); P = F P Fᵀ + G Σ_ε Gᵀ.
  Eigen::Matrix4d F, G;
  x_ = bmm_.linearize(x_, u, &F, &G);
  const Eigen::Vector4d sigma2 = bmm_.noise_cov().diagonal();
  P_ = F * P_ * F.transpose() + G * sigma2.asDiagonal() * G.transpose();
  P_ = 0.5 * (P_ + P_.transpose());
}

template <int M>
UpdateResult Ekf::update_fixed(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
  using VecM = Eigen::Matrix<double, M, 1>;
  using MatM4 = Eigen::Matrix<double, M, 4>;
  using MatMM = Eigen::Matrix<double, M, M>;
  const int m = model.dim();
  VecM zhat(m), y(m);
  MatM4 H(m, 4);
  model.predict(x_, zhat);
  model.jacobian(x_, H);
  model.residual(z, zhat, y);  // eq. 12, angle-aware
  const MatMM R = model.noise().cov();
  const Eigen::Matrix<double, 4, M> PHt = P_ * H.transpose();
  const MatMM S = H * PHt + R;  // eq. 12
  const Eigen::LLT<MatMM> llt(S);
  if (llt.info() != Eigen::Success) {
    throw std::runtime_error(std::string("EKF ") + to_string(model.kind()) +
                             " update: innovation covariance S is not positive definite");
  }
  UpdateResult res;
  res.dim = m;
  res.nis = y.dot(llt.solve(y));
  if (gate_rejects(res.nis, m)) {
    res.accepted = false;
    return res;
  }
  const Eigen::Matrix<double, 4, M> K = llt.solve(PHt.transpose()).transpose();  // eq. 13
  x_ += K * y;                                                                    // eq. 14
  x_[kTheta] = wrap_angle(x_[kTheta]);
  const Eigen::Matrix4d IKH = Eigen::Matrix4d::Identity() - K * H;
  P_ = IKH * P_ * IKH.transpose() + K * R * K.transpose();  // Joseph form of eq. 14
  P_ = 0.5 * (P_ + P_.transpose());
  return res;
}

UpdateResult Ekf::update_position(const Eigen::Ref<const Eigen::VectorXd>& z, const Eigen::Matrix2d& R) {
  // Eqs. 12–14 with H = [I₂ 0] written out: P Hᵀ = P[:, :2], H P Hᵀ = P[:2, :2].
  // Same arithmetic as update_fixed<2>, without the products by zeros.
  const Eigen::Vector2d y(z[0] - x_[kX], z[1] - x_[kY]);
  const Eigen::Matrix<double, 4, 2> PHt = P_.leftCols<2>();
  const Eigen::Matrix2d S = P_.topLeftCorner<2, 2>() + R;
  const Eigen::LLT<Eigen::Matrix2d> llt(S);
  if (llt.info() != Eigen::Success) {
    throw std::runtime_error("EKF position update: innovation covariance S is not positive definite");
  }
  UpdateResult res;
  res.dim = 2;
  res.nis = y.dot(llt.solve(y));
  if (gate_rejects(res.nis, 2)) {
    res.accepted = false;
    return res;
  }
  const Eigen::Matrix<double, 4, 2> K = llt.solve(PHt.transpose()).transpose();
  x_ += K * y;
  x_[kTheta] = wrap_angle(x_[kTheta]);
  // Joseph form: A = (I − KH) P = P − K P[:2, :]; P = A (I − KH)ᵀ + K R Kᵀ = A − A[:, :2] Kᵀ + K R Kᵀ.
  const Eigen::Matrix4d A = P_ - K * P_.topRows<2>();
  P_ = A - A.leftCols<2>() * K.transpose() + K * R * K.transpose();
  P_ = 0.5 * (P_ + P_.transpose());
  return res;
}

UpdateResult Ekf::update(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
  model.check(z);
  if (model.kind() == MeasurementKind::Position) return update_position(z, model.noise().cov());
  switch (model.dim()) {
    case 1: return update_fixed<1>(model, z);
    case 2: return update_fixed<2>(model, z);
    default: return update_fixed<Eigen::Dynamic>(model, z);
  }
}

// --------------------------------------------------------------------------
// Particle filter
// --------------------------------------------------------------------------

namespace {
/// One noisy BMM step (eqs. 3, 4, 6, 7/9) for N particles stored as columns.
/// A single branch-free loop that the compiler vectorises (it needs
/// -fno-trapping-math to if-convert the clamps).  θ moves by δ_i; (cos θ,
/// sin θ) is rotated by δ_i with sin δ and cos δ from their Taylor series in
/// Horner form (error < 1e-17 for |δ| ≤ 0.25; larger turns are redone exactly
/// by the caller).  Writes δ_i to dl.
void particles_step(int N, double* __restrict x, double* __restrict y, double* __restrict v,
                    double* __restrict th, double* __restrict cs, double* __restrict sn, double* __restrict dl,
                    const double* __restrict ex, const double* __restrict ey, const double* __restrict ev,
                    const double* __restrict et, double vdes, double heading_step, double up_step,
                    double down_step, double vmax, double k, double sv, double st, double sp) {
  constexpr double two_pi = 2.0 * kPi;
    for (int i = 0; i < N; ++i) {
    // eq. 3 (Bmm::next_speed) + ε_v, clamped to [0, v_max]
    const double vi = v[i];
    double up = vi + up_step;
    up = up < vdes ? up : vdes;
    up = up < vmax ? up : vmax;
    double down = vi - down_step;
    down = down > vdes ? down : vdes;
    down = down > 0.0 ? down : 0.0;
    double v1 = (vdes > vi ? up : down) + sv * ev[i];
    v1 = v1 > 0.0 ? v1 : 0.0;
    v1 = v1 < vmax ? v1 : vmax;
    v[i] = v1;
    // eq. 4 + ε_θ: θ moves by δ; rotate (cos θ, sin θ) by δ, with sin δ and
    // cos δ from their Taylor series in Horner form (reciprocal constants).
    const double d = heading_step + st * et[i];
    dl[i] = d;
    const double d2 = d * d;
    const double sd = d * (1 - d2 * (1.0 / 6) * (1 - d2 * (1.0 / 20) * (1 - d2 * (1.0 / 42) *
                                  (1 - d2 * (1.0 / 72) * (1 - d2 * (1.0 / 110))))));
    const double cd = 1 - d2 * 0.5 * (1 - d2 * (1.0 / 12) * (1 - d2 * (1.0 / 30) * (1 - d2 * (1.0 / 56) *
                                  (1 - d2 * (1.0 / 90) * (1 - d2 * (1.0 / 132))))));
    const double c1 = cs[i] * cd - sn[i] * sd;
    const double s1 = sn[i] * cd + cs[i] * sd;
    const double r = 1.5 - 0.5 * (c1 * c1 + s1 * s1);  // keep (c, s) on the unit circle
    const double c2 = c1 * r, s2 = s1 * r;
    cs[i] = c2;
    sn[i] = s2;
    double t = th[i] + d;  // wrap to (−π, π]; exact for |δ| < π
    t = t > kPi ? t - two_pi : t;
    t = t <= -kPi ? t + two_pi : t;
    th[i] = t;
    // eq. 7/9 + (ε_x, ε_y): position moves with the updated v and θ
    x[i] += k * v1 * c2 + sp * ex[i];
    y[i] += k * v1 * s2 + sp * ey[i];
  }
}
}  // namespace

struct ParticleFilter::Impl {
  using Particles = Eigen::Matrix<double, Eigen::Dynamic, 4>;  // one particle per row; columns contiguous
  Bmm bmm;
  detail::Rng rng;
  double resample_threshold;
  Particles X;                // (x, y, v, θ) per row
  Eigen::ArrayXd c, s;        // cos θ, sin θ of every particle, kept in step with θ
  Eigen::ArrayXd logw, w;     // log-weights and normalised weights
  int n_resampled = 0;
  // scratch
  Eigen::Matrix<double, Eigen::Dynamic, 4> noise;
  Eigen::ArrayXd delta;
  Eigen::MatrixXd Y;
  Eigen::ArrayXd cum;
  Eigen::VectorXd zhat, resid;

  Impl(const BmmParams& p, std::uint64_t seed, double thr) : bmm(p), rng(seed), resample_threshold(thr) {}

  int n() const { return static_cast<int>(X.rows()); }

  /// Normalise the log-weights.  Weights below e^−300 of the best particle's
  /// are floored there: such particles are dead either way, and the floor keeps
  /// exp() and w² out of subnormal numbers, which are ~100× slower.
  void normalise() {
    constexpr double kLogFloor = -300.0;
    const double mx = logw.maxCoeff();
    logw = logw.max(mx + kLogFloor);
    w = (logw - mx).exp();
    const double sum = w.sum();  // ≥ 1: the best particle contributes exp(0)
    logw -= mx + std::log(sum);
    w /= sum;
  }

  void resample() {
    // Systematic resampling: one uniform offset, N evenly spaced pointers.
    const int N = n();
    cum.resize(N);
    double acc = 0.0;
    for (int i = 0; i < N; ++i) cum[i] = (acc += w[i]);
    cum[N - 1] = 1.0;
    const double u0 = rng.uniform() / N;
    Particles nX(N, 4);
    Eigen::ArrayXd nc(N), ns(N);
    int i = 0;
    for (int j = 0; j < N; ++j) {
      const double u = u0 + static_cast<double>(j) / N;
      while (i < N - 1 && cum[i] < u) ++i;
      nX.row(j) = X.row(i);
      nc[j] = c[i];
      ns[j] = s[i];
    }
    X.swap(nX);
    c.swap(nc);
    s.swap(ns);
    logw.setConstant(-std::log(static_cast<double>(N)));
    w.setConstant(1.0 / N);
    ++n_resampled;
  }

  State mean() const {
    State m = X.transpose() * w.matrix();
    m[kTheta] = std::atan2((w * s).sum(), (w * c).sum());  // circular mean
    return m;
  }

  /// Weighted covariance Σ w_i d_i d_iᵀ about m, θ deviations wrapped.
  StateCov covariance(const State& m) const {
    const double* x = X.col(kX).data();
    const double* y = X.col(kY).data();
    const double* v = X.col(kV).data();
    const double* th = X.col(kTheta).data();
    double a0 = 0, a1 = 0, a2 = 0, a3 = 0, a4 = 0, a5 = 0, a6 = 0, a7 = 0, a8 = 0, a9 = 0;
    constexpr double two_pi = 2.0 * kPi;
    const double m0 = m[0], m1 = m[1], m2 = m[2], m3 = m[3];
    const double* ww = w.data();
    const int N = n();
    // SIMD reduction (-fopenmp-simd): a fixed summation order for a given build.
#pragma omp simd reduction(+ : a0, a1, a2, a3, a4, a5, a6, a7, a8, a9)
    for (int i = 0; i < N; ++i) {
      double d3 = th[i] - m3;  // both in (−π, π]: one wrap suffices
      d3 = d3 > kPi ? d3 - two_pi : d3;
      d3 = d3 <= -kPi ? d3 + two_pi : d3;
      const double d0 = x[i] - m0, d1 = y[i] - m1, d2 = v[i] - m2;
      const double wi = ww[i];
      const double w0 = wi * d0, w1 = wi * d1, w2 = wi * d2, w3 = wi * d3;
      a0 += w0 * d0; a1 += w0 * d1; a2 += w0 * d2; a3 += w0 * d3;
      a4 += w1 * d1; a5 += w1 * d2; a6 += w1 * d3;
      a7 += w2 * d2; a8 += w2 * d3;
      a9 += w3 * d3;
    }
    StateCov P;
    P << a0, a1, a2, a3,
         a1, a4, a5, a6,
         a2, a5, a7, a8,
         a3, a6, a8, a9;
    return P;
  }

  /// Noisy BMM for every particle (eqs. 6–9, the body of Bmm::transition).
  /// θ moves by a small δ_i per step, so cos/sin of the new heading come from
  /// rotating the cached (cos θ, sin θ) by δ_i, with sin δ and cos δ from their
  /// Taylor series (error < 1e-17 for |δ| ≤ kSmallTurn); larger turns use
  /// std::cos/std::sin.  This keeps the loop free of libm calls.
  void predict(double desired_speed, double heading_step) {
    constexpr double kSmallTurn = 0.25;
    const auto& p = bmm.params();
    const int N = n();
    const double k = p.terrain_factor() * p.dt;
    noise.resize(N, 4);
    rng.fill_normal(noise.data(), 4L * N);
    delta.resize(N);
    double* __restrict x = X.col(kX).data();
    double* __restrict y = X.col(kY).data();
    double* __restrict v = X.col(kV).data();
    double* __restrict th = X.col(kTheta).data();
    double* __restrict cs = c.data();
    double* __restrict sn = s.data();
    double* __restrict dl = delta.data();
    const double* __restrict ex = noise.col(0).data();
    const double* __restrict ey = noise.col(1).data();
    const double* __restrict ev = noise.col(2).data();
    const double* __restrict et = noise.col(3).data();
    particles_step(N, x, y, v, th, cs, sn, dl, ex, ey, ev, et, desired_speed, heading_step, p.acceleration * p.dt,
                   p.deceleration * p.dt, p.max_speed, k, p.speed_noise, p.heading_noise, p.position_noise);
    if (delta.abs().maxCoeff() > kSmallTurn) {  // rare: large turns get exact trigonometry
      for (int i = 0; i < N; ++i) {
        if (std::abs(dl[i]) > kSmallTurn) {
          th[i] = wrap_angle(th[i]);
          const double ce = std::cos(th[i]), se = std::sin(th[i]);
          x[i] += k * v[i] * (ce - cs[i]);
          y[i] += k * v[i] * (se - sn[i]);
          cs[i] = ce;
          sn[i] = se;
        }
      }
    }
  }
};

ParticleFilter::ParticleFilter(const BmmParams& params, const State& x0, const StateCov& P0, int n_particles,
                               std::uint64_t seed, double resample_threshold) {
  if (n_particles < 1) {
    throw std::invalid_argument("n_particles = " + std::to_string(n_particles) + " must be >= 1");
  }
  if (!(std::isfinite(resample_threshold) && resample_threshold >= 0.0 && resample_threshold <= 1.0)) {
    std::ostringstream os;
    os << "resample_threshold = " << resample_threshold << " must be in [0, 1]";
    throw std::invalid_argument(os.str());
  }
  check_prior(x0, P0);
  impl_ = std::make_unique<Impl>(params, seed, resample_threshold);
  auto& I = *impl_;
  const Eigen::Matrix4d L = P0.llt().matrixL();
  I.X.resize(n_particles, 4);
  I.c.resize(n_particles);
  I.s.resize(n_particles);
  for (int i = 0; i < n_particles; ++i) {
    Eigen::Vector4d n;
    for (int k = 0; k < 4; ++k) n[k] = I.rng.normal();
    State p = x0 + L * n;
    p[kV] = std::max(0.0, p[kV]);
    p[kTheta] = wrap_angle(p[kTheta]);
    I.X.row(i) = p.transpose();
    I.c[i] = std::cos(p[kTheta]);
    I.s[i] = std::sin(p[kTheta]);
  }
  I.logw = Eigen::ArrayXd::Constant(n_particles, -std::log(static_cast<double>(n_particles)));
  I.w = Eigen::ArrayXd::Constant(n_particles, 1.0 / n_particles);
}

ParticleFilter::~ParticleFilter() = default;
ParticleFilter::ParticleFilter(ParticleFilter&&) noexcept = default;
ParticleFilter& ParticleFilter::operator=(ParticleFilter&&) noexcept = default;

int ParticleFilter::size() const { return impl_->n(); }
double ParticleFilter::ess() const { return 1.0 / impl_->w.square().sum(); }
int ParticleFilter::resample_count() const { return impl_->n_resampled; }
State ParticleFilter::mean() const { return impl_->mean(); }
StateCov ParticleFilter::covariance() const { return impl_->covariance(impl_->mean()); }
StateCov ParticleFilter::covariance(const State& about) const { return impl_->covariance(about); }
Eigen::VectorXd ParticleFilter::weights() const { return impl_->w.matrix(); }

Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> ParticleFilter::particles() const {
  return impl_->X;
}

void ParticleFilter::predict(const Control& u) {
  if (!u.allFinite()) {
    std::ostringstream os;
    os << "control (desired_speed, heading_change) = (" << u[0] << ", " << u[1] << ") is not finite";
    throw std::invalid_argument(os.str());
  }
  impl_->predict(u[0], impl_->bmm.clipped_heading_change(u[1]));
}

UpdateResult ParticleFilter::update(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
  model.check(z);
  auto& I = *impl_;
  const int m = model.dim();
  const int N = I.n();
  const Eigen::MatrixXd& R = model.noise().cov();
  UpdateResult res;
  res.dim = m;
  if (model.kind() == MeasurementKind::Position) {
    // Fast path: 2-D residuals, log-likelihood and NIS moments in one pass.
    const Eigen::Matrix2d Ri = R.inverse();
    const double* x = I.X.col(kX).data();
    const double* y = I.X.col(kY).data();
    const double* w = I.w.data();
    double* logw = I.logw.data();
    const double z0 = z[0], z1 = z[1], r00 = 0.5 * Ri(0, 0), r01 = Ri(0, 1), r11 = 0.5 * Ri(1, 1);
    double s0 = 0, s1 = 0, s00 = 0, s01 = 0, s11 = 0;
#pragma omp simd reduction(+ : s0, s1, s00, s01, s11)
    for (int i = 0; i < N; ++i) {
      const double d0 = z0 - x[i], d1 = z1 - y[i], wi = w[i];
      s0 += wi * d0; s1 += wi * d1;
      s00 += wi * d0 * d0; s01 += wi * d0 * d1; s11 += wi * d1 * d1;
      logw[i] -= r00 * d0 * d0 + r01 * d0 * d1 + r11 * d1 * d1;
    }
    const Eigen::Vector2d ybar(s0, s1);
    Eigen::Matrix2d S;
    S << s00 - s0 * s0, s01 - s0 * s1, s01 - s0 * s1, s11 - s1 * s1;
    S += R;
    res.nis = ybar.dot(S.ldlt().solve(ybar));
  } else {
    // Residual of every particle, y_i = z ⊖ h(x_i), one per column.
    I.Y.resize(m, N);
    I.zhat.resize(m);
    I.resid.resize(m);
    for (int i = 0; i < N; ++i) {
      model.predict(I.X.row(i).transpose(), I.zhat);
      model.residual(z, I.zhat, I.resid);
      I.Y.col(i) = I.resid;
    }
    // NIS (diagnostic) of the prior predictive: mean residual ȳ, S = Cov_w(y) + R.
    const Eigen::VectorXd ybar = I.Y * I.w.matrix();
    const Eigen::MatrixXd D = I.Y.colwise() - ybar;
    const Eigen::MatrixXd S = D * I.w.matrix().asDiagonal() * D.transpose() + R;
    res.nis = ybar.dot(S.ldlt().solve(ybar));
    // log-likelihood −½ yᵀR⁻¹y = −½‖L⁻¹y‖², added to the log-weights.
    Eigen::LLT<Eigen::MatrixXd>(R).matrixL().solveInPlace(I.Y);
    I.logw -= 0.5 * I.Y.colwise().squaredNorm().transpose().array();
  }
  I.normalise();
  if (ess() < I.resample_threshold * N) I.resample();
  return res;
}

// --------------------------------------------------------------------------
// Extended information filter
// --------------------------------------------------------------------------

InformationFilter::InformationFilter(const BmmParams& params, const State& x0, const StateCov& P0) : bmm_(params) {
  check_prior(x0, P0);
  Y_ = P0.inverse();
  Y_ = 0.5 * (Y_ + Y_.transpose());
  y_ = Y_ * x0;
}

State InformationFilter::x() const { return Y_.ldlt().solve(y_); }
StateCov InformationFilter::P() const { return Y_.inverse(); }

void InformationFilter::predict(const Control& u) {
  Eigen::Matrix4d F, G;
  const State x1 = bmm_.linearize(x(), u, &F, &G);
  const Eigen::Vector4d sigma2 = bmm_.noise_cov().diagonal();
  Eigen::Matrix4d Pp = F * P() * F.transpose() + G * sigma2.asDiagonal() * G.transpose();
  Pp = 0.5 * (Pp + Pp.transpose());
  const Eigen::LLT<Eigen::Matrix4d> llt(Pp);
  if (llt.info() != Eigen::Success || !(llt.matrixL().toDenseMatrix().diagonal().minCoeff() > 1e-12)) {
    // Zero uncertainty in some direction: infinite information, which the
    // information form cannot hold.  Happens when a noise sigma is 0 and a
    // BMM limit binds (∂v'/∂v = 0 with speed_noise = 0, for instance).
    throw std::runtime_error(
        "information filter predict: the predicted covariance F P Fᵀ + Q is singular (a state "
        "component became exactly known, e.g. speed_noise = 0 while a speed limit binds); "
        "the information form needs a positive-definite covariance: use process noise > 0");
  }
  Y_ = llt.solve(Eigen::Matrix4d::Identity());
  Y_ = 0.5 * (Y_ + Y_.transpose());
  y_ = Y_ * x1;
}

UpdateResult InformationFilter::update(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
  model.check(z);
  const State xb = x();
  const Eigen::MatrixXd H = model.jacobian(xb);
  Eigen::VectorXd zhat = model.predict(xb), nu(model.dim());
  model.residual(z, zhat, nu);
  const Eigen::MatrixXd& R = model.noise().cov();
  const Eigen::MatrixXd RinvH = R.ldlt().solve(H);  // R⁻¹ H
  UpdateResult res;
  res.dim = model.dim();
  const Eigen::MatrixXd S = H * P() * H.transpose() + R;
  res.nis = nu.dot(S.ldlt().solve(nu));
  Y_ += H.transpose() * RinvH;
  Y_ = 0.5 * (Y_ + Y_.transpose());
  y_ += RinvH.transpose() * (nu + H * xb);
  return res;
}

// --------------------------------------------------------------------------
// Batch filtering
// --------------------------------------------------------------------------

void MeasurementStream::validate(int n_steps) const {
  auto bad_rows = [&](const char* name, Eigen::Index rows) {
    if (rows != 0 && rows != n_steps) {
      std::ostringstream os;
      os << "measurement stream '" << name << "' has " << rows << " rows, expected " << n_steps
         << " (one per control step) or 0";
      throw std::invalid_argument(os.str());
    }
  };
  bad_rows("position", position.rows());
  bad_rows("speed_heading", speed_heading.rows());
  bad_rows("ranges", ranges.rows());
  bad_rows("bearings", bearings.rows());
  auto check_rows = [](const char* name, const RowMatrixX2& m) {
    for (Eigen::Index k = 0; k < m.rows(); ++k) {
      const bool nan0 = std::isnan(m(k, 0)), nan1 = std::isnan(m(k, 1));
      if (nan0 && nan1) continue;  // a gap
      if (nan0 || nan1 || !std::isfinite(m(k, 0)) || !std::isfinite(m(k, 1))) {
        std::ostringstream os;
        os << "measurement stream '" << name << "' row " << k << " = (" << m(k, 0) << ", " << m(k, 1)
           << ") is invalid: use a full NaN row for a gap, finite values otherwise";
        throw std::invalid_argument(os.str());
      }
    }
  };
  check_rows("position", position);
  check_rows("speed_heading", speed_heading);
  auto check_lm = [&](const char* name, const RowMatrixXd& m) {
    if (m.rows() == 0) return;
    if (m.cols() != landmarks.rows()) {
      std::ostringstream os;
      os << "measurement stream '" << name << "' has " << m.cols() << " columns but there are "
         << landmarks.rows() << " landmarks";
      throw std::invalid_argument(os.str());
    }
    for (Eigen::Index k = 0; k < m.rows(); ++k)
      for (Eigen::Index j = 0; j < m.cols(); ++j)
        if (std::isinf(m(k, j))) {
          std::ostringstream os;
          os << "measurement stream '" << name << "' row " << k << " landmark " << j << " = " << m(k, j)
             << " is not finite (use NaN for 'not observed')";
          throw std::invalid_argument(os.str());
        }
  };
  check_lm("ranges", ranges);
  check_lm("bearings", bearings);
}

namespace {

template <class Filter>
State estimate(const Filter& f);
template <>
State estimate(const Ekf& f) { return f.x(); }
template <>
State estimate(const InformationFilter& f) { return f.x(); }
template <>
State estimate(const ParticleFilter& f) { return f.mean(); }

template <class Filter>
StateCov estimate_cov(const Filter& f, const State&);
template <>
StateCov estimate_cov(const Ekf& f, const State&) { return f.P(); }
template <>
StateCov estimate_cov(const InformationFilter& f, const State&) { return f.P(); }
template <>
StateCov estimate_cov(const ParticleFilter& f, const State& mean) { return f.covariance(mean); }

/// Landmark model restricted to the landmarks seen in row k (NaN = unseen).
struct LandmarkStream {
  const RowMatrixXd* data = nullptr;
  std::unique_ptr<MeasurementModel> full;
  std::vector<int> seen;
  Eigen::VectorXd z;

  bool step(Eigen::Index k, std::unique_ptr<MeasurementModel>& subset_out, const MeasurementModel*& model) {
    if (!data || data->rows() == 0) return false;
    seen.clear();
    for (Eigen::Index j = 0; j < data->cols(); ++j)
      if (!std::isnan((*data)(k, j))) seen.push_back(static_cast<int>(j));
    if (seen.empty()) return false;
    z.resize(static_cast<Eigen::Index>(seen.size()));
    for (size_t j = 0; j < seen.size(); ++j) z[static_cast<Eigen::Index>(j)] = (*data)(k, seen[j]);
    if (static_cast<Eigen::Index>(seen.size()) == data->cols()) {
      model = full.get();
    } else {
      subset_out = std::make_unique<MeasurementModel>(full->subset(seen));
      model = subset_out.get();
    }
    return true;
  }
};

template <class Filter>
FilterRun run_impl(Filter& f, const Eigen::Ref<const RowMatrixX2>& controls, const MeasurementStream& st,
                   const std::function<int()>& resampled) {
  const Eigen::Index N = controls.rows();
  FilterRun out;
  out.states.resize(N + 1, 4);
  out.covariances.resize(N + 1, 16);
  out.nis = Eigen::VectorXd::Constant(N, std::numeric_limits<double>::quiet_NaN());
  out.nis_dof = Eigen::VectorXi::Zero(N);

  std::unique_ptr<MeasurementModel> pos, imu;
  if (st.position.rows()) pos = std::make_unique<MeasurementModel>(MeasurementModel::position(st.position_cov));
  if (st.speed_heading.rows())
    imu = std::make_unique<MeasurementModel>(MeasurementModel::speed_heading(st.speed_heading_cov));
  LandmarkStream rng_s, brg_s;
  if (st.ranges.rows()) {
    rng_s.data = &st.ranges;
    rng_s.full = std::make_unique<MeasurementModel>(MeasurementModel::range(st.landmarks, st.range_std));
  }
  if (st.bearings.rows()) {
    brg_s.data = &st.bearings;
    brg_s.full = std::make_unique<MeasurementModel>(MeasurementModel::bearing(st.landmarks, st.bearing_std));
  }

  auto record = [&](Eigen::Index row) {
    const State m = estimate(f);
    const StateCov P = estimate_cov(f, m);
    out.states.row(row) = m.transpose();
    out.covariances.row(row) = Eigen::Map<const Eigen::Matrix<double, 1, 16>>(P.data());  // symmetric
  };
  record(0);
  for (Eigen::Index k = 0; k < N; ++k) {
    const Control u = controls.row(k).transpose();
    if (!u.allFinite()) {
      std::ostringstream os;
      os << "controls row " << k << " = (" << u[0] << ", " << u[1] << ") is not finite";
      throw std::invalid_argument(os.str());
    }
    f.predict(u);
    double nis = 0.0;
    int dof = 0, n_meas = 0;
    auto apply = [&](const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
      const UpdateResult r = f.update(model, z);
      ++n_meas;
      if (r.accepted) {
        ++out.n_updates;
        nis += r.nis;
        dof += r.dim;
      } else {
        ++out.n_rejected;
      }
    };
    if (pos && !std::isnan(st.position(k, 0))) apply(*pos, st.position.row(k).transpose());
    if (imu && !std::isnan(st.speed_heading(k, 0))) apply(*imu, st.speed_heading.row(k).transpose());
    std::unique_ptr<MeasurementModel> sub;
    const MeasurementModel* lm_model = nullptr;
    if (rng_s.step(k, sub, lm_model)) apply(*lm_model, rng_s.z);
    if (brg_s.step(k, sub, lm_model)) apply(*lm_model, brg_s.z);
    if (n_meas == 0) ++out.n_gaps;
    if (dof > 0) {
      out.nis[k] = nis;
      out.nis_dof[k] = dof;
    }
    record(k + 1);
  }
  out.n_resampled = resampled();
  return out;
}

}  // namespace

FilterRun run_filter(const BmmParams& params, const FilterOptions& options, const State& x0, const StateCov& P0,
                     const Eigen::Ref<const RowMatrixX2>& controls, const MeasurementStream& stream) {
  stream.validate(static_cast<int>(controls.rows()));
  switch (options.type) {
    case FilterType::Ekf: {
      Ekf f(params, x0, P0);
      f.set_gate(options.gate_probability);
      return run_impl(f, controls, stream, [] { return 0; });
    }
    case FilterType::ParticleFilter: {
      ParticleFilter f(params, x0, P0, options.n_particles, options.seed, options.resample_threshold);
      return run_impl(f, controls, stream, [&f] { return f.resample_count(); });
    }
    case FilterType::InformationFilter: {
      InformationFilter f(params, x0, P0);
      return run_impl(f, controls, stream, [] { return 0; });
    }
  }
  throw std::invalid_argument("unknown filter type");
}

}  // namespace safenav

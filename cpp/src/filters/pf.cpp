// Particle filter (the Battlefield Motion Model's SIR filter): construction,
// validation and the measurement update's dispatch (SIR, kernel or ensemble
// update); the filter's state and passes are ParticleFilter::Impl in
// pf_impl.hpp, the method is documented at ParticleFilter in safenav/filters.hpp.
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "checks.hpp"
#include "pf_impl.hpp"
#include "safenav/filters.hpp"

namespace safenav {

ParticleFilter::ParticleFilter(const BmmParams& params, const State& x0, const StateCov& P0, int n_particles,
                               std::uint64_t seed, double resample_threshold, double bandwidth_scale) {
  if (n_particles < 1) {
    throw std::invalid_argument("n_particles = " + std::to_string(n_particles) + " must be >= 1");
  }
  if (!(std::isfinite(resample_threshold) && resample_threshold >= 0.0 && resample_threshold <= 1.0)) {
    std::ostringstream os;
    os << "resample_threshold = " << resample_threshold << " must be in [0, 1]";
    throw std::invalid_argument(os.str());
  }
  if (!(std::isfinite(bandwidth_scale) && bandwidth_scale >= 0.0 && bandwidth_scale <= 10.0)) {
    std::ostringstream os;
    os << "bandwidth_scale = " << bandwidth_scale << " must be in [0, 10] (0: no regularisation)";
    throw std::invalid_argument(os.str());
  }
  check_prior(x0, P0);
  impl_ = std::make_unique<Impl>(params, seed, resample_threshold, n_particles, bandwidth_scale);
  auto& I = *impl_;
  const int N = n_particles;
  const Eigen::Matrix4d L = P0.llt().matrixL();
  I.rng.fill_normal(I.noise.col(0), 4L * I.noise.stride());
  for (int i = 0; i < N; ++i) {
    const Eigen::Vector4d e(I.noise.col(0)[i], I.noise.col(1)[i], I.noise.col(2)[i], I.noise.col(3)[i]);
    State p = x0 + L * e;
    p[kV] = std::max(0.0, p[kV]);
    p[kTheta] = wrap_angle(p[kTheta]);
    for (int c = 0; c < 4; ++c) I.col(c)[i] = p[c];
    I.col(Impl::kCos)[i] = std::cos(p[kTheta]);
    I.col(Impl::kSin)[i] = std::sin(p[kTheta]);
  }
  I.reset_weights();
}

ParticleFilter::~ParticleFilter() = default;
ParticleFilter::ParticleFilter(ParticleFilter&&) noexcept = default;
ParticleFilter& ParticleFilter::operator=(ParticleFilter&&) noexcept = default;
ParticleFilter::ParticleFilter(const ParticleFilter& o) : impl_(std::make_unique<Impl>(*o.impl_)) {}
ParticleFilter& ParticleFilter::operator=(const ParticleFilter& o) {
  if (this == &o) return *this;
  if (!impl_ || impl_->N != o.impl_->N) {
    impl_ = std::make_unique<Impl>(*o.impl_);
    return *this;
  }
  // The state only (the scratch columns are rewritten before they are read).
  Impl& a = *impl_;
  const Impl& b = *o.impl_;
  a.bmm = b.bmm;
  a.rng = b.rng;
  a.resample_threshold = b.resample_threshold;
  a.h = b.h;
  a.S = b.S;
  a.W = b.W;
  a.ess = b.ess;
  a.n_resampled = b.n_resampled;
  a.ancestor = b.ancestor;
  a.gate_probability = b.gate_probability;
  a.gate_thresholds = b.gate_thresholds;
  return *this;
}

int ParticleFilter::size() const { return impl_->n(); }
double ParticleFilter::ess() const { return impl_->ess; }
int ParticleFilter::resample_count() const { return impl_->n_resampled; }
State ParticleFilter::mean() const { return impl_->mean(); }
StateCov ParticleFilter::covariance() const { return impl_->reported_covariance(impl_->mean()); }
StateCov ParticleFilter::covariance(const State& about) const { return impl_->reported_covariance(about); }
StateCov ParticleFilter::sample_covariance() const { return impl_->covariance(impl_->mean()); }
double ParticleFilter::bandwidth() const { return impl_->h; }
StateCov ParticleFilter::covariance_floor() const {
  const auto& I = *impl_;
  return (I.h * I.h) * I.covariance(I.mean(Impl::kUniform), Impl::kUniform);
}
Eigen::VectorXd ParticleFilter::weights() const { return Eigen::Map<const Eigen::VectorXd>(impl_->w(), size()); }

Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> ParticleFilter::particles() const {
  const auto& I = *impl_;
  Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> X(I.N, 4);
  for (int c = 0; c < 4; ++c) X.col(c) = Eigen::Map<const Eigen::VectorXd>(I.col(c), I.N);
  return X;
}

void ParticleFilter::predict(const Control& u) {
  if (!u.allFinite()) {
    std::ostringstream os;
    os << "control (desired_speed, heading_change) = (" << u[0] << ", " << u[1] << ") is not finite";
    throw std::invalid_argument(os.str());
  }
  impl_->predict(u[0], impl_->bmm.clipped_heading_change(u[1]));
  // Finite inputs can still overflow (positions near 1e308, a huge dt·v_max); v and θ stay bounded.
  for (int c : {kX, kY}) {
    const Eigen::Map<const Eigen::ArrayXd> col(impl_->col(c), impl_->n());
    if (!col.allFinite()) {
      std::ostringstream os;
      os << "particle filter predict: particle " << (c == kX ? "x" : "y") << " overflows (control (" << u[0]
         << ", " << u[1] << "), dt = " << impl_->bmm.params().dt << ", max_speed = "
         << impl_->bmm.params().max_speed << ")";
      throw std::invalid_argument(os.str());
    }
  }
}

void ParticleFilter::predict(const Control& u, double dt) {
  auto& I = *impl_;
  if (I.bmm.is_nominal_step(dt)) return predict(u);
  const Bmm nominal = I.bmm;
  I.bmm = nominal.with_step(dt);
  try {
    predict(u);
  } catch (...) {
    I.bmm = nominal;
    throw;
  }
  I.bmm = nominal;
}

void ParticleFilter::set_gate(double probability) {
  if (!(std::isfinite(probability) && probability >= 0.0 && probability < 1.0)) {
    std::ostringstream os;
    os << "gate probability = " << probability << " must be in [0, 1) (0 disables the gate)";
    throw std::invalid_argument(os.str());
  }
  impl_->gate_probability = probability;
  impl_->gate_thresholds.clear();
}

double ParticleFilter::gate() const { return impl_->gate_probability; }

UpdateResult ParticleFilter::update(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z_in) {
  model.check(z_in);
  // The IMU's heading wrapped once here, so that each residual wraps in one step (imu_moments).
  Eigen::VectorXd z = z_in;
  if (model.kind() == MeasurementKind::SpeedHeading) z[1] = wrap_angle(z[1]);
  auto& I = *impl_;
  const int m = model.dim();
  const int N = I.n();
  const Eigen::MatrixXd R = model.noise().cov();
  UpdateResult res;
  res.dim = m;
  const bool regularised = I.h > 0.0;
  res.nis = I.likelihood(model, z, R, regularised);  // log p(z | x_i) into the gain column, ȳ, C_yy, C_xy
  res.log_det_s = I.log_det_s;  // of the NIS's S
  if (std::isfinite(res.nis)) check_log_det_s(res.log_det_s, "particle filter", model.kind());
  if (I.gate_probability > 0.0 && std::isfinite(res.nis)) {
    if (static_cast<int>(I.gate_thresholds.size()) <= m) I.gate_thresholds.resize(m + 1, -1.0);
    double& t = I.gate_thresholds[m];
    if (t < 0.0) t = chi2_quantile(I.gate_probability, m);
    if (res.nis > t) {  // rejected: the weights stay as they were
      res.accepted = false;
      return res;
    }
  }
  double* logw = I.logw();
  const double* gain = I.W.col(Impl::kGain);
  double mx = -std::numeric_limits<double>::infinity();
  for (int i = 0; i < N; ++i) mx = std::max(mx, logw[i] + gain[i]);  // exact in any order
  if (!std::isfinite(mx) || !std::isfinite(res.nis)) {  // the weights stay as they were; say why
    check_nis(res.nis, "particle filter", model.kind());
    // every likelihood underflowed (residuals beyond ~1e154 σ)
    std::ostringstream os;
    os << "particle filter " << to_string(model.kind()) << " update: the measurement has zero likelihood under "
       << "every particle (log-likelihood " << mx << ")";
    throw std::invalid_argument(os.str());
  }
  if (regularised && model.kind() == MeasurementKind::SpeedHeading && I.ess > 16.0) {
    I.ensemble_update(z, R);  // the IMU does not see the position: no reweighting (see the class comment)
    return res;
  }
  // The SIR weights, unless they would fall below the resampling threshold
  // and the filter is regularised: then the kernel update instead.
  double s1 = 0.0, s2 = 0.0;  // ESS = s1²/s2 of the SIR weights
  for (int i = 0; regularised && i < N; ++i) {
    const double e = std::exp(logw[i] + gain[i] - mx);
    s1 += e;
    s2 += e * e;
  }
  if (!regularised || s1 * s1 >= I.resample_threshold * N * s2) {
    for (int i = 0; i < N; ++i) logw[i] += gain[i];
    I.normalise(mx);
    if (I.ess < I.resample_threshold * N) I.resample();
    return res;
  }
  I.kernel_update(model, z, R);
  return res;
}

}  // namespace safenav

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
void check_prior(const State& x0, const StateCov& P0) {
  check_finite_state(x0, "x0");
  check_covariance(P0, "P0");
}
}  // namespace

// --------------------------------------------------------------------------
// EKF
// --------------------------------------------------------------------------

Ekf::Ekf(const BmmParams& params, const State& x0, const StateCov& P0) : bmm_(params) { set_state(x0, P0); }

void Ekf::set_state(const State& x, const StateCov& P) {
  check_prior(x, P);
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

UpdateResult Ekf::update(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
  model.check(z);
  switch (model.dim()) {
    case 1: return update_fixed<1>(model, z);
    case 2: return update_fixed<2>(model, z);
    default: return update_fixed<Eigen::Dynamic>(model, z);
  }
}

// --------------------------------------------------------------------------
// Particle filter
// --------------------------------------------------------------------------

struct ParticleFilter::Impl {
  Bmm bmm;
  detail::Rng rng;
  double resample_threshold;
  Eigen::ArrayXd x, y, v, th, c, s;  // states and cached cos/sin of θ
  Eigen::ArrayXd logw;
  int n_resampled = 0;
  // scratch
  Eigen::ArrayXd w, ll, cum;
  Eigen::VectorXd zhat, resid, tmp;

  Impl(const BmmParams& p, std::uint64_t seed, double thr) : bmm(p), rng(seed), resample_threshold(thr) {}

  int n() const { return static_cast<int>(x.size()); }
  State particle(int i) const { return State(x[i], y[i], v[i], th[i]); }

  void normalise() {
    const double mx = logw.maxCoeff();
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
    Eigen::ArrayXd nx(N), ny(N), nv(N), nth(N), nc(N), ns(N);
    int i = 0;
    for (int j = 0; j < N; ++j) {
      const double u = u0 + static_cast<double>(j) / N;
      while (i < N - 1 && cum[i] < u) ++i;
      nx[j] = x[i];
      ny[j] = y[i];
      nv[j] = v[i];
      nth[j] = th[i];
      nc[j] = c[i];
      ns[j] = s[i];
    }
    x.swap(nx);
    y.swap(ny);
    v.swap(nv);
    th.swap(nth);
    c.swap(nc);
    s.swap(ns);
    logw.setConstant(-std::log(static_cast<double>(N)));
    w.setConstant(1.0 / N);
    ++n_resampled;
  }

  State mean() const {
    State m;
    m[kX] = (w * x).sum();
    m[kY] = (w * y).sum();
    m[kV] = (w * v).sum();
    m[kTheta] = std::atan2((w * s).sum(), (w * c).sum());
    return m;
  }

  StateCov covariance(const State& m) const {
    StateCov P = StateCov::Zero();
    for (int i = 0; i < n(); ++i) {
      const Eigen::Vector4d d(x[i] - m[kX], y[i] - m[kY], v[i] - m[kV], wrap_angle(th[i] - m[kTheta]));
      P.noalias() += w[i] * (d * d.transpose());
    }
    return 0.5 * (P + P.transpose());
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
  for (auto* a : {&I.x, &I.y, &I.v, &I.th, &I.c, &I.s}) a->resize(n_particles);
  for (int i = 0; i < n_particles; ++i) {
    Eigen::Vector4d n;
    for (int k = 0; k < 4; ++k) n[k] = I.rng.normal();
    const Eigen::Vector4d p = x0 + L * n;
    I.x[i] = p[kX];
    I.y[i] = p[kY];
    I.v[i] = std::max(0.0, p[kV]);
    I.th[i] = wrap_angle(p[kTheta]);
    I.c[i] = std::cos(I.th[i]);
    I.s[i] = std::sin(I.th[i]);
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
Eigen::VectorXd ParticleFilter::weights() const { return impl_->w.matrix(); }

Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> ParticleFilter::particles() const {
  const auto& I = *impl_;
  Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> out(I.n(), 4);
  out.col(0) = I.x.matrix();
  out.col(1) = I.y.matrix();
  out.col(2) = I.v.matrix();
  out.col(3) = I.th.matrix();
  return out;
}

void ParticleFilter::predict(const Control& u) {
  // Every particle follows the noisy BMM, eqs. 6–9 (same as Bmm::transition).
  auto& I = *impl_;
  if (!u.allFinite()) {
    std::ostringstream os;
    os << "control (desired_speed, heading_change) = (" << u[0] << ", " << u[1] << ") is not finite";
    throw std::invalid_argument(os.str());
  }
  const auto& p = I.bmm.params();
  const double dth = I.bmm.clipped_heading_change(u[1]);
  const double k = p.terrain_factor() * p.dt;
  const double sig[4] = {p.position_noise, p.position_noise, p.speed_noise, p.heading_noise};
  for (int i = 0; i < I.n(); ++i) {
    double eps[4];
    for (int j = 0; j < 4; ++j) eps[j] = sig[j] > 0.0 ? sig[j] * I.rng.normal() : 0.0;
    I.bmm.transition_unchecked(I.x[i], I.y[i], I.v[i], I.th[i], u[0], dth, k, eps, I.c[i], I.s[i]);
  }
}

UpdateResult ParticleFilter::update(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
  model.check(z);
  auto& I = *impl_;
  const int m = model.dim();
  const int N = I.n();
  I.zhat.resize(m);
  I.resid.resize(m);
  I.tmp.resize(m);
  I.ll.resize(N);
  const Eigen::MatrixXd Rinv = model.noise().cov().inverse();
  UpdateResult res;
  res.dim = m;
  // NIS of the prior weighted mean (diagnostic), before the weights change.
  {
    const State mu = I.mean();
    const StateCov P = I.covariance(mu);
    const Eigen::MatrixXd H = model.jacobian(mu);
    model.predict(mu, I.zhat);
    model.residual(z, I.zhat, I.resid);
    const Eigen::MatrixXd S = H * P * H.transpose() + model.noise().cov();
    res.nis = I.resid.dot(S.ldlt().solve(I.resid));
  }
  if (m == 2 && (model.kind() == MeasurementKind::Position)) {
    const Eigen::Matrix2d Ri = Rinv;
    for (int i = 0; i < N; ++i) {
      const double d0 = z[0] - I.x[i], d1 = z[1] - I.y[i];
      I.ll[i] = -0.5 * (Ri(0, 0) * d0 * d0 + 2.0 * Ri(0, 1) * d0 * d1 + Ri(1, 1) * d1 * d1);
    }
  } else {
    for (int i = 0; i < N; ++i) {
      model.predict(I.particle(i), I.zhat);
      model.residual(z, I.zhat, I.resid);
      I.tmp.noalias() = Rinv * I.resid;
      I.ll[i] = -0.5 * I.resid.dot(I.tmp);
    }
  }
  I.logw += I.ll;
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
  Y_ = Pp.inverse();
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
StateCov estimate_cov(const ParticleFilter& f, const State&) { return f.covariance(); }

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

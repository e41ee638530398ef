// The one interface of the online filters (safenav/filter.hpp): the checks,
// once, and its four implementations — the EKF and the particle filter, each
// plain or augmented.
#include "safenav/filter.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cfloat>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>
#include <typeinfo>

#include "checks.hpp"
#include "../errors.hpp"
#include "safenav/augmented.hpp"
#include "safenav/measurement.hpp"

namespace safenav {

namespace {

std::string num(double v) { return detail::num(v, 12); }

[[noreturn]] void refuse(const char* step, const std::string& why) {
  throw std::invalid_argument(std::string(step) + ": " + why + "; the input is refused and the filter left as it was");
}

/// A variance σ² that is finite, > 0 and whose inverse is finite (σ in about [1e-154, 1e154]).
void check_std(double s, const char* step, const char* what) {
  const double v = s * s;
  if (!(std::isfinite(s) && s > 0.0 && std::isfinite(v) && v >= DBL_MIN))
    throw std::invalid_argument(std::string(step) + ": " + what + " = " + num(s) +
                                " must be > 0 with a finite, normal square");
}

void check_noise2(const Eigen::Vector2d& z, const Eigen::Matrix2d& R, const char* step) {
  if (!z.allFinite())
    throw std::invalid_argument(std::string(step) + ": z = (" + num(z[0]) + ", " + num(z[1]) + ") is not finite");
  check_cov2(R, step);
  const double det = R(0, 0) * R(1, 1) - R(0, 1) * R(1, 0);
  if (!(det >= DBL_MIN && std::isfinite(det)))
    throw std::invalid_argument(std::string(step) + ": R has determinant " + num(det) +
                                ", too close to singular (or too large) for its inverse");
}

/// A valid covariance: every variance ≥ 0, and positive definite (the fast
/// Cholesky test) or, failing that, no eigenvalue below −1e-12·max|P_ij|
/// (singular within rounding: a state without process noise, say).
template <class M>
bool is_covariance(const M& P) {
  if ((P.diagonal().array() < 0.0).any()) return false;
  if (Eigen::LLT<M>(P).info() == Eigen::Success) return true;
  const Eigen::SelfAdjointEigenSolver<M> eig(P, Eigen::EigenvaluesOnly);
  return eig.info() == Eigen::Success && eig.eigenvalues().minCoeff() >= -1e-12 * P.cwiseAbs().maxCoeff();
}

}  // namespace

// ------------------------------- Filter --------------------------------------

Filter::Filter(FilterType type, bool augmented, const State& x0, const StateCov& P0)
    : type_(type), augmented_(augmented), x_(x0), P_(P0) {
  x_[kTheta] = wrap_angle(x_[kTheta]);  // until the first input the estimate is the prior itself
}
Filter::~Filter() = default;

std::unique_ptr<Filter> Filter::clone() const {
  if (depth_ != 0) throw std::logic_error("Filter::clone inside a transaction");
  return do_clone();
}

void Filter::assign(const Filter& other) {
  if (typeid(*this) != typeid(other)) throw std::logic_error("Filter::assign: another filter implementation");
  if (depth_ != 0 || other.depth_ != 0) throw std::logic_error("Filter::assign inside a transaction");
  x_ = other.x_;
  P_ = other.P_;
  dirty_ = other.dirty_;
  do_assign(other);
}

Filter::Transaction::Transaction(Filter& f) : f_(f), outer_(f.depth_ == 0) {
  if (outer_) {
    f_.save();
    f_.saved_x_ = f_.x_;
    f_.saved_P_ = f_.P_;
    f_.saved_dirty_ = f_.dirty_;
  }
  ++f_.depth_;
}

void Filter::Transaction::commit(const char* step) {
  if (outer_) f_.check_result(step);
  committed_ = true;
}

Filter::Transaction::~Transaction() {
  --f_.depth_;
  if (outer_ && !committed_) {
    f_.restore();
    f_.x_ = f_.saved_x_;
    f_.P_ = f_.saved_P_;
    f_.dirty_ = f_.saved_dirty_;
  }
}

const State& Filter::x() const {
  if (dirty_) {
    estimate(x_, P_);
    dirty_ = false;
  }
  return x_;
}

const StateCov& Filter::P() const {
  x();
  return P_;
}

void Filter::check_result(const char* step) const {
  const State& x = this->x();
  const StateCov& P = this->P();
  if (!x.allFinite())
    refuse(step, "the state would become (" + num(x[0]) + ", " + num(x[1]) + ", " + num(x[2]) + ", " + num(x[3]) +
                     "), not finite");
  if (!P.allFinite())
    refuse(step, "the covariance would not be finite (diagonal " + num(P(0, 0)) + ", " + num(P(1, 1)) + ", " +
                     num(P(2, 2)) + ", " + num(P(3, 3)) + ")");
  // The EKF's P must stay a covariance; the particles' weighted covariance is
  // positive semi-definite by construction (it may be singular: one particle).
  if (type_ == FilterType::Ekf && !is_covariance(P))
    refuse(step, "the covariance would not be positive semi-definite (diagonal " + num(P(0, 0)) + ", " +
                     num(P(1, 1)) + ", " + num(P(2, 2)) + ", " + num(P(3, 3)) +
                     "): the prior covariance is too large against the input's for double precision");
  check_state(step);
}

template <class F>
UpdateResult Filter::checked(const char* step, F&& f) {
  Transaction tx(*this);
  const UpdateResult r = f();
  dirty_ = true;
  if (!std::isfinite(r.nis)) refuse(step, "NIS = " + num(r.nis) + " is not finite");
  tx.commit(step);
  return r;
}

void Filter::predict(const Control& u, double dt) {
  if (!(std::isfinite(dt) && dt > 0.0))
    throw std::invalid_argument("filter predict: dt = " + num(dt) + " s must be finite and > 0");
  if (!u.allFinite())
    throw std::invalid_argument("filter predict: control (" + num(u[0]) + ", " + num(u[1]) + ") is not finite");
  checked("filter predict", [&] {
    do_predict(u, dt);
    return UpdateResult{};
  });
}

UpdateResult Filter::update(const LandmarkMeasurement& m) {
  const char* step = "filter landmark update";
  const bool has_r = m.has_range(), has_b = m.has_bearing();
  if (!has_r && !has_b) throw std::invalid_argument(std::string(step) + ": neither a range nor a bearing");
  if (!m.landmark.allFinite())
    throw std::invalid_argument(std::string(step) + ": landmark (" + num(m.landmark[0]) + ", " + num(m.landmark[1]) +
                                ") is not finite");
  if (has_r && !(std::isfinite(m.range) && m.range >= 0.0))
    throw std::invalid_argument(std::string(step) + ": range = " + num(m.range) + " must be finite and >= 0");
  if (has_b && !std::isfinite(m.bearing))
    throw std::invalid_argument(std::string(step) + ": bearing = " + num(m.bearing) + " is not finite");
  if (has_r) check_std(m.range_std, step, "range_std");
  if (has_b) check_std(m.bearing_std, step, "bearing_std");
  return checked(step, [&] { return do_update(m); });
}

UpdateResult Filter::update_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  check_noise2(z, R, "filter position update");
  return checked("filter position update", [&] { return do_update_position(z, R); });
}

UpdateResult Filter::update_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  check_noise2(z, R, "filter speed_heading update");
  return checked("filter speed_heading update", [&] { return do_update_speed_heading(z, R); });
}

void Filter::set_gate(double probability) {
  if (!(std::isfinite(probability) && probability >= 0.0 && probability < 1.0))
    throw std::invalid_argument("gate probability = " + num(probability) + " must be in [0, 1) (0 disables the gate)");
  do_set_gate(probability);
}

// --------------------------- the implementations ----------------------------

namespace {

/// The EKF on the 4-state BMM (fixed-size arithmetic).
class EkfFilter final : public Filter {
 public:
  EkfFilter(const BmmParams& p, const State& x0, const StateCov& P0)
      : Filter(FilterType::Ekf, false, x0, P0), f_(p, x0, P0), spare_(f_) {}
  const Ekf* ekf() const override { return &f_; }

 private:
  void do_predict(const Control& u, double dt) override { f_.predict(u, dt); }
  UpdateResult do_update(const LandmarkMeasurement& m) override {
    // The landmark model (safenav/measurement.hpp) with k = b = 0.
    const State& x = f_.x();
    const LandmarkGeometry g = landmark_geometry(x[kX], x[kY], m.landmark.x(), m.landmark.y());
    if (!g.finite() || !g.defined())
      throw std::domain_error("EKF landmark update: the landmark is at the estimate or 1.8e308 from it");
    const bool has_r = m.has_range(), has_b = m.has_bearing();
    LandmarkJacobian Jr, Jb;
    const double hr = has_r ? predict_range(g, 0.0, 0.0, &Jr) : 0.0;
    const double hb = has_b ? predict_bearing(g, x[kTheta], &Jb) : 0.0;
    if (has_r && has_b) {
      const Eigen::Vector2d y(m.range - hr, wrap_angle(m.bearing - hb));
      Eigen::Matrix<double, 2, 4> H;
      H << Jr.x, Jr.y, 0.0, Jr.theta, Jb.x, Jb.y, 0.0, Jb.theta;
      const Eigen::Matrix2d R =
          Eigen::Vector2d(m.range_std * m.range_std, m.bearing_std * m.bearing_std).asDiagonal();
      return f_.update_linearized(y, H, R, MeasurementKind::RangeBearing);
    }
    const LandmarkJacobian& J = has_r ? Jr : Jb;
    Eigen::Matrix<double, 1, 1> y, R;
    Eigen::Matrix<double, 1, 4> H;
    H << J.x, J.y, 0.0, J.theta;
    y(0) = has_r ? m.range - hr : wrap_angle(m.bearing - hb);
    R(0) = has_r ? m.range_std * m.range_std : m.bearing_std * m.bearing_std;
    return f_.update_linearized(y, H, R, has_r ? MeasurementKind::Range : MeasurementKind::Bearing);
  }
  UpdateResult do_update_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) override {
    return f_.update_position(z, R);
  }
  UpdateResult do_update_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) override {
    // h(x) = (v, θ), H = [0 0 1 0; 0 0 0 1]: the arithmetic of update(MeasurementModel::speed_heading(R), z).
    const Eigen::Vector2d y = MeasurementModel::direct_residual(MeasurementKind::SpeedHeading, z, f_.x());
    Eigen::Matrix<double, 2, 4> H;
    H << 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0;
    return f_.update_linearized(y, H, R, MeasurementKind::SpeedHeading);
  }
  void do_set_gate(double p) override { f_.set_gate(p); }
  void estimate(State& x, StateCov& P) const override {
    x = f_.x();
    P = f_.P();
  }
  void check_state(const char*) const override {}
  void save() override { spare_ = f_; }
  void restore() override { f_ = spare_; }
  std::unique_ptr<Filter> do_clone() const override { return std::make_unique<EkfFilter>(*this); }
  void do_assign(const Filter& o) override { f_ = static_cast<const EkfFilter&>(o).f_; }

  Ekf f_, spare_;
};

/// The particle filter on the 4-state BMM.
class PfFilter final : public Filter {
 public:
  PfFilter(const BmmParams& p, const State& x0, const StateCov& P0, int n, std::uint64_t seed, double thr,
           double bandwidth_scale)
      : Filter(FilterType::ParticleFilter, false, x0, P0), f_(p, x0, P0, n, seed, thr, bandwidth_scale), spare_(f_) {}

 private:
  void do_predict(const Control& u, double dt) override { f_.predict(u, dt); }
  UpdateResult do_update(const LandmarkMeasurement& m) override {
    const Landmarks lm = m.landmark.transpose();
    if (m.has_range() && m.has_bearing())
      return f_.update(MeasurementModel::range_bearing(lm, m.range_std, m.bearing_std),
                       Eigen::Vector2d(m.range, m.bearing));
    if (m.has_range())
      return f_.update(MeasurementModel::range(lm, m.range_std), Eigen::Matrix<double, 1, 1>(m.range));
    return f_.update(MeasurementModel::bearing(lm, m.bearing_std), Eigen::Matrix<double, 1, 1>(m.bearing));
  }
  // Position and IMU models are reused while their covariance stays the same.
  UpdateResult do_update_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) override {
    if (!fix_ || fix_R_ != R) {
      fix_.emplace(MeasurementModel::position(R));
      fix_R_ = R;
    }
    return f_.update(*fix_, z);
  }
  UpdateResult do_update_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) override {
    if (!imu_ || imu_R_ != R) {
      imu_.emplace(MeasurementModel::speed_heading(R));
      imu_R_ = R;
    }
    return f_.update(*imu_, z);
  }
  void do_set_gate(double p) override { f_.set_gate(p); }
  void estimate(State& x, StateCov& P) const override {
    x = f_.mean();
    P = f_.covariance(x);
  }
  void check_state(const char*) const override {}
  void save() override { spare_ = f_; }
  void restore() override { f_ = spare_; }
  std::unique_ptr<Filter> do_clone() const override { return std::make_unique<PfFilter>(*this); }
  void do_assign(const Filter& o) override { f_ = static_cast<const PfFilter&>(o).f_; }

  ParticleFilter f_, spare_;
  std::optional<MeasurementModel> fix_, imu_;
  Eigen::Matrix2d fix_R_, imu_R_;
};

/// The landmark observation on an augmented filter (EKF or PF: the same calls).
template <class F>
UpdateResult update_augmented(F& f, const LandmarkMeasurement& m) {
  if (m.has_range() && m.has_bearing()) {
    const Eigen::Matrix2d R = Eigen::Vector2d(m.range_std * m.range_std, m.bearing_std * m.bearing_std).asDiagonal();
    return f.update_range_bearing(m.row, m.landmark, Eigen::Vector2d(m.range, m.bearing), R);
  }
  if (m.has_range()) return f.update_range(m.row, m.landmark, m.range, m.range_std * m.range_std);
  return f.update_bearing(m.row, m.landmark, m.bearing, m.bearing_std * m.bearing_std);
}

/// An augmented filter (EKF or PF: the same calls) behind Filter; the two
/// differ only in how they report their estimate and check their state.
template <class F>
class AugmentedFilter : public Filter {
 public:
  Eigen::VectorXd augmented_state() const override { return f_.augmented(); }

 protected:
  AugmentedFilter(FilterType type, const State& x0, const StateCov& P0, F f)
      : Filter(type, true, x0, P0), f_(std::move(f)), spare_(f_) {}
  F f_, spare_;

 private:
  void do_predict(const Control& u, double dt) override { f_.predict(u, dt); }
  UpdateResult do_update(const LandmarkMeasurement& m) override { return update_augmented(f_, m); }
  UpdateResult do_update_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) override {
    return f_.update_position(z, R);
  }
  UpdateResult do_update_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) override {
    return f_.update_speed_heading(z, R);
  }
  void do_set_gate(double p) override { f_.set_gate(p); }
  void save() override { spare_ = f_; }
  void restore() override { f_ = spare_; }
  void do_assign(const Filter& o) override { f_ = static_cast<const AugmentedFilter&>(o).f_; }
};

class AugmentedEkfFilter final : public AugmentedFilter<AugmentedEkf> {
 public:
  AugmentedEkfFilter(const BmmParams& p, const AugmentedStates& a, int K, const State& x0, const StateCov& P0)
      : AugmentedFilter(FilterType::Ekf, x0, P0, AugmentedEkf(p, a, K, x0, P0)), llt_(f_.size()) {}
  const AugmentedEkf* augmented_ekf() const override { return &f_; }

 private:
  std::unique_ptr<Filter> do_clone() const override { return std::make_unique<AugmentedEkfFilter>(*this); }
  void estimate(State& x, StateCov& P) const override {
    x = f_.x();
    P = f_.P();
  }
  void check_state(const char* step) const override {
    const Eigen::MatrixXd& P = f_.augmented_cov();
    if (!f_.augmented().allFinite() || !P.allFinite() || (P.diagonal().array() < 0.0).any() ||
        (llt_.compute(P).info() != Eigen::Success && !is_covariance(P)))
      refuse(step, "the augmented covariance would not be finite and positive semi-definite");
  }

  mutable Eigen::LLT<Eigen::MatrixXd> llt_;
};

class AugmentedPfFilter final : public AugmentedFilter<AugmentedParticleFilter> {
 public:
  AugmentedPfFilter(const BmmParams& p, const AugmentedStates& a, int K, const State& x0, const StateCov& P0, int n,
                    std::uint64_t seed, double thr, double bandwidth_scale)
      : AugmentedFilter(FilterType::ParticleFilter, x0, P0,
                        AugmentedParticleFilter(p, a, K, x0, P0, n, seed, thr, bandwidth_scale)) {}

 private:
  std::unique_ptr<Filter> do_clone() const override { return std::make_unique<AugmentedPfFilter>(*this); }
  void estimate(State& x, StateCov& P) const override {
    x = f_.mean();
    P = f_.covariance();
  }
  void check_state(const char* step) const override {
    if (!f_.particles().allFinite()) refuse(step, "a particle's augmented state would not be finite");
  }
};

}  // namespace

std::unique_ptr<Filter> make_filter(const FilterOptions& o, const BmmParams& params, const AugmentedStates& augment,
                                    int n_landmarks, const State& x0, const StateCov& P0, std::uint64_t seed) {
  o.validate("filter.");
  if (o.type == FilterType::InformationFilter)
    throw std::invalid_argument("filter.type = InformationFilter: the online filters are the EKF and the particle filter");
  std::unique_ptr<Filter> f;
  if (o.type == FilterType::Ekf && augment.any())
    f = std::make_unique<AugmentedEkfFilter>(params, augment, n_landmarks, x0, P0);
  else if (o.type == FilterType::Ekf)
    f = std::make_unique<EkfFilter>(params, x0, P0);
  else if (augment.any())
    f = std::make_unique<AugmentedPfFilter>(params, augment, n_landmarks, x0, P0, o.n_particles, seed,
                                            o.resample_threshold, o.bandwidth_scale);
  else
    f = std::make_unique<PfFilter>(params, x0, P0, o.n_particles, seed, o.resample_threshold, o.bandwidth_scale);
  if (o.gate_probability > 0.0) f->set_gate(o.gate_probability);
  return f;
}

}  // namespace safenav

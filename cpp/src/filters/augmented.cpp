// EKF over the BMM with augmented sensor-error states (safenav/augmented.hpp);
// its particle-filter counterpart is in augmented_pf.cpp.
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

State AugmentedEkf::step(const State& x4, double beta, const Control& u, double dt, Eigen::Matrix4d& F4,
                          Eigen::Matrix4d& G, Eigen::Vector4d& Fb, Eigen::Matrix4d& noise) const {
  // The BMM (eqs. 3–9) of Bmm::with_step(dt) evaluated at θ − β·dt gives
  // θ' = θ + clip(Δθ) − β·dt and p' moving along that θ' (eq. 7), with
  // F₄ = ∂f/∂(x, y, v, θ) and G = ∂f/∂ε; then ∂f/∂β = −dt·∂f/∂θ.
  if (!(std::isfinite(dt) && dt > 0.0))
    throw std::invalid_argument("AugmentedEkf predict: dt = " + num(dt) + " s must be finite and > 0");
  const Bmm step = bmm_.is_nominal_step(dt) ? bmm_ : bmm_.with_step(dt);
  State xs = x4;
  xs[kTheta] = x4[kTheta] - beta * dt;
  const State x1 = step.linearize(xs, u, &F4, &G);
  Fb = -dt * F4.col(kTheta);  // ∂f/∂β
  noise = step.noise_cov();
  return x1;
}

void AugmentedEkf::predict(const Control& u, double dt) {
  // Eq. 11 over dt with the bias-corrected heading change (step()).
  const double beta = ig_ >= 0 ? x_[ig_] : 0.0;
  Eigen::Matrix4d F4, G, noise;
  Eigen::Vector4d Fb;
  const State x1 = step(x4_, beta, u, dt, F4, G, Fb, noise);
  // F = [F₄ Fβ 0; 0 I]: only rows 0..3 change.  JP = rows 0..3 of F P.
  JP_.noalias() = F4 * P_.topRows<4>();
  if (ig_ >= 0) JP_.noalias() += Fb * P_.row(ig_);
  Eigen::Matrix4d TL = JP_.leftCols<4>() * F4.transpose();
  if (ig_ >= 0) TL.noalias() += JP_.col(ig_) * Fb.transpose();
  TL.noalias() += G * noise * G.transpose();
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
  add_walks(P_, dt);
  x_.head<4>() = x1;
  sync4();
  last_F4_ = F4;
  last_Fb_ = Fb;
  last_G_ = G;
  last_noise_ = noise;
  last_dt_ = dt;
}

void AugmentedEkf::transition(const Eigen::Ref<const Eigen::VectorXd>& x, const Control& u, double dt,
                              Eigen::Ref<Eigen::VectorXd> x1, Eigen::Ref<Eigen::MatrixXd> F,
                              Eigen::Ref<Eigen::MatrixXd> Q) const {
  // predict's f, F and Q (step(), add_walks) at x instead of the estimate.
  if (x.size() != n_ || x1.size() != n_ || F.rows() != n_ || F.cols() != n_ || Q.rows() != n_ || Q.cols() != n_)
    throw std::invalid_argument("AugmentedEkf.transition: x, x1 must have " + std::to_string(n_) +
                                " entries and F, Q be " + std::to_string(n_) + "x" + std::to_string(n_));
  Eigen::Matrix4d F4, G, noise;
  Eigen::Vector4d Fb;
  const State x4 = x.head<4>();
  x1 = x;
  x1.head<4>() = step(x4, ig_ >= 0 ? x[ig_] : 0.0, u, dt, F4, G, Fb, noise);
  F.setIdentity();
  F.topLeftCorner<4, 4>() = F4;
  if (ig_ >= 0) F.block<4, 1>(0, ig_) = Fb;
  Q.setZero();
  Q.topLeftCorner<4, 4>() = G * noise * G.transpose();
  add_walks(Q, dt);
}

void AugmentedEkf::add_walks(Eigen::Ref<Eigen::MatrixXd> P, double dt) const {
  if (ik_ >= 0) P(ik_, ik_) += augment_.scale_walk * augment_.scale_walk * dt;
  if (ig_ >= 0) P(ig_, ig_) += augment_.heading_rate_bias_walk * augment_.heading_rate_bias_walk * dt;
  if (ib0_ >= 0)
    for (int j = 0; j < n_landmarks_; ++j)
      P(ib0_ + j, ib0_ + j) += augment_.range_bias_walk * augment_.range_bias_walk * dt;
}

void AugmentedEkf::last_transition(Eigen::MatrixXd& F, Eigen::MatrixXd& Q) const {
  // predict's F = [F₄ Fβ 0; 0 I] and Q = diag(G Σ_ε Gᵀ, walks).
  F.setIdentity(n_, n_);
  F.topLeftCorner<4, 4>() = last_F4_;
  if (ig_ >= 0) F.block<4, 1>(0, ig_) = last_Fb_;
  Q.setZero(n_, n_);
  Q.topLeftCorner<4, 4>() = last_G_ * last_noise_ * last_G_.transpose();
  if (last_dt_ > 0.0) add_walks(Q, last_dt_);
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
  return apply<2>(MeasurementModel::direct_residual(MeasurementKind::Position, z, x_.head<4>()), R,
                  MeasurementKind::Position);
}

UpdateResult AugmentedEkf::update_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  check_finite2(z, "speed-heading");
  check_cov2(R, "AugmentedEkf speed-heading update:");
  H_.setZero();
  H_(0, kV) = 1.0;
  H_(1, kTheta) = 1.0;
  return apply<2>(MeasurementModel::direct_residual(MeasurementKind::SpeedHeading, z, x_.head<4>()), R,
                  MeasurementKind::SpeedHeading);
}

}  // namespace safenav

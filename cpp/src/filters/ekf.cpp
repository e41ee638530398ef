// Extended Kalman filter over the Battlefield Motion Model (eqs. 11–14).
#include <Eigen/Cholesky>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "checks.hpp"
#include "kalman_update.hpp"
#include "safenav/filters.hpp"

namespace safenav {

namespace {
void check_gate(double p) {
  if (!(std::isfinite(p) && p >= 0.0 && p < 1.0)) {
    std::ostringstream os;
    os << "gate probability = " << p << " must be in [0, 1) (0 disables the gate)";
    throw std::invalid_argument(os.str());
  }
}
}  // namespace

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

void Ekf::predict(const Control& u) { predict_with(bmm_, u); }

void Ekf::predict(const Control& u, double dt) {
  if (bmm_.is_nominal_step(dt)) predict_with(bmm_, u);
  else predict_with(bmm_.with_step(dt), u);
}

void Ekf::predict_with(const Bmm& bmm, const Control& u) {
  // Eq. 11: x̂ = f(x̂, u); P = F P Fᵀ + G Σ_ε Gᵀ.
  Eigen::Matrix4d F, G;
  const State x1 = bmm.linearize(x_, u, &F, &G);
  const Eigen::Vector4d sigma2 = bmm.noise_cov().diagonal();
  Eigen::Matrix4d P1 = F * P_ * F.transpose() + G * sigma2.asDiagonal() * G.transpose();
  P1 = 0.5 * (P1 + P1.transpose());
  commit(x1, P1, "EKF predict");
  last_F_ = F;
  last_G_ = G;
  last_sigma2_ = sigma2;
  last_dt_ = bmm.params().dt;
}

EkfTransition Ekf::last_transition() const {
  EkfTransition t;
  t.F = last_F_;
  t.Q = last_G_ * last_sigma2_.asDiagonal() * last_G_.transpose();  // eq. 11's G Σ_ε Gᵀ
  t.dt = last_dt_;
  return t;
}

void Ekf::commit(const State& x, const StateCov& P, const char* step) {
  // Finite inputs can still overflow (P = 1e308·I, say): refuse the step and keep the old state.
  if (!P.allFinite() || !x.allFinite()) {
    std::ostringstream os;
    os << "P = " << P_(0, 0) << ", " << P_(1, 1) << ", " << P_(2, 2) << ", " << P_(3, 3) << " (diagonal)";
    check_finite_result(x, (std::string(step) + " x").c_str(), os.str());
    check_finite_result(P, (std::string(step) + " P").c_str(), os.str());
  }
  x_ = x;
  P_ = P;
}

template <int M>
UpdateResult Ekf::update_fixed(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
  using VecM = Eigen::Matrix<double, M, 1>;
  using MatM4 = Eigen::Matrix<double, M, 4>;
  using MatMM = Eigen::Matrix<double, M, M>;
  const int m = model.dim();
  VecM zhat(m), y(m);
  MatM4 H(m, 4);
  model.predict(x_, zhat, H);
  model.residual(z, zhat, y);  // eq. 12, angle-aware
  const MatMM R = model.noise().cov();
  return apply<M>(y, H, R, model.kind());
}

template <int M>
UpdateResult Ekf::apply(const Eigen::Matrix<double, M, 1>& y, const Eigen::Matrix<double, M, 4>& H,
                        const Eigen::Matrix<double, M, M>& R, MeasurementKind kind) {
  // [SafeNav eqs. 12–14] in Joseph form: the update shared with AugmentedEkf (kalman_update.hpp).
  const int m = static_cast<int>(y.size());
  Eigen::Matrix<double, 4, M> PHt(4, m), unused(4, m);  // the fixed-size update keeps K, K R in locals
  StateCov P1;
  State x1;
  const UpdateResult res =
      kalman_update<M>("EKF", kind, x_, P_, y, H, R, [this](double nis, int dim) { return gate_rejects(nis, dim); },
                       KalmanWork{PHt, unused, unused, unused, P1, x1});
  if (res.accepted) commit(x1, P1, "EKF update");
  return res;
}

UpdateResult Ekf::update_linearized(const Eigen::Matrix<double, 1, 1>& y, const Eigen::Matrix<double, 1, 4>& H,
                                    const Eigen::Matrix<double, 1, 1>& R, MeasurementKind kind) {
  if (!(y.allFinite() && H.allFinite() && R(0, 0) > 0.0 && std::isfinite(R(0, 0))))
    throw std::invalid_argument(std::string("EKF ") + to_string(kind) +
                                " update: residual, Jacobian and variance must be finite, variance > 0");
  return apply<1>(y, H, R, kind);
}

UpdateResult Ekf::update_linearized(const Eigen::Vector2d& y, const Eigen::Matrix<double, 2, 4>& H,
                                    const Eigen::Matrix2d& R, MeasurementKind kind) {
  if (!(y.allFinite() && H.allFinite()))
    throw std::invalid_argument(std::string("EKF ") + to_string(kind) +
                                " update: residual and Jacobian must be finite");
  check_cov2(R, to_string(kind));
  return apply<2>(y, H, R, kind);
}

UpdateResult Ekf::update_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  if (!z.allFinite()) {
    std::ostringstream os;
    os << "EKF position update: z = (" << z[0] << ", " << z[1] << ") is not finite";
    throw std::invalid_argument(os.str());
  }
  check_cov2(R, "position");
  // Eqs. 12–14 with H = [I₂ 0] written out: P Hᵀ = P[:, :2], H P Hᵀ = P[:2, :2].
  // Same arithmetic as update_fixed<2>, without the products by zeros.
  const Eigen::Vector2d y = MeasurementModel::direct_residual(MeasurementKind::Position, z, x_);
  const Eigen::Matrix<double, 4, 2> PHt = P_.leftCols<2>();
  const Eigen::Matrix2d S = P_.topLeftCorner<2, 2>() + R;
  const Eigen::LLT<Eigen::Matrix2d> llt(S);
  if (llt.info() != Eigen::Success) {
    throw std::runtime_error("EKF position update: innovation covariance S is not positive definite");
  }
  UpdateResult res;
  res.dim = 2;
  res.nis = y.dot(llt.solve(y));
  res.log_det_s = log_det_from_cholesky(llt.matrixLLT().diagonal());
  check_nis(res.nis, "EKF", MeasurementKind::Position);
  check_log_det_s(res.log_det_s, "EKF", MeasurementKind::Position);
  if (gate_rejects(res.nis, 2)) {
    res.accepted = false;
    return res;
  }
  const Eigen::Matrix<double, 4, 2> K = llt.solve(PHt.transpose()).transpose();
  State x1 = x_ + K * y;
  x1[kTheta] = wrap_angle(x1[kTheta]);
  // Joseph form: A = (I − KH) P = P − K P[:2, :]; P = A (I − KH)ᵀ + K R Kᵀ = A − A[:, :2] Kᵀ + K R Kᵀ.
  const Eigen::Matrix4d A = P_ - K * P_.topRows<2>();
  const Eigen::Matrix4d P1 = A - A.leftCols<2>() * K.transpose() + K * R * K.transpose();
  commit(x1, 0.5 * (P1 + P1.transpose()), "EKF position update");
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

}  // namespace safenav

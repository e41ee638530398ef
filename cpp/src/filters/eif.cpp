// Extended information filter: the EKF in information form (Y = P⁻¹, y = Y x).
#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <sstream>
#include <stdexcept>
#include <string>

#include "checks.hpp"
#include "safenav/filters.hpp"

namespace safenav {

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
  if (!Pp.allFinite()) {
    std::ostringstream os;
    os << "dt = " << bmm_.params().dt << " and the prior P (diagonal " << P().diagonal().transpose() << ")";
    check_finite_result(Pp, "information filter predict P", os.str());
  }
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
  Eigen::MatrixXd H(model.dim(), 4);
  Eigen::VectorXd zhat(model.dim()), nu(model.dim());
  model.predict(xb, zhat, H);
  model.residual(z, zhat, nu);
  const Eigen::MatrixXd R = model.noise().cov();
  const Eigen::MatrixXd RinvH = R.ldlt().solve(H);  // R⁻¹ H
  UpdateResult res;
  res.dim = model.dim();
  const Eigen::MatrixXd S = H * P() * H.transpose() + R;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(S);
  res.nis = nu.dot(ldlt.solve(nu));
  res.log_det_s = ldlt.vectorD().array().log().sum();
  check_nis(res.nis, "information filter", model.kind());
  check_log_det_s(res.log_det_s, "information filter", model.kind());
  Eigen::Matrix4d Y1 = Y_ + H.transpose() * RinvH;
  Y1 = 0.5 * (Y1 + Y1.transpose());
  const State y1 = y_ + RinvH.transpose() * (nu + H * xb);
  if (!Y1.allFinite() || !y1.allFinite()) {
    throw std::invalid_argument(std::string("information filter ") + to_string(model.kind()) +
                                " update: the information overflows (measurement noise too small for its scale)");
  }
  Y_ = Y1;
  y_ = y1;
  return res;
}

}  // namespace safenav

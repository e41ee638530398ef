#include "checks.hpp"

#include <Eigen/Cholesky>
#include <boost/math/distributions/chi_squared.hpp>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace safenav {

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

void FilterOptions::validate(const std::string& prefix) const {
  std::ostringstream os;
  if (type == FilterType::ParticleFilter && n_particles < 1)
    os << prefix << "n_particles = " << n_particles << ": must be >= 1";
  else if (!(resample_threshold >= 0.0 && resample_threshold <= 1.0))
    os << prefix << "resample_threshold = " << resample_threshold << ": must be in [0, 1]";
  else if (!(bandwidth_scale >= 0.0 && bandwidth_scale <= 10.0))
    os << prefix << "bandwidth_scale = " << bandwidth_scale << ": must be in [0, 10]";
  else if (!(gate_probability >= 0.0 && gate_probability < 1.0))
    os << prefix << "gate_probability = " << gate_probability << ": must be in [0, 1) (0 = off)";
  else
    return;
  throw std::invalid_argument(os.str());
}

void check_nis(double nis, const char* filter, MeasurementKind kind) {
  if (std::isfinite(nis)) return;
  std::ostringstream os;
  os << filter << " " << to_string(kind) << " update: NIS = " << nis
     << " is not finite (the measurement is too far from the prediction for its covariance)";
  throw std::invalid_argument(os.str());
}
void check_prior(const State& x0, const StateCov& P0, const char* xname, const char* pname) {
  check_finite_state(x0, xname);
  check_covariance(P0, pname);
}

void check_cov2(const Eigen::Matrix2d& R, const char* what) {
  const bool symmetric = std::abs(R(0, 1) - R(1, 0)) <= 1e-9 * (std::abs(R(0, 1)) + std::abs(R(1, 0)) + 1e-300);
  if (!(R.allFinite() && symmetric && R(0, 0) > 0.0 && R(0, 0) * R(1, 1) - R(0, 1) * R(1, 0) > 0.0)) {
    std::ostringstream os;
    os << what << " R = [[" << R(0, 0) << ", " << R(0, 1) << "], [" << R(1, 0) << ", " << R(1, 1)
       << "]]: must be finite, symmetric and positive definite";
    throw std::invalid_argument(os.str());
  }
}

}  // namespace safenav

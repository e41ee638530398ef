#include "checks.hpp"

#include <Eigen/Cholesky>
#include <boost/math/distributions/chi_squared.hpp>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "../declare.hpp"

namespace safenav {

template <>
const ParamSet<FilterOptions>& param_set<FilterOptions>();  // defined below

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
  if (!symmetric_to_rounding(P)) {
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

void FilterOptions::validate(const std::string& prefix) const { param_set<FilterOptions>().check(*this, prefix); }

void check_nis(double nis, const char* filter, MeasurementKind kind) {
  if (std::isfinite(nis)) return;
  std::ostringstream os;
  os << filter << " " << to_string(kind) << " update: NIS = " << nis
     << " is not finite (the measurement is too far from the prediction for its covariance)";
  throw std::invalid_argument(os.str());
}
void check_log_det_s(double log_det_s, const char* filter, MeasurementKind kind) {
  if (std::isfinite(log_det_s)) return;
  std::ostringstream os;
  os << filter << " " << to_string(kind) << " update: log det S = " << log_det_s
     << ": the innovation covariance is not positive definite in double precision";
  throw std::invalid_argument(os.str());
}
void check_prior(const State& x0, const StateCov& P0, const char* xname, const char* pname) {
  check_finite_state(x0, xname);
  check_covariance(P0, pname);
}

void check_cov2(const Eigen::Matrix2d& R, const char* what) {
  if (!(R.allFinite() && symmetric_to_rounding(R) && R(0, 0) > 0.0 && R(0, 0) * R(1, 1) - R(0, 1) * R(1, 0) > 0.0)) {
    std::ostringstream os;
    os << what << " R = [[" << R(0, 0) << ", " << R(0, 1) << "], [" << R(1, 0) << ", " << R(1, 1)
       << "]]: must be finite, symmetric and positive definite";
    throw std::invalid_argument(os.str());
  }
}


// ---------------------------------------------------------------------------
// Parameter declarations (safenav/params.hpp)

template <>
const ParamSet<FilterOptions>& param_set<FilterOptions>() {
  using F = FilterOptions;
  // The type is a choice and the seed a 64-bit integer (a double would round it): set directly.
  static const ParamSet<F> s =
      Declare<F>{}
          .real("gate_probability", SN_REF(F, gate_probability), "", closed(0, 0.999999), "chi-square gate of each update (ours); 0 = off, the paper's loop; at 1 the gate would reject nothing")
          .integer("n_particles", SN_REF(F, n_particles), closed(1, 1e7), "particles of the particle filter")
          .real("resample_threshold", SN_REF(F, resample_threshold), "", closed(0, 1), "the particle filter resamples when the effective sample size falls below this share of n_particles")
          .real("bandwidth_scale", SN_REF(F, bandwidth_scale), "", closed(0, 10), "particle filter kernel bandwidth as a multiple of Musso et al.'s optimal h_opt = (4/(N(d+2)))^(1/(d+4)); 0 = the plain SIR filter (no kernel update, no covariance floor)")
          .set;
  return s;
}

template class ParamSet<FilterOptions>;

}  // namespace safenav

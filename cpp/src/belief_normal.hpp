// The pieces that the deviation mixture (belief_mixture.cpp) is built from: the standard
// normal's (the Gauss–Hermite rule, the truncated normal's moments and its inverse survival
// function) and the scaling that keeps its moments consistent (`excess`).
#pragma once

#include <algorithm>
#include <boost/math/distributions/normal.hpp>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

#include "belief_model.hpp"
#include "errors.hpp"

namespace safenav::belief {

/// The Gauss–Hermite rule of N(0, 1) with n = 3, 5 or 7 nodes
/// (numpy.polynomial.hermite_e.hermegauss, weights over √(2π)).
struct Quadrature {
  std::vector<double> node, weight;
  explicit Quadrature(int n) {
    if (n == 3) {
      node = {-std::sqrt(3.0), 0.0, std::sqrt(3.0)};
      weight = {1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0};
    } else if (n == 5) {
      node = {-2.8569700138728056, -1.355626179974266, 0.0, 1.355626179974266, 2.8569700138728056};
      weight = {0.011257411327720677, 0.22207592200561257, 8.0 / 15.0, 0.22207592200561257, 0.011257411327720677};
    } else if (n == 7) {
      node = {-3.7504397177257425, -2.366759410734541, -1.1544053947399682, 0.0,
              1.1544053947399682,  2.366759410734541,  3.7504397177257425};
      weight = {0.0005482688559722169, 0.030757123967586515, 0.24012317860501264, 16.0 / 35.0,
                0.24012317860501264,   0.030757123967586515, 0.0005482688559722169};
    } else {
      detail::bad("deviation_nodes = " + std::to_string(n) + ": must be 3, 5 or 7");
    }
  }
};

/// N(0, 1) restricted to [lo, hi] (either may be infinite): its mass, mean
/// and variance (the truncated normal's moments).
struct Interval {
  double lo = 0.0, hi = 0.0, mass = 1.0, mean = 0.0, var = 0.0;
};

inline Interval interval(double lo, double hi) {
  Interval c{lo, hi};
  // Differences of the far tail, so a cell far out keeps its digits.
  c.mass = lo >= 0.0 ? normal_sf(lo) - normal_sf(hi) : normal_sf(-hi) - normal_sf(-lo);
  const auto xpdf = [](double z) { return std::isfinite(z) ? z * normal_pdf(z) : 0.0; };
  const auto pdf = [](double z) { return std::isfinite(z) ? normal_pdf(z) : 0.0; };
  c.mean = std::clamp((pdf(lo) - pdf(hi)) / c.mass, lo, hi);
  c.var = std::max(0.0, 1.0 + (xpdf(lo) - xpdf(hi)) / c.mass - c.mean * c.mean);
  return c;
}

/// z with P(N(0, 1) > z) = p, 0 < p < 1 (Boost.Math's quantile, as the guard's k(ε)).
inline double normal_isf(double p) {
  return boost::math::quantile(boost::math::complement(boost::math::normal_distribution<double>(), p));
}

/// The divisor d ≥ 1 with X / d² ⪯ Y, the least (to a margin of 10⁻¹²):
/// √λ_max of X v = λ Y v where that exceeds 1, else 1; +∞ where Y is not
/// positive definite (scaled by 1/d, the part is then dropped).
inline double excess(const StateCov& X, const StateCov& Y) {
  const Eigen::GeneralizedSelfAdjointEigenSolver<StateCov> ges(0.5 * (X + X.transpose()), Y, Eigen::EigenvaluesOnly);
  if (ges.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
  const double lambda = ges.eigenvalues().maxCoeff();
  return lambda > 1.0 ? std::sqrt(lambda * (1.0 + 1e-12)) : 1.0;
}

/// A, scaled down where needed so that A P_prev Aᵀ ⪯ P_next: Patil's
/// recursion needs Cov w = P_next − A P_prev Aᵀ ⪰ 0.  A stratum's update
/// can raise its error (its filter trusts a fix more than its own, smaller
/// error warrants), so the mixture's update need not shrink it in every
/// direction.  The scale keeps the marginals and lowers only the correlation
/// of the errors between stages: toward independent stages, whose product
/// of survivals is close to the union bound for small probabilities.
inline Eigen::Matrix4d within_marginals(const Eigen::Matrix4d& A, const StateCov& P_prev, const StateCov& P_next) {
  const double d = excess(A * P_prev * A.transpose(), P_next);
  return d > 1.0 ? Eigen::Matrix4d(A / d) : A;
}

}  // namespace safenav::belief

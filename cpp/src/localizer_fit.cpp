// The localizer's start from ranges: the rigid-transform fit (localizer_fit.hpp).
#include "localizer_fit.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "safenav/types.hpp"

namespace safenav::detail {

bool fit_transform(const std::vector<RangeObs>& obs, double k0, Eigen::Vector3d& th, double& rms,
                   Eigen::Matrix3d& C) {
  const auto n = static_cast<Eigen::Index>(obs.size());
  Eigen::VectorXd e(n);
  Eigen::MatrixXd J(n, 3);
  std::vector<char> mask(obs.size(), 1);
  // Normalised residuals e = (z − h)/σ and J = ∂e/∂(X, Y, φ) over the masked rows.
  auto residuals = [&](const Eigen::Vector3d& th) {
    const double c = std::cos(th[2]), s = std::sin(th[2]);
    Eigen::Index m = 0;
    for (std::size_t i = 0; i < obs.size(); ++i) {
      if (!mask[i]) continue;
      const RangeObs& o = obs[i];
      const double dx = th[0] + c * o.qx - s * o.qy - o.ax, dy = th[1] + s * o.qx + c * o.qy - o.ay;
      const double rho = std::max(std::hypot(dx, dy), 1e-6), ux = dx / rho, uy = dy / rho;
      e[m] = (o.z - (1.0 + k0) * rho) / o.s;
      J(m, 0) = -(1.0 + k0) * ux / o.s;
      J(m, 1) = -(1.0 + k0) * uy / o.s;
      J(m, 2) = -(1.0 + k0) * (ux * (-s * o.qx - c * o.qy) + uy * (c * o.qx - s * o.qy)) / o.s;
      ++m;
    }
    return m;
  };
  auto gauss_newton = [&](Eigen::Vector3d th, int iters) {
    for (int it = 0; it < iters; ++it) {
      const Eigen::Index m = residuals(th);
      const Eigen::Vector3d step = J.topRows(m).completeOrthogonalDecomposition().solve(-e.head(m));
      th += step;
      if (step.cwiseAbs().maxCoeff() < 1e-6) break;
    }
    return th;
  };
  double ax = 0.0, ay = 0.0;
  for (const RangeObs& o : obs) ax += o.ax, ay += o.ay;
  ax /= static_cast<double>(n);
  ay /= static_cast<double>(n);
  const double seeds[5][2] = {{ax, ay}, {ax + 30, ay}, {ax - 30, ay}, {ax, ay + 30}, {ax, ay - 30}};
  double best_cost = std::numeric_limits<double>::infinity();
  Eigen::Vector3d best = Eigen::Vector3d::Zero();
  for (int h = 0; h < 16; ++h) {
    const double phi0 = -kPi + 2.0 * kPi * h / 16.0;
    for (const auto& sd : seeds) {
      const Eigen::Vector3d th = gauss_newton(Eigen::Vector3d(sd[0], sd[1], phi0), 15);
      const Eigen::Index m = residuals(th);
      const double cost = e.head(m).squaredNorm();
      if (cost < best_cost) best_cost = cost, best = th;
    }
  }
  if (!std::isfinite(best_cost)) return false;
  // Drop residuals over 3σ and refit once.
  residuals(best);
  int inliers = 0;
  for (Eigen::Index i = 0; i < n; ++i) inliers += (mask[i] = std::abs(e[i]) < 3.0);
  if (inliers < 3) return false;
  th = gauss_newton(best, 20);
  const Eigen::Index m = residuals(th);
  double ss = 0.0;
  for (Eigen::Index i = 0, r = 0; i < n; ++i)
    if (mask[i]) ss += (e[r] * obs[i].s) * (e[r] * obs[i].s), ++r;
  rms = std::sqrt(ss / static_cast<double>(m));
  const Eigen::Matrix3d JtJ = J.topRows(m).transpose() * J.topRows(m);
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(JtJ);
  if (!lu.isInvertible()) return false;
  C = lu.inverse();
  return true;
}

}  // namespace safenav::detail

// trilateration_models.hpp — the measurement models, the weighted cost, the
// normal equations and each model's linear starting point that
// trilateration.cpp's solvers share (ranges and absolute bearings), kept
// apart from the solvers.
#pragma once

#include <limits>
#include <vector>
#include <Eigen/Core>
#include <Eigen/QR>
#include <cmath>

#include "safenav/measurement.hpp"
#include "safenav/trilateration.hpp"

namespace safenav::trilateration_detail {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// One measurement model over a set of anchors: residual z − h(p) and the
/// Jacobian row ∂h/∂p.
struct RangeModel {
  static constexpr int kMinimal = 3;
  static constexpr const char* kWhat = "ranges";
  /// The landmark model (safenav/measurement.hpp) with k = b = 0 and the anchor as the landmark.
  double residual(const Eigen::Vector2d& p, const Eigen::Vector2d& a, double z) const {
    return z - predict_range(landmark_geometry(p.x(), p.y(), a.x(), a.y()), 0.0, 0.0);
  }
  Eigen::RowVector2d jacobian(const Eigen::Vector2d& p, const Eigen::Vector2d& a) const {
    const LandmarkGeometry g = landmark_geometry(p.x(), p.y(), a.x(), a.y());
    LandmarkJacobian J;
    if (!(g.r > 0.0)) return Eigen::RowVector2d::Zero();
    predict_range(g, 0.0, 0.0, &J);
    return Eigen::RowVector2d(J.x, J.y);
  }
};

/// Absolute bearings: the landmark model's relative bearing at heading 0.
struct BearingModel {
  static constexpr int kMinimal = 2;
  static constexpr const char* kWhat = "bearings";
  double residual(const Eigen::Vector2d& p, const Eigen::Vector2d& a, double z) const {
    return wrap_angle(z - predict_bearing(landmark_geometry(p.x(), p.y(), a.x(), a.y()), 0.0));
  }
  Eigen::RowVector2d jacobian(const Eigen::Vector2d& p, const Eigen::Vector2d& a) const {
    const LandmarkGeometry g = landmark_geometry(p.x(), p.y(), a.x(), a.y());
    LandmarkJacobian J;
    if (!(g.q > 0.0)) return Eigen::RowVector2d::Zero();
    predict_bearing(g, 0.0, &J);
    return Eigen::RowVector2d(J.x, J.y);
  }
};

struct Problem {
  const Eigen::Ref<const Anchors>& anchors;
  const Eigen::Ref<const Eigen::VectorXd>& z;
  const Eigen::Ref<const Eigen::VectorXd>& sigma;
  Eigen::Vector2d a(int i) const { return anchors.row(i).transpose(); }
};

struct Fit {
  Eigen::Vector2d p = Eigen::Vector2d::Constant(kNaN);
  double cost = kNaN;
  int iterations = 0;
  bool converged = false;
};

template <class Model>
double cost_at(const Model& m, const Problem& pr, const std::vector<int>& idx, const Eigen::Vector2d& p) {
  double c = 0.0;
  for (int i : idx) {
    const double e = m.residual(p, pr.a(i), pr.z[i]) / pr.sigma[i];
    c += e * e;
  }
  return c;
}

/// Weighted normal equations A = Jᵀ W J, g = Jᵀ W e at p.
template <class Model>
void normal_equations(const Model& m, const Problem& pr, const std::vector<int>& idx, const Eigen::Vector2d& p,
                      Eigen::Matrix2d& A, Eigen::Vector2d& g) {
  A.setZero();
  g.setZero();
  for (int i : idx) {
    const double w = 1.0 / (pr.sigma[i] * pr.sigma[i]);
    const Eigen::RowVector2d J = m.jacobian(p, pr.a(i));
    A.noalias() += w * J.transpose() * J;
    g.noalias() += (w * m.residual(p, pr.a(i), pr.z[i])) * J.transpose();
  }
}

/// Linear start for ranges: 2aᵢᵀp − s = |aᵢ|² − rᵢ² with s = |p|² (3 unknowns).
inline bool linear_start(const RangeModel&, const Problem& pr, const std::vector<int>& idx, Eigen::Vector2d& p) {
  const int k = static_cast<int>(idx.size());
  Eigen::MatrixXd M(k, 3);
  Eigen::VectorXd b(k);
  for (int r = 0; r < k; ++r) {
    const int i = idx[r];
    const Eigen::Vector2d a = pr.a(i);
    const double w = 1.0 / pr.sigma[i];
    M.row(r) << 2.0 * a.x() * w, 2.0 * a.y() * w, -w;
    b[r] = (a.squaredNorm() - pr.z[i] * pr.z[i]) * w;
  }
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(M);
  if (qr.rank() < 3) return false;
  const Eigen::Vector3d sol = qr.solve(b);
  p = sol.head<2>();
  return p.allFinite();
}

/// Linear start for bearings: nᵢᵀp = nᵢᵀaᵢ with nᵢ = (−sin βᵢ, cos βᵢ).
inline bool linear_start(const BearingModel&, const Problem& pr, const std::vector<int>& idx, Eigen::Vector2d& p) {
  const int k = static_cast<int>(idx.size());
  Eigen::MatrixXd M(k, 2);
  Eigen::VectorXd b(k);
  for (int r = 0; r < k; ++r) {
    const int i = idx[r];
    const Eigen::Vector2d nrm(-std::sin(pr.z[i]), std::cos(pr.z[i]));
    M.row(r) = nrm.transpose();
    b[r] = nrm.dot(pr.a(i));
  }
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(M);
  if (qr.rank() < 2) return false;
  p = qr.solve(b);
  return p.allFinite();
}

}  // namespace safenav::trilateration_detail

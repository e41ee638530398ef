// safenav/types.hpp — the core's basic types: the vehicle state and control,
// arrays of 2-D points and row-major matrices (numpy's layout), π, and angle
// wrapping.  Every other header takes them from here.
#pragma once

#include <cmath>
#include <Eigen/Core>

namespace safenav {

/// State x = (x, y, v, θ): position [m], speed [m/s], heading [rad, wrapped to (−π, π]].
using State = Eigen::Vector4d;
using StateCov = Eigen::Matrix4d;     ///< covariance of State
/// Control u = (desired speed v_desired [m/s], heading change Δθ [rad]).
using Control = Eigen::Vector2d;

/// Index of each state component.
enum StateIndex : int { kX = 0, kY = 1, kV = 2, kTheta = 3 };

/// Row-major arrays, one row per point, state or time step (numpy's layout).
using RowMatrixX2 = Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>;
using RowMatrixX4 = Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>;
using RowMatrixX16 = Eigen::Matrix<double, Eigen::Dynamic, 16, Eigen::RowMajor>;
using RowMatrixXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
/// N×2 points (x, y).
using Points2 = RowMatrixX2;
using BoolVector = Eigen::Matrix<bool, Eigen::Dynamic, 1>;

constexpr double kPi = 3.14159265358979323846;

/// Wrap an angle to (−π, π] for any finite input.  Non-finite input is returned unchanged.
inline double wrap_angle_slow(double a) {
  if (!std::isfinite(a)) return a;
  double r = std::remainder(a, 2.0 * kPi);  // in [−π, π]
  if (r <= -kPi) r += 2.0 * kPi;
  return r;
}

/// Wrap an angle to (−π, π].  Non-finite input is returned unchanged.  Angles
/// within 3π of zero cost one comparison and at most one subtraction.
inline double wrap_angle(double a) {
  constexpr double two_pi = 2.0 * kPi;
  if (a > -kPi && a <= kPi) return a;
  if (a > kPi && a <= 3.0 * kPi) return a - two_pi;
  if (a <= -kPi && a > -3.0 * kPi) return a + two_pi;
  return wrap_angle_slow(a);
}

}  // namespace safenav

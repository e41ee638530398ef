// Private helpers for the core's error messages (std::invalid_argument, which
// the Python bindings turn into ValueError).
#pragma once

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include <Eigen/Core>

namespace safenav::detail {

[[noreturn]] inline void bad(const std::string& what) { throw std::invalid_argument(what); }

/// A number in a message: the stream's default 6 significant digits, or `precision`.
inline std::string num(double v, int precision = 6) {
  std::ostringstream os;
  os.precision(precision);
  os << v;
  return os.str();
}

inline void require_finite_positive(double v, const char* name) {
  if (!std::isfinite(v) || v <= 0.0) bad(std::string(name) + " = " + num(v) + ": must be finite and > 0");
}

inline void require_finite_nonneg(double v, const char* name) {
  if (!std::isfinite(v) || v < 0.0) bad(std::string(name) + " = " + num(v) + ": must be finite and >= 0");
}

/// "(x, y)" with the stream's default precision.
inline std::string fmt(const Eigen::Vector2d& p) {
  std::ostringstream s;
  s << "(" << p.x() << ", " << p.y() << ")";
  return s.str();
}

}  // namespace safenav::detail

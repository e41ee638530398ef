// Private helpers for the core's error messages (std::invalid_argument, which
// the Python bindings turn into ValueError).
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

#include <Eigen/Core>

namespace safenav::detail {

[[noreturn]] inline void bad(const std::string& what) { throw std::invalid_argument(what); }

/// "(x, y)" with the stream's default precision.
inline std::string fmt(const Eigen::Vector2d& p) {
  std::ostringstream s;
  s << "(" << p.x() << ", " << p.y() << ")";
  return s.str();
}

}  // namespace safenav::detail

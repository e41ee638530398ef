// ParamSpec: the range text and check of one declared parameter
// (safenav/params.hpp).  The declarations themselves live beside their
// structs, in the .cpp of each area, built with declare.hpp.
#include "safenav/params.hpp"

#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

#include "declare.hpp"

namespace safenav {

namespace {

/// The shortest text that reads back as v (1e-06, not 9.9999999999999995e-07).
std::string number(double v) {
  std::string text;
  for (int precision = 15; precision <= 17; ++precision) {
    std::ostringstream os;
    os.precision(precision);
    os << v;
    text = os.str();
    if (!std::isfinite(v) || std::strtod(text.c_str(), nullptr) == v) break;
  }
  return text;
}

}  // namespace

void detail::check_param_value(const ParamSpec& s, const std::vector<double>& v, const std::string& prefix) {
  if (s.kind != ParamKind::RealList) {
    if (v.size() != 1)
      throw std::invalid_argument(prefix + s.name + ": needs one value, got " + std::to_string(v.size()));
    s.check(v[0], prefix);
    return;
  }
  if (v.empty() || static_cast<int>(v.size()) > s.max_size)
    throw std::invalid_argument(prefix + s.name + ": needs 1 to " + std::to_string(s.max_size) + " entries, got " +
                                std::to_string(v.size()));
  for (std::size_t i = 0; i < v.size(); ++i) {
    ParamSpec item = s;
    item.name += "[" + std::to_string(i) + "]";
    item.check(v[i], prefix);
  }
}

std::string ParamSpec::range_text() const {
  if (kind == ParamKind::Boolean) return "{0, 1}";
  const bool whole = kind == ParamKind::Integer;
  auto fmt = [whole](double v) { return whole ? std::to_string(static_cast<long long>(v)) : number(v); };
  return (lo_open ? "(" : "[") + fmt(lo) + ", " + fmt(hi) + "]";
}

void ParamSpec::check(double v, const std::string& prefix) const {
  if (kind == ParamKind::Boolean) {
    if (!(v == 0.0 || v == 1.0))
      throw std::invalid_argument(prefix + name + " = " + number(v) + ": must be a boolean (0 or 1)");
    return;
  }
  // An infinite hi (no upper limit) admits +inf itself ("none": BoxRangeOptions::max_range).
  const bool ok = (std::isfinite(v) || (std::isinf(hi) && v == hi)) && (lo_open ? v > lo : v >= lo) && v <= hi &&
                  (kind != ParamKind::Integer || v == std::floor(v));
  if (!ok) {
    throw std::invalid_argument(prefix + name + " = " + number(v) + ": must be " +
                                (kind == ParamKind::Integer ? "an integer " : "") + "in " + range_text() +
                                (unit.empty() ? "" : " " + unit));
  }
}

}  // namespace safenav

// LocalizationOptions (safenav/trilateration.hpp): its parameter
// declarations and validation.  A sibling of trilateration.cpp, which is at
// the 600-line limit.
#include "safenav/trilateration.hpp"

#include <limits>
#include <stdexcept>

#include "declare.hpp"
#include "errors.hpp"

namespace safenav {

template <>
const ParamSet<LocalizationOptions>& param_set<LocalizationOptions>();  // defined below

void LocalizationOptions::validate() const {
  param_set<LocalizationOptions>().check(*this);
  // Beyond the closed range: lines crossing at pi/2 are perpendicular, never parallel.
  if (!(min_crossing_angle < kPi / 2))
    detail::bad("min_crossing_angle = " + detail::num(min_crossing_angle) + ": must be below pi/2");
}

template <>
const ParamSet<LocalizationOptions>& param_set<LocalizationOptions>() {
  using O = LocalizationOptions;
  constexpr double kNone = std::numeric_limits<double>::infinity();
  // The seed is a 64-bit integer (a double would round it): set directly.
  static const ParamSet<O> s =
      Declare<O>{}
          .real("outlier_threshold", SN_REF(O, outlier_threshold), "", above(0, 1e3), "a measurement is an outlier when |residual| / sigma exceeds this")
          .flag("reject_outliers", SN_REF(O, reject_outliers), "reject outliers (only with more measurements than the minimal set)")
          .integer("max_iterations", SN_REF(O, max_iterations), closed(1, 1e6), "Gauss-Newton / Levenberg-Marquardt iteration limit")
          .real("tolerance", SN_REF(O, tolerance), "", above(0, 1), "relative step tolerance of the iteration")
          .real("max_gdop", SN_REF(O, max_gdop), "", above(0, kNone), "GDOP above this is degenerate geometry; inf = never")
          .real("ambiguity_margin", SN_REF(O, ambiguity_margin), "", closed(0, 1e6), "a second solution within this chi-square margin of the best, more than 3 sigma away, makes the fix ambiguous")
          .real("profile_probability", SN_REF(O, profile_probability), "", closed(0, 0.999999), "widen each principal axis of the covariance until the cost's profile rises by the chi-square (2 dof) quantile at this probability where the Gaussian's contour is; 0 = the linear covariance alone")
          .real("min_crossing_angle", SN_REF(O, min_crossing_angle), "rad", closed(0, kPi / 2), "bearing lines crossing at less than this are parallel (below pi/2)")
          .integer("max_subsets", SN_REF(O, max_subsets), closed(1, 1e7), "minimal sets tried for outlier rejection: all when at most this many, else this many drawn with the seed")
          .set;
  return s;
}

template class ParamSet<LocalizationOptions>;

}  // namespace safenav

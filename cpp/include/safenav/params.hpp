// safenav/params.hpp — each parameter declared once: its name, unit, valid
// range and meaning, beside the core struct that holds it (whose member
// initialiser is the default).
//
// Modelled on OMPL's ParamSet/GenericParam: one declaration gives the getter,
// the setter, the range check and the documentation, so that scenario files,
// the Python layer and benchmarks read and write parameters generically
// instead of mirroring every field.  param_set<T>() is specialised for each
// settings struct in the source file of the area that implements it (see
// below), built with the private cpp/src/declare.hpp; a struct that holds
// another includes the nested struct's declared set under a name prefix
// (Declare::nested), so that each field is declared once.  The Python
// bindings expose each as T.params(), T.get_param(name) and
// T.set_param(name, value), and safenav.scenario builds its sections from them.
//
// Only std types appear here.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <variant>
#include <vector>

namespace safenav {

enum class ParamKind {
  Real,      ///< a double
  Integer,   ///< an integer (int or int64 member)
  RealList,  ///< a list of doubles, each in the range, 1 … max_size entries
  Boolean,   ///< a bool switch, read and written as 0 or 1 (range [0, 1])
};

/// One parameter's declaration.  The range is [lo, hi], open at lo when
/// lo_open; hi = +inf means no upper limit (+inf itself then allowed, for a
/// parameter whose infinite default means "none").  Values are checked
/// against it by ParamSet::set and ::check.
struct ParamSpec {
  std::string name;
  ParamKind kind = ParamKind::Real;
  std::string unit;  ///< SI unit ("m", "m/s", "rad", …); empty = dimensionless
  double lo = 0.0;
  double hi = 0.0;
  bool lo_open = false;
  int max_size = 0;  ///< RealList: the most entries
  std::string doc;   ///< one line; cites the paper where the parameter comes from

  /// "(lo, hi]" or "[lo, hi]" (integers without decimals); "{0, 1}" for a Boolean.
  std::string range_text() const;
  /// Throws std::invalid_argument "prefix.name = value: must be in range" unless v is in range.
  void check(double v, const std::string& prefix = "") const;
};

/// The parameters of settings struct T.  Members are reached through accessor
/// functions, so that a parameter may live in a nested struct (e.g. the
/// segment length inside NavigationSettings::segments).
template <class T>
class ParamSet {
 public:
  using RealRef = std::function<double&(T&)>;
  using IntRef = std::function<int&(T&)>;
  using Int64Ref = std::function<std::int64_t&(T&)>;
  using ListRef = std::function<std::vector<double>&(T&)>;
  using BoolRef = std::function<bool&(T&)>;
  using Ref = std::variant<RealRef, IntRef, Int64Ref, ListRef, BoolRef>;

  struct Entry {
    ParamSpec spec;
    Ref ref;
  };

  ParamSet& add(ParamSpec spec, Ref ref);

  const std::vector<Entry>& entries() const { return entries_; }
  std::vector<ParamSpec> specs() const;
  const Entry& entry(const std::string& name) const;  ///< throws std::invalid_argument on an unknown name

  /// The value (one entry for scalars) of parameter `name` of `t`.
  std::vector<double> get(const T& t, const std::string& name) const;
  /// Checks and sets; throws std::invalid_argument naming the parameter.
  void set(T& t, const std::string& name, const std::vector<double>& value) const;
  /// Throws std::invalid_argument naming the first parameter of `t` out of its range.
  void check(const T& t, const std::string& prefix = "") const;

 private:
  std::vector<Entry> entries_;
};

/// The parameter set of settings struct T, specialised beside each struct:
///   BmmParams                          cpp/src/motion.cpp
///   RiskZones, SegmentOptions          cpp/src/corridor.cpp
///   PlanningMap, Inflation             cpp/src/world.cpp
///   PlannerSettings                    cpp/src/planning.cpp
///   BeliefSettings, BeliefPlannerSettings  cpp/src/belief.cpp
///   GuardSettings                      cpp/src/guard.cpp
///   NavigationSettings                 cpp/src/navigation_settings.cpp
///   SensorSettings                     cpp/src/navigation.cpp
///   PositionNoise                      cpp/src/noise.cpp
///   FilterOptions                      cpp/src/filters/checks.cpp
///   AugmentedStates                    cpp/src/filters/augmented_params.cpp
///   LocalizerSettings                  cpp/src/localizer_params.cpp
///   LocalizationOptions                cpp/src/trilateration_params.cpp
///   BoxRangeOptions                    cpp/src/stereo.cpp
/// (a *_params.cpp file is a sibling of an area file near the 600-line limit).
template <class T>
const ParamSet<T>& param_set();

}  // namespace safenav

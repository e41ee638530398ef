// Parameter declarations (safenav/params.hpp): name, unit, range and meaning
// of each settings field, once.  Defaults are the structs' member initialisers.
// The ranges are physical limits (docs/scenario.md says why each one); the
// structs' validate() checks them after their own invariants.
#include "safenav/params.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "safenav/augmented.hpp"
#include "safenav/localizer.hpp"
#include "safenav/navigation.hpp"

namespace safenav {

namespace {

std::string number(double v) {
  std::ostringstream os;
  os.precision(17);
  os << v;
  return os.str();
}

template <class... F>
struct Overload : F... {
  using F::operator()...;
};
template <class... F>
Overload(F...) -> Overload<F...>;

/// Checks a value of parameter `s` (each entry of a list, named name[i]).
void check_value(const ParamSpec& s, const std::vector<double>& v, const std::string& prefix) {
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

}  // namespace

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
  const bool ok = std::isfinite(v) && (lo_open ? v > lo : v >= lo) && v <= hi &&
                  (kind != ParamKind::Integer || v == std::floor(v));
  if (!ok) {
    throw std::invalid_argument(prefix + name + " = " + number(v) + ": must be " +
                                (kind == ParamKind::Integer ? "an integer " : "") + "in " + range_text() +
                                (unit.empty() ? "" : " " + unit));
  }
}

template <class T>
ParamSet<T>& ParamSet<T>::add(ParamSpec spec, Ref ref) {
  entries_.push_back({std::move(spec), std::move(ref)});
  return *this;
}

template <class T>
std::vector<ParamSpec> ParamSet<T>::specs() const {
  std::vector<ParamSpec> out;
  for (const auto& e : entries_) out.push_back(e.spec);
  return out;
}

template <class T>
const typename ParamSet<T>::Entry& ParamSet<T>::entry(const std::string& name) const {
  for (const auto& e : entries_)
    if (e.spec.name == name) return e;
  std::string known;
  for (const auto& e : entries_) known += (known.empty() ? "" : ", ") + e.spec.name;
  throw std::invalid_argument("unknown parameter '" + name + "' (known: " + known + ")");
}

template <class T>
std::vector<double> ParamSet<T>::get(const T& t, const std::string& name) const {
  T& m = const_cast<T&>(t);  // the accessors return references; get only reads
  return std::visit(Overload{[&](const RealRef& r) { return std::vector<double>{r(m)}; },
                             [&](const IntRef& r) { return std::vector<double>{static_cast<double>(r(m))}; },
                             [&](const Int64Ref& r) { return std::vector<double>{static_cast<double>(r(m))}; },
                             [&](const ListRef& r) { return r(m); },
                             [&](const BoolRef& r) { return std::vector<double>{r(m) ? 1.0 : 0.0}; }},
                    entry(name).ref);
}

template <class T>
void ParamSet<T>::set(T& t, const std::string& name, const std::vector<double>& value) const {
  const Entry& e = entry(name);
  check_value(e.spec, value, "");
  std::visit(Overload{[&](const RealRef& r) { r(t) = value[0]; },
                      [&](const IntRef& r) { r(t) = static_cast<int>(value[0]); },
                      [&](const Int64Ref& r) { r(t) = static_cast<std::int64_t>(value[0]); },
                      [&](const ListRef& r) { r(t) = value; },
                      [&](const BoolRef& r) { r(t) = value[0] != 0.0; }},
             e.ref);
}

template <class T>
void ParamSet<T>::check(const T& t, const std::string& prefix) const {
  for (const auto& e : entries_) check_value(e.spec, get(t, e.spec.name), prefix);
}

// ---------------------------------------------------------------------------
// The declarations

namespace {

struct Range {
  double lo, hi;
  bool lo_open;
};
constexpr Range closed(double lo, double hi) { return {lo, hi, false}; }
constexpr Range above(double lo, double hi) { return {lo, hi, true}; }  ///< (lo, hi]

/// Builds a ParamSet with one line per parameter.
template <class T>
struct Declare {
  ParamSet<T> set;
  using PS = ParamSet<T>;

  static ParamSpec spec(const char* name, ParamKind kind, const char* unit, Range r, const char* doc, int max_size = 0) {
    return ParamSpec{name, kind, unit, r.lo, r.hi, r.lo_open, max_size, doc};
  }
  Declare& real(const char* name, typename PS::RealRef ref, const char* unit, Range r, const char* doc) {
    set.add(spec(name, ParamKind::Real, unit, r, doc), std::move(ref));
    return *this;
  }
  Declare& integer(const char* name, typename PS::IntRef ref, Range r, const char* doc) {
    set.add(spec(name, ParamKind::Integer, "", r, doc), std::move(ref));
    return *this;
  }
  Declare& integer64(const char* name, typename PS::Int64Ref ref, Range r, const char* doc) {
    set.add(spec(name, ParamKind::Integer, "", r, doc), std::move(ref));
    return *this;
  }
  Declare& flag(const char* name, typename PS::BoolRef ref, const char* doc) {
    set.add(spec(name, ParamKind::Boolean, "", closed(0, 1), doc), std::move(ref));
    return *this;
  }
  Declare& list(const char* name, typename PS::ListRef ref, const char* unit, Range r, int max_size, const char* doc) {
    set.add(spec(name, ParamKind::RealList, unit, r, doc, max_size), std::move(ref));
    return *this;
  }
};

// Member accessors: SN_REF(T, member) reaches t.member (nested members too).
#define SN_REF(T, member) [](T& t) -> auto& { return t.member; }

constexpr int kMaxIterations = 1'000'000;  ///< RAw-RRT* iterations of one plan
constexpr int kMaxZones = 64;              ///< RiskZones::weights entries

}  // namespace

template <>
const ParamSet<BmmParams>& param_set<BmmParams>() {
  static const ParamSet<BmmParams> s =
      Declare<BmmParams>{}
          .real("acceleration", SN_REF(BmmParams, acceleration), "m/s^2", above(0, 100), "a, acceleration capability [SafeNav eq. 3]")
          .real("deceleration", SN_REF(BmmParams, deceleration), "m/s^2", above(0, 100), "d, deceleration capability [SafeNav eq. 3]")
          .real("max_speed", SN_REF(BmmParams, max_speed), "m/s", above(0, 100), "v_max [SafeNav eq. 3]")
          .real("max_heading_rate", SN_REF(BmmParams, max_heading_rate), "rad/s", above(0, 100), "m, manoeuvrability: |dtheta| <= m*dt [SafeNav eq. 4]")
          .real("dt", SN_REF(BmmParams, dt), "s", above(0, 10), "the time step dt")
          .real("terrain_effect", SN_REF(BmmParams, terrain_effect), "", closed(0, 100), "tau, terrain effect [SafeNav eq. 8] (see BmmParams)")
          .real("speed_noise", SN_REF(BmmParams, speed_noise), "m/s", closed(0, 10), "sigma of eps_v per step [SafeNav eq. 6]")
          .real("heading_noise", SN_REF(BmmParams, heading_noise), "rad", closed(0, kPi), "sigma of eps_theta per step [SafeNav eq. 6]")
          .real("position_noise", SN_REF(BmmParams, position_noise), "m", closed(0, 10), "sigma of eps_x, eps_y per step [SafeNav eq. 7]")
          .set;
  return s;
}

template <>
const ParamSet<RiskZones>& param_set<RiskZones>() {
  static const ParamSet<RiskZones> s =
      Declare<RiskZones>{}
          .real("half_width", SN_REF(RiskZones, half_width), "m", above(0, 1000), "d_max, the safe buffer's half-width [SafeNav eq. 18]")
          .list("weights", SN_REF(RiskZones, weights), "", above(0, 1e6), kMaxZones, "w_1..w_n, the zones' weights, inner to outer [SafeNav eq. 18]")
          .set;
  return s;
}

template <>
const ParamSet<PlannerSettings>& param_set<PlannerSettings>() {
  static const ParamSet<PlannerSettings> s =
      Declare<PlannerSettings>{}
          .real("alpha", SN_REF(PlannerSettings, alpha), "", above(0, 1e6), "alpha, weight of the length term [SafeNav eq. 19]")
          .real("beta", SN_REF(PlannerSettings, beta), "", closed(0, 1e6), "beta, weight of the risk term [SafeNav eq. 19]; 0 = plain RRT*")
          .real("range", SN_REF(PlannerSettings, range), "m", closed(0, 1e6), "longest tree edge; 0 = OMPL's default (20 % of the field's diagonal)")
          .real("goal_bias", SN_REF(PlannerSettings, goal_bias), "", closed(0, 1), "probability of sampling the goal")
          .integer64("max_iterations", SN_REF(PlannerSettings, max_iterations), closed(1, kMaxIterations), "RRT* iterations (the deterministic budget)")
          .real("max_time", SN_REF(PlannerSettings, max_time), "s", closed(0, 1e6), "wall-clock budget; 0 = none")
          .real("resolution", SN_REF(PlannerSettings, resolution), "m", above(0, 1e3), "cost-integration and corridor-check step along a motion")
          .real("goal_tolerance", SN_REF(PlannerSettings, goal_tolerance), "m", closed(0, 1e3), "a tree node this close to the goal reaches it")
          .real("corridor_bias", SN_REF(PlannerSettings, corridor_bias), "", closed(0, 1), "share of samples drawn inside the corridor (0 = uniform, as the paper)")
          .real("hazard_weight", SN_REF(PlannerSettings, hazard_weight), "1/m", closed(0, 1e6), "beta_h, weight of the hazard term beta_h * integral of risk ds; 0 = the paper's cost")
          .set;
  return s;
}

template <>
const ParamSet<PlanningMap>& param_set<PlanningMap>() {
  static const ParamSet<PlanningMap> s =
      Declare<PlanningMap>{}
          .real("clearance", SN_REF(PlanningMap, clearance), "m", closed(0, 100), "planned paths keep this far from every obstacle")
          .real("forbidden_risk", SN_REF(PlanningMap, forbidden_risk), "", above(0, 1e6), "hazards with risk >= this are obstacles; above 1 = none (the paper)")
          .set;
  return s;
}

template <>
const ParamSet<Inflation>& param_set<Inflation>() {
  static const ParamSet<Inflation> s =
      Declare<Inflation>{}
          .real("vehicle_radius", SN_REF(Inflation, vehicle_radius), "m", closed(0, 50), "the vehicle's radius; clearance = vehicle_radius + margin")
          .real("margin", SN_REF(Inflation, margin), "m", closed(0, 50), "distance kept beyond the vehicle's body; clearance = vehicle_radius + margin")
          .set;
  return s;
}

template <>
const ParamSet<NavigationSettings>& param_set<NavigationSettings>() {
  using N = NavigationSettings;
  static const ParamSet<N> s =
      Declare<N>{}
          .real("cruise_speed", SN_REF(N, cruise_speed), "m/s", closed(0.01, 100), "desired speed")
          .real("arrival_radius", SN_REF(N, arrival_radius), "m", above(0, 100), "arrived when the estimate is this close to the destination")
          .real("segment_length", SN_REF(N, segments.length), "m", above(0, 1e5), "longest path segment [SafeNav Alg. 1], [SafeNav Alg. 2]")
          .integer("sub_segments", SN_REF(N, segments.sub_segments), closed(1, 1000), "sub-segments per segment [SafeNav Alg. 2]")
          .real("lookahead", SN_REF(N, lookahead), "m", above(0, 1e5), "the corrective control aims this far ahead [SafeNav Alg. 1]")
          .real("step_back_speed", SN_REF(N, step_back_speed), "m/s", closed(0.01, 100), "speed of the step back [SafeNav Alg. 1]")
          .real("sensing_range", SN_REF(N, sensing_range), "m", above(0, 1e5), "obstacles this far ahead on the path are detected")
          .integer("obstacle_check_every", SN_REF(N, obstacle_check_every), closed(1, 1e6), "steps between obstacle checks")
          .real("replan_lookahead", SN_REF(N, replan_lookahead), "m", above(0, 1e5), "a detour rejoins the path this far ahead")
          .integer("max_replans", SN_REF(N, max_replans), closed(0, 1e6), "detours planned at most per trial")
          .integer64("replan_iterations", SN_REF(N, planner.max_iterations), closed(1, kMaxIterations), "RAw-RRT* iterations of a detour")
          .real("corridor_bias", SN_REF(N, planner.corridor_bias), "", closed(0, 1), "share of RAw-RRT* samples drawn inside the corridor")
          .real("corridor_margin", SN_REF(N, corridor_margin), "m", closed(0, 1e5), "left the corridor: deviation beyond half_width + this")
          .real("lost_position_std", SN_REF(N, lost_position_std), "m", above(0, 1e4), "lost localization above this position sigma")
          .integer("max_steps", SN_REF(N, max_steps), closed(0, N::kMaxSteps), "step budget; 0 = 3 x path length / (speed x dt) + 200")
          .real("gate_probability", SN_REF(N, filter.gate_probability), "", closed(0, 0.999999), "chi-square gate of each update (ours); 0 = off, the paper's loop")
          .real("guard_k", SN_REF(N, guard.k), "", above(0, 100), "the guard keeps k x position sigma clear of obstacles and forbidden hazards (ours)")
          .real("guard_buffer", SN_REF(N, guard.buffer), "m", closed(0, 1e4), "the guard keeps this much beyond k sigma")
          .real("guard_slow_distance", SN_REF(N, guard.slow_distance), "m", closed(0, 1e4), "the guard slows down when its margin falls below this")
          .real("guard_horizon", SN_REF(N, guard.horizon), "s", above(0, 1e3), "the guard looks at the control held this long, then braking")
          .real("guard_min_speed_fraction", SN_REF(N, guard.min_speed_fraction), "", above(0, 1), "slowest fraction of the commanded speed while the guard slows")
          .set;
  return s;
}

template <>
const ParamSet<SensorSettings>& param_set<SensorSettings>() {
  using S = SensorSettings;
  static const ParamSet<S> s =
      Declare<S>{}
          .real("max_range", SN_REF(S, max_range), "m", above(0, 1e4), "landmarks farther than this are not detected")
          .real("field_of_view", SN_REF(S, field_of_view), "rad", above(0, 2 * kPi), "full horizontal field of view, centred on the heading; 2 pi = all round")
          .integer("min_landmarks", SN_REF(S, min_landmarks), closed(1, 1000), "a position fix needs this many landmarks in view [SafeNav-ext §V-A3(ii)]: clusters of >= 3")
          .flag("occlusion", SN_REF(S, occlusion), "obstacles hide landmarks from the simulated camera (ours; off in the papers' loop)")
          .integer("position_every", SN_REF(S, position_every), closed(1, 1e6), "a position fix every n steps")
          .real("imu_speed_std", SN_REF(S, imu_speed_std), "m/s", closed(1e-6, 10), "sigma of the IMU's speed")
          .real("imu_heading_std", SN_REF(S, imu_heading_std), "rad", closed(1e-6, kPi), "sigma of the IMU's heading")
          .real("range_std", SN_REF(S, range_std), "m", closed(1e-6, 100), "sigma of one landmark range (fixes from ranges)")
          .real("dropout_probability", SN_REF(S, faults.dropout_probability), "", closed(0, 1), "a landmark observation is missed with this probability (ours)")
          .real("outlier_probability", SN_REF(S, faults.outlier_probability), "", closed(0, 1), "a landmark range is an outlier with this probability (ours)")
          .real("outlier_magnitude", SN_REF(S, faults.outlier_magnitude), "m", above(0, 1e4), "an outlier range is off by this much, either sign")
          .real("misassociation_probability", SN_REF(S, faults.misassociation_probability), "", closed(0, 1), "a landmark observation carries another landmark's id with this probability (ours)")
          .set;
  return s;
}

template <>
const ParamSet<AugmentedStates>& param_set<AugmentedStates>() {
  using A = AugmentedStates;
  // The on/off switches (range_scale, heading_rate_bias, range_bias) are bools, set directly.
  static const ParamSet<A> s =
      Declare<A>{}
          .real("scale_prior", SN_REF(A, scale_prior), "", closed(-0.5, 0.5), "k0, prior mean of the range scale k: r = (1+k)|p - a| + b (ours; Plaza reads ~7 % long)")
          .real("scale_std", SN_REF(A, scale_std), "", above(0, 1), "sigma of k0")
          .real("scale_walk", SN_REF(A, scale_walk), "1/sqrt(s)", closed(0, 1), "random walk of k per sqrt(second)")
          .real("heading_rate_bias_prior", SN_REF(A, heading_rate_bias_prior), "rad/s", closed(-1, 1), "beta0, prior mean of the heading-rate (gyro) bias: theta' = theta + clip(dtheta) - beta*dt (ours)")
          .real("heading_rate_bias_std", SN_REF(A, heading_rate_bias_std), "rad/s", above(0, 1), "sigma of beta0")
          .real("heading_rate_bias_walk", SN_REF(A, heading_rate_bias_walk), "rad/s/sqrt(s)", closed(0, 1), "random walk of beta per sqrt(second)")
          .real("range_bias_std", SN_REF(A, range_bias_std), "m", above(0, 100), "sigma of each landmark's range bias b_j (prior mean 0; ours)")
          .real("range_bias_walk", SN_REF(A, range_bias_walk), "m/sqrt(s)", closed(0, 10), "random walk of each b_j per sqrt(second)")
          .set;
  return s;
}

template <>
const ParamSet<LocalizerSettings>& param_set<LocalizerSettings>() {
  using L = LocalizerSettings;
  static const ParamSet<L> s =
      Declare<L>{}
          .real("gate_probability", SN_REF(L, filter.gate_probability), "", closed(0, 0.999999), "chi-square gate of each update (0 = off)")
          .real("init_window", SN_REF(L, init_window), "s", above(0, 1e4), "starting from the data: the odometry track and ranges of the last init_window seconds are fitted together")
          .real("init_min_path", SN_REF(L, init_min_path), "m", closed(0, 1e4), "starting from the data: odometry path within the window before a fit is tried (heading is unobservable at rest)")
          .integer("init_min_beacons", SN_REF(L, init_min_beacons), closed(2, 1000), "starting from the data: distinct landmarks ranged within the window before a fit is tried")
          .real("init_max_rms", SN_REF(L, init_max_rms), "m", above(0, 1e4), "starting from the data: accept the fit only if its inlier range residual RMS is below this")
          .real("init_max_pos_std", SN_REF(L, init_max_pos_std), "m", above(0, 1e4), "starting from the data: accept the fit only if its position sigma is below this")
          .real("init_cov_inflation", SN_REF(L, init_cov_inflation), "", closed(1, 1e4), "starting from the data: the fit's pose covariance is multiplied by this")
          .real("init_baseline", SN_REF(L, init_baseline), "m", above(0, 1e4), "starting from position fixes: motion before the heading is taken from two positions")
          .real("init_speed_std", SN_REF(L, init_speed_std), "m/s", above(0, 100), "sigma of the initial speed when starting from the data")
          .integer("reset_after_rejections", SN_REF(L, reset_after_rejections), closed(0, 1e6), "consecutive fixes rejected by the gate before the next resets the position; 0 = never")
          .set;
  return s;
}

template class ParamSet<BmmParams>;
template class ParamSet<LocalizerSettings>;
template class ParamSet<AugmentedStates>;
template class ParamSet<SensorSettings>;
template class ParamSet<RiskZones>;
template class ParamSet<PlannerSettings>;
template class ParamSet<PlanningMap>;
template class ParamSet<Inflation>;
template class ParamSet<NavigationSettings>;

}  // namespace safenav

// SafeNav guidance: [SafeNav Algs. 1–2] (CHull, Centroid) and the obstacle
// check and RAw-RRT* detours of [SafeNav-ext Alg. 4] (= [SafeNav-conf
// Alg. 3]) as an online object (safenav/guidance.hpp).
#include "safenav/guidance.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "errors.hpp"
#include "rng.hpp"
#include "safenav/params.hpp"

namespace safenav {

namespace {

using detail::bad;
using detail::num;
using detail::require_finite_nonneg;
using detail::require_finite_positive;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The event of each GuardAction (Keep has none).
constexpr unsigned kGuardEvent[] = {0u, kGuardSlow, kGuardSteer, kGuardHold, kGuardRecover, kBlocked};

double heading_to(const State& x, const Eigen::Vector2d& target) {
  const Eigen::Vector2d d = target - x.head<2>();
  if (d.squaredNorm() < 1e-18) return 0.0;
  return wrap_angle(std::atan2(d.y(), d.x()) - x[kTheta]);
}

}  // namespace

// ---------------------------------------------------------------------------
// names and validation

std::string to_string(GuidanceStatus status) {
  switch (status) {
    case GuidanceStatus::Initializing: return "initializing";
    case GuidanceStatus::Guiding: return "guiding";
    case GuidanceStatus::Arrived: return "arrived";
    case GuidanceStatus::NoPath: return "no_path";
    case GuidanceStatus::LostLocalization: return "lost_localization";
    case GuidanceStatus::StaleInput: return "stale_input";
    case GuidanceStatus::Blocked: return "blocked";
  }
  return "unknown";
}

// ---------------------------------------------------------------------------
// [SafeNav Algs. 1–2]

namespace {
/// [SafeNav Alg. 2]'s control, with the centroid it steers toward.
Control centroid_toward(const PathSegments& segments, const State& estimate, double cruise_speed, CentroidTarget& t) {
  check_finite_state(estimate, "estimate");
  require_finite_positive(cruise_speed, "cruise_speed");
  const Eigen::Vector2d p = estimate.head<2>();
  t = segments.nearest_centroid_ahead(p);
  const Eigen::Vector2d target = t.ahead ? t.point : Eigen::Vector2d(segments.corridor().path().bottomRows<1>().transpose());
  return Control(cruise_speed, heading_to(estimate, target));
}
}  // namespace

Control centroid_control(const PathSegments& segments, const State& estimate, double cruise_speed) {
  CentroidTarget t;
  return centroid_toward(segments, estimate, cruise_speed, t);
}

ChullDecision chull_control(const PathSegments& segments, const Bmm& bmm, const State& estimate, double cruise_speed,
                            double lookahead, double step_back_speed, const ObstacleChecker* obstacles) {
  check_finite_state(estimate, "estimate");
  require_finite_positive(cruise_speed, "cruise_speed");
  require_finite_positive(lookahead, "lookahead");
  require_finite_positive(step_back_speed, "step_back_speed");
  const Corridor& corridor = segments.corridor();
  const Eigen::Vector2d p = estimate.head<2>();
  const PathProjection proj = corridor.project(p);
  ChullDecision d;
  d.segment = segments.segment_at(proj.arc_length);
  const int k = d.segment;
  // Outside every adjacent hull (k−1, k, k+1): step back toward the path.
  const bool inside_adjacent = segments.in_current_or_next(k, p) || (k > 0 && segments.hull_contains(k - 1, p));
  if (!inside_adjacent) {
    const Eigen::Vector2d foot = (proj.foot - p).squaredNorm() > 1e-18
                                     ? proj.foot
                                     : Eigen::Vector2d(proj.foot + corridor.tangent_at(proj.arc_length));
    d.control = Control(step_back_speed, heading_to(estimate, foot));
    d.action = ChullAction::StepBack;
    d.predicted = bmm.predict(estimate, d.control).head<2>();
    return d;
  }
  // Default command: toward the look-ahead point on the safe path; the look-
  // ahead shrinks (halving, down to 1/8) while the chord to it hits an obstacle.
  double la = lookahead;
  Eigen::Vector2d aim = corridor.point_at(proj.arc_length + la);
  if (obstacles) {
    while (la > lookahead / 8.0 && !obstacles->segment_free(p, aim)) {
      la *= 0.5;
      aim = corridor.point_at(proj.arc_length + la);
    }
  }
  Control u(cruise_speed, heading_to(estimate, aim));
  State pred = bmm.predict(estimate, u);
  if (segments.in_current_or_next(k, pred.head<2>())) {  // [SafeNav-ext Alg. 1 l. 13] (conf l. 10)
    d.control = u;
    d.action = ChullAction::Keep;
    d.predicted = pred.head<2>();
    return d;
  }
  // Corrective control ([SafeNav-ext Alg. 1 l. 17], conf l. 13): back toward the path, 1 m ahead of the foot.
  u = Control(cruise_speed, heading_to(estimate, corridor.point_at(proj.arc_length + 1.0)));
  d.control = u;
  d.action = ChullAction::Corrective;
  d.predicted = bmm.predict(estimate, u).head<2>();
  return d;
}

// ---------------------------------------------------------------------------
// Guidance

/// What a guidance run is built from, once; shared (immutable) by the runs
/// that Guidance::fresh makes.
struct GuidanceShared {
  NavigationProblem problem;
  NavigationSettings settings;
  LocalizerSettings localizer;  // bmm = problem.bmm; filter seed set per run
  Landmarks landmarks;
  std::vector<int> ids;
  std::shared_ptr<const PathSegments> safe;  // the safe path's segments
  ObstacleChecker obstacles;                 // obstacles with the planning clearance (CHull's look-ahead)
  ObstacleChecker collisions;                // obstacles, no clearance (the way ahead)
  Bmm bmm;
  double exposures = 1.0;                    // N of the safe path (path_exposures)

  static PlanningMap no_clearance(PlanningMap m) {
    m.clearance = 0.0;
    return m;
  }

  GuidanceShared(NavigationProblem p, NavigationSettings s, LocalizerSettings ls, Landmarks lm, std::vector<int> id)
      : problem(std::move(p)),
        settings(std::move(s)),
        localizer(std::move(ls)),
        landmarks(std::move(lm)),
        ids(std::move(id)),
        obstacles((problem.validate(), settings.validate(), problem.map)),
        collisions(no_clearance(problem.map)),
        bmm(problem.bmm) {
    localizer.bmm = problem.bmm;
    safe = std::make_shared<const PathSegments>(Corridor(problem.path, problem.zones), settings.segments);
    resolve_guard_k();
  }

  /// The guard's k from the risk budget (docs/safety.md): N exposures of the
  /// safe path — the arc length where an obstacle lies within the corridor
  /// limit plus the buffer, per guard horizon travelled at cruise speed
  /// (measured in control steps of v·Δt/(1+τ) metres) — and, unless a k > 0
  /// was given, k = Φ⁻¹(1 − ε/N).
  void resolve_guard_k() {
    const double reach = problem.zones.half_width + settings.corridor_margin + settings.guard.buffer;
    const double step = settings.cruise_speed * bmm.params().dt * bmm.params().terrain_factor();
    const double exposure_length = std::max(step, settings.cruise_speed * settings.guard.horizon *
                                                      bmm.params().terrain_factor());
    exposures = path_exposures(safe->corridor(), collisions, reach, exposure_length, step);
    if (settings.guard.k == 0.0) settings.guard.k = guard_k_for_risk(settings.collision_probability, exposures);
  }

  /// [SafeNav-ext Alg. 4 l. 8] (= conf Alg. 3 l. 6): whether the way ahead of a vehicle at p (arc length
  /// s on the path) hits an obstacle — the chord from p to the path
  /// (look-ahead point) and the path up to sensing_range of arc beyond s.
  bool blocked_ahead(const Corridor& c, const Eigen::Vector2d& p, double s) const {
    const double s1 = std::min(c.length(), s + settings.sensing_range);
    Eigen::Vector2d a = p;
    const Eigen::VectorXd& vs = c.vertex_arc_lengths();
    Eigen::Index i = 0;
    while (i < vs.size() && vs[i] <= s) ++i;
    for (; i < vs.size() && vs[i] < s1; ++i) {
      const Eigen::Vector2d b = c.path().row(i).transpose();
      if (!collisions.segment_free(a, b)) return true;
      a = b;
    }
    return !collisions.segment_free(a, c.point_at(s1));
  }

  /// Splice a RAw-RRT* detour from p into the active path.  Returns the new
  /// segments, or null when no path was found.
  std::shared_ptr<const PathSegments> detour(const PathSegments& active, const Eigen::Vector2d& p,
                                             std::uint64_t seed, std::string* why) const {
    // Plan locally: in a window around the vehicle and the rejoin point (the
    // whole field when the window would not fit), keeping the planning
    // clearance where the vehicle's own position allows it.
    const Corridor& ac = active.corridor();
    const double s_here = ac.project(p).arc_length;
    const Eigen::Vector2d rejoin = ac.point_at(s_here + settings.replan_lookahead);
    const double margin = settings.replan_lookahead;
    PlanningProblem pp;
    pp.map = problem.map;
    pp.map.lower = pp.map.lower.cwiseMax(p.cwiseMin(rejoin) - Eigen::Vector2d::Constant(margin));
    pp.map.upper = pp.map.upper.cwiseMin(p.cwiseMax(rejoin) + Eigen::Vector2d::Constant(margin));
    pp.central_path = ac.path();
    pp.zones = problem.zones;
    while (pp.map.clearance > 0.05 && !ObstacleChecker(pp.map).point_free(p)) pp.map.clearance *= 0.5;
    if (!ObstacleChecker(pp.map).point_free(p)) pp.map.clearance = 0.0;
    PlannerSettings ps = settings.planner;
    ps.seed = seed;
    PlanResult r;
    try {
      // The goal slides along the path past blocked points, possibly out of the window.
      r = replan(pp, p, settings.replan_lookahead, ps);
    } catch (const std::invalid_argument&) {
      r = PlanResult{};
    }
    if (!r.success) {
      pp.map.lower = problem.map.lower;
      pp.map.upper = problem.map.upper;
      try {
        r = replan(pp, p, settings.replan_lookahead, ps);
      } catch (const std::invalid_argument& e) {  // e.g. the estimate lies inside an obstacle
        *why = e.what();
        return nullptr;
      }
    }
    if (!r.success || r.path.rows() < 2) {
      *why = "RAw-RRT* found no path (" + to_string(r.status) + ", " + std::to_string(r.iterations) + " iterations)";
      return nullptr;
    }
    const Corridor& c = active.corridor();
    const Eigen::Vector2d goal = r.path.bottomRows<1>().transpose();
    const double s_goal = c.project(goal).arc_length;
    const Eigen::VectorXd& vs = c.vertex_arc_lengths();
    std::vector<Eigen::Vector2d> pts;
    for (Eigen::Index i = 0; i < r.path.rows(); ++i) pts.emplace_back(r.path.row(i).transpose());
    for (Eigen::Index i = 0; i < vs.size(); ++i)
      if (vs[i] > s_goal + 1e-9) pts.emplace_back(c.path().row(i).transpose());
    Points2 np(static_cast<Eigen::Index>(pts.size()), 2);
    for (std::size_t i = 0; i < pts.size(); ++i) np.row(static_cast<Eigen::Index>(i)) = pts[i].transpose();
    return std::make_shared<const PathSegments>(Corridor(np, problem.zones), settings.segments);
  }

};

struct Guidance::Impl {
  std::shared_ptr<const GuidanceShared> shared;
  const NavigationProblem& problem;
  const NavigationSettings& settings;
  std::shared_ptr<const PathSegments> active;  // the path followed (detours spliced in)
  Localizer localizer;
  std::uint64_t seed;
  int replans = 0;
  int commands = 0;
  std::string detail;
  Guard guard;  // the uncertainty-aware guard (guard.hpp)
  bool blocked = false;  // the guard gave up (GuidanceStatus::Blocked)
  // The estimate predicted to a command's time (Localizer::predict_to; eq. 11).
  State x_ahead;
  StateCov P_ahead;

  static LocalizerSettings seeded(LocalizerSettings s, std::uint64_t seed) {
    s.filter.seed = derive_seed(seed, 2);
    return s;
  }

  Impl(std::shared_ptr<const GuidanceShared> sh, std::uint64_t sd)
      : shared(std::move(sh)),
        problem(shared->problem),
        settings(shared->settings),
        active(shared->safe),
        localizer(seeded(shared->localizer, sd), shared->landmarks, shared->ids),
        seed(sd),
        guard(settings.guard, shared->bmm, shared->collisions, shared->landmarks,
              problem.zones.half_width + settings.corridor_margin) {}

  /// The watchdog: true (with c's status StaleInput, control 0) when an input
  /// stream is older than input_timeout at t.
  bool stale(double t, Command& c) {
    if (!localizer.initialized()) return false;
    const double motion_age = t - localizer.last_motion_time();
    const double measurement_age = t - localizer.last_measurement_time();
    c.input_age = std::max(motion_age, measurement_age);
    const double limit = settings.input_timeout;
    if (limit == 0.0 || !(c.input_age > limit)) return false;
    c.status = GuidanceStatus::StaleInput;
    c.events = kStaleInput;
    c.control = Control(0.0, 0.0);
    detail = (motion_age >= measurement_age ? "motion input " + num(motion_age) : "measurement " + num(measurement_age)) +
             " s old > input_timeout " + num(limit) + " s: stopped";
    return true;
  }

  /// The estimate at t: the localizer's, predicted past its time as a
  /// measurement at t would be (Localizer::predict_to); false when t is not
  /// past the localizer's time.  The localizer is left as it is.
  bool predicted(double t) { return localizer.predict_to(t, x_ahead, P_ahead); }

  Eigen::Vector2d destination() const { return shared->safe->corridor().path().bottomRows<1>().transpose(); }

  GuidanceStatus status() const {
    if (!localizer.initialized()) return GuidanceStatus::Initializing;
    if (blocked) return GuidanceStatus::Blocked;
    const double pstd = localizer.position_std();
    if (!(pstd <= settings.lost_position_std)) return GuidanceStatus::LostLocalization;
    if ((localizer.x().head<2>() - destination()).norm() <= settings.arrival_radius) return GuidanceStatus::Arrived;
    return GuidanceStatus::Guiding;
  }

  /// Obstacles ahead [SafeNav-ext Alg. 4 ll. 7–9]: when the way ahead of the
  /// estimate xe is blocked, splice a detour into the path (events in c).
  /// False, with c's status NoPath, when none can be had.
  bool check_ahead(const State& xe, Command& c) {
    const double s = active->corridor().project(xe.head<2>()).arc_length;
    if (!shared->blocked_ahead(active->corridor(), xe.head<2>(), s)) return true;
    if (replans >= settings.max_replans) {
      c.status = GuidanceStatus::NoPath;
      c.events = kNoPath;
      detail = "path blocked after " + std::to_string(replans) + " replans (max_replans)";
      return false;
    }
    std::string why;
    auto next = shared->detour(*active, xe.head<2>(), derive_seed(seed, 16 + static_cast<std::uint64_t>(replans)), &why);
    ++replans;
    if (!next) {
      c.status = GuidanceStatus::NoPath;
      c.events = kNoPath;
      detail = "path blocked at s = " + num(s) + " m and no detour: " + why;
      return false;
    }
    active = std::move(next);
    c.events |= kDetourPlanned | kPathSpliced;
    return true;
  }

  /// The method's control from the estimate xe [SafeNav Algs. 1–2].
  void method_control(const State& xe, Command& c) const {
    const NavigationSettings& st = settings;
    if (st.method == NavigationMethod::Centroid) {
      CentroidTarget target;
      c.control = centroid_toward(*active, xe, st.cruise_speed, target);
      c.predicted = shared->bmm.predict(xe, c.control).head<2>();
      c.segment = target.segment;  // the segment of the centroid steered toward
    } else {
      const ChullDecision d = chull_control(*active, shared->bmm, xe, st.cruise_speed, st.lookahead,
                                            st.step_back_speed, &shared->obstacles);
      c.control = d.control;
      c.predicted = d.predicted;
      c.segment = d.segment;
      c.action = d.action;
    }
  }
};

Guidance::Guidance(NavigationProblem problem, NavigationSettings settings, LocalizerSettings localizer,
                   Landmarks landmarks, std::vector<int> ids, std::uint64_t seed)
    : impl_(std::make_unique<Impl>(std::make_shared<const GuidanceShared>(std::move(problem), std::move(settings),
                                                                          std::move(localizer), std::move(landmarks),
                                                                          std::move(ids)),
                                   seed)) {}

Guidance::Guidance(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Guidance Guidance::fresh(std::uint64_t seed) const {
  return Guidance(std::make_unique<Impl>(impl_->shared, seed));
}

Guidance Guidance::planned(const PlanningProblem& planning, const PlannerSettings& planner, NavigationProblem problem,
                           NavigationSettings settings, LocalizerSettings localizer, Landmarks landmarks,
                           std::vector<int> ids, std::uint64_t seed) {
  const PlanResult r = plan(planning, planner);
  if (!r.success || r.path.rows() < 2)
    throw std::runtime_error("Guidance.planned: RAw-RRT* found no safe path (" + to_string(r.status) + ", " +
                             std::to_string(r.iterations) + " iterations)");
  problem.path = r.path;
  return Guidance(std::move(problem), std::move(settings), std::move(localizer), std::move(landmarks), std::move(ids),
                  seed);
}

Guidance::~Guidance() = default;

Guidance::Guidance(Guidance&&) noexcept = default;
Guidance& Guidance::operator=(Guidance&&) noexcept = default;

Localizer& Guidance::localizer() { return impl_->localizer; }
const Localizer& Guidance::localizer() const { return impl_->localizer; }
const NavigationProblem& Guidance::problem() const { return impl_->problem; }
const NavigationSettings& Guidance::settings() const { return impl_->settings; }
const PathSegments& Guidance::safe_path() const { return *impl_->shared->safe; }
const PathSegments& Guidance::path() const { return *impl_->active; }
int Guidance::replans() const { return impl_->replans; }
int Guidance::commands() const { return impl_->commands; }
const std::string& Guidance::detail() const { return impl_->detail; }
double Guidance::guard_k() const { return impl_->settings.guard.k; }
double Guidance::guard_exposures() const { return impl_->shared->exposures; }
GuidanceStatus Guidance::status() const { return impl_->status(); }

State Guidance::start_state() const {
  const Corridor& safe = impl_->shared->safe->corridor();
  const Eigen::Vector2d t = safe.tangent_at(0.0);
  State x;
  x << safe.path()(0, 0), safe.path()(0, 1), 0.0, std::atan2(t.y(), t.x());
  return x;
}

RowMatrixX4 Guidance::nominal_trajectory(int max_steps) const {
  if (max_steps < 0) bad("nominal_trajectory: max_steps = " + std::to_string(max_steps) + ": must be >= 0");
  const Impl& im = *impl_;
  State x = start_state();
  std::vector<State> rows{x};
  Command c;
  for (int k = 0; k < max_steps && (x.head<2>() - im.destination()).norm() > im.settings.arrival_radius; ++k) {
    im.method_control(x, c);
    x = im.shared->bmm.predict(x, c.control);
    rows.push_back(x);
  }
  RowMatrixX4 out(static_cast<Eigen::Index>(rows.size()), 4);
  for (std::size_t i = 0; i < rows.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = rows[i].transpose();
  return out;
}

Command Guidance::command(double t) {
  if (!std::isfinite(t)) bad("command: time t = " + num(t) + " is not finite");
  Impl& im = *impl_;
  const NavigationSettings& st = im.settings;
  Command c;
  c.status = im.status();
  if (c.status == GuidanceStatus::Initializing) return c;
  c.position_std = im.localizer.position_std();
  if (c.status == GuidanceStatus::LostLocalization) {
    c.events = kLostLocalization;
    im.detail = "position std " + num(c.position_std) + " m > " + num(st.lost_position_std) + " m";
    return c;
  }
  if (c.status == GuidanceStatus::Blocked) {
    c.events = kBlocked;
    return c;
  }
  if (c.status == GuidanceStatus::Arrived) {
    c.events = kArrived;
    im.detail = "arrived";
    return c;
  }
  if (im.stale(t, c)) return c;
  const bool ahead = im.predicted(t);
  const State& xe = ahead ? im.x_ahead : im.localizer.x();
  if (ahead) c.position_std = safenav::position_std(im.P_ahead);
  if (st.replan && im.commands % st.obstacle_check_every == 0 && !im.check_ahead(xe, c)) return c;
  ++im.commands;
  im.method_control(xe, c);
  if (st.guard.enabled) {
    const GuardDecision g = im.guard.decide(t, xe, c.position_std, c.control, im.active->corridor());
    c.control = g.control;
    c.clearance = g.clearance;
    c.guard_margin = g.margin;
    if (g.action != GuardAction::Keep) {
      c.events |= kGuardEvent[static_cast<int>(g.action)];
      c.predicted = im.shared->bmm.predict(xe, c.control).head<2>();
    }
    if (g.action == GuardAction::Blocked) {
      im.blocked = true;
      im.detail = g.reason;
      c.status = GuidanceStatus::Blocked;
    }
  }
  return c;
}

}  // namespace safenav
